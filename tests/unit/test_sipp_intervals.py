"""The safe intervals' forbidden intervals: one batched k-d tree query, per-flight samples
kept between calls, the very intervals of a plain pair-by-pair measurement."""

import gc

import numpy as np
import pytest

from planner.model.trajectory import Trajectory
from planner.search import sipp
from planner.search.sipp import STEP, Mover, forbidden_intervals


def _plain(samples, spacing, speed, radius, others):
    """Every sample of every other flight against every sample of the path (no tree, no
    box, no raster): squared distance against the squared reach, as a k-d tree tests it."""
    passing = spacing / speed / 2
    slots, los, his = [], [], []
    for other in others:
        need = radius + other.radius + spacing / 2 + STEP / 2
        period = STEP / max(other.speed, 1e-9)
        traj = other.trajectory
        times = np.arange(0.0, traj.end_time + period, period)
        times[-1] = min(times[-1], traj.end_time)
        where = traj.at(times)
        gap = where[:, None, :] - samples[None, :, :]
        i, j = np.nonzero(gap[..., 0] * gap[..., 0] + gap[..., 1] * gap[..., 1] <= need * need)
        widen = period / 2 + passing
        slots.append(j)
        los.append(times[i] - widen)
        his.append(times[i] + widen)
    slot = np.concatenate(slots).astype(np.intp)
    if not len(slot):
        return np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0)
    return sipp._merge(slot, np.concatenate(los), np.concatenate(his))


def _flight(rng: np.random.Generator, size: float) -> Mover:
    points = rng.uniform(0, size, (int(rng.integers(2, 6)), 2))
    speed = float(rng.choice([0.5, 1.0, 1.5]))
    waits = rng.choice([0.0, 0.0, 2.5], len(points))
    trajectory = Trajectory.from_waypoints(points, speed, waits)
    return Mover(trajectory, float(rng.choice([0.2, 0.3, 0.45])), speed)


def _path(rng: np.random.Generator, size: float) -> tuple[np.ndarray, float]:
    a, b = rng.uniform(0, size, (2, 2))
    count = max(2, int(np.ceil(np.hypot(*(b - a)) / STEP)) + 1)
    samples = np.linspace(a, b, count)
    return samples, float(np.hypot(*(b - a)) / (count - 1))


@pytest.mark.parametrize("seed", range(12))
def test_the_batched_query_finds_the_plain_measurements_intervals(seed: int) -> None:
    rng = np.random.default_rng(seed)
    size = float(rng.choice([6.0, 20.0, 60.0]))
    others = [_flight(rng, size) for _ in range(int(rng.integers(0, 30)))]
    samples, spacing = _path(rng, size)
    got = forbidden_intervals(samples, spacing, 1.0, 0.3, others)
    want = _plain(samples, spacing, 1.0, 0.3, others)
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype
        assert g.tobytes() == w.tobytes()  # the same intervals, bit for bit


def test_samples_are_kept_per_flight_and_dropped_with_it() -> None:
    rng = np.random.default_rng(5)
    mover = _flight(rng, 20.0)
    period = STEP / mover.speed
    first = sipp._sampled(mover.trajectory, period)
    assert sipp._sampled(mover.trajectory, period) is first  # asked again: kept
    moved = Trajectory(mover.trajectory.points + np.array([0.0, 1.0, 0.0]))  # another flight
    other = sipp._sampled(moved, period)
    assert other is not first
    assert np.allclose(other.where, first.where + np.array([1.0, 0.0]))
    key = (id(moved), period)
    assert key in sipp._SAMPLED
    del moved, other
    gc.collect()
    assert key not in sipp._SAMPLED
