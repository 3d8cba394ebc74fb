"""Cost terms of many candidate paths for one UAV at once: the planner's hot path.

A candidate is a polyline of waypoints with a hover time at each. Every term is
computed for the whole population in numpy: separation from the other UAVs at
sampled encounters with a margin that covers the motion between samples, clearance
from blocked cells from a fine distance raster, also with a margin. Both err on the
safe side, and every plan is still judged by the exact check in `planner.check.safety`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.geometry.clearance import ClearanceField, ExactClearance, distance_to_polyline
from planner.model.trajectory import Trajectory

Array = NDArray[np.float64]
SPACING = 0.1  # cells between clearance samples along a path


@dataclass(frozen=True)
class Traffic:
    """The other UAVs, fixed while one UAV searches, as a short list of encounters.

    They are sampled every `step` seconds, and only the samples inside the region the
    searching UAV can reach are kept: (time, place, distance needed). Between two
    samples two UAVs close in by at most (v_i + v_j) x step, so every encounter asks
    for half of that on top of the radii: a path that clears every sample clears the
    exact continuous check as well, and a path that fails it is always caught.
    """

    times: Array  # (S,) the sample times the encounters use
    slot: NDArray[np.intp]  # (Q,) index of each encounter's time in `times`
    where: Array  # (Q, 2) the other UAV's position
    need: Array  # (Q,) centre distance needed, margin included
    step: float

    @classmethod
    def around(
        cls,
        others: list[tuple[Trajectory, float, float]],
        *,
        radius: float,
        speed: float,
        start: Array,
        lower: Array,
        upper: Array,
        corridor: tuple[Array, float] | None = None,
    ) -> Traffic:
        """`others` are (trajectory, radius, speed); the searcher leaves `start` at t = 0 and
        stays inside [lower, upper], so it cannot meet anything it could not reach in time.

        With a `corridor` (polyline, reach) the searcher also stays within `reach` of that
        polyline, and only the samples that close to it are kept: the encounters of a
        long path across a crowded map then shrink to those of the UAVs that cross it.
        """
        step = 0.1 / max([speed] + [v for _, _, v in others])
        horizon = max((t.end_time for t, _, _ in others), default=0.0)
        grid = np.arange(0.0, horizon + step, step)
        slots, places, needs = [], [], []
        for trajectory, r, v in others:
            need = radius + r + (speed + v) * step / 2
            at = trajectory.at(grid)  # NaN once landed
            near = np.all((at >= lower - need) & (at <= upper + need), axis=1)
            with np.errstate(invalid="ignore"):  # NaN once the other UAV has landed
                near &= np.hypot(*(at - start).T) - need <= speed * grid
            if corridor is not None and near.any():
                polyline, reach = corridor
                close = distance_to_polyline(at[near], polyline) <= reach + need
                near[np.flatnonzero(near)[~close]] = False
            slots.append(np.flatnonzero(near))
            places.append(at[near])
            needs.append(np.full(near.sum(), need))
        slot = np.concatenate(slots) if slots else np.zeros(0, dtype=np.intp)
        used, slot = np.unique(slot, return_inverse=True)
        where = np.concatenate(places) if places else np.zeros((0, 2))
        needed = np.concatenate(needs) if needs else np.zeros(0)
        return cls(grid[used], slot.astype(np.intp), where, needed, step)


@dataclass(frozen=True)
class PathTerms:
    """Per candidate: what the objectives weigh."""

    length: Array
    waiting: Array
    end_time: Array
    deviation: Array  # distance of the last waypoint from the goal
    separation_deficit: Array  # Σ over encounters of (needed - distance) x step, UAVs
    separation_hits: NDArray[Any]  # encounters where two UAVs come too close (a count)
    clearance_deficit: Array  # Σ over samples of (needed - clearance) x spacing, obstacles
    clearance_hits: NDArray[Any]  # samples (or legs) inside an obstacle's reach (a count)

    @property
    def safe(self) -> NDArray[np.bool_]:
        safe: NDArray[np.bool_] = (self.separation_hits == 0) & (self.clearance_hits == 0)
        return safe


def timeline(waypoints: Array, waits: Array, speed: float) -> tuple[Array, Array]:
    """Breakpoint times (N, 2P) and positions (N, 2P, 2): arrive, hover, leave each waypoint."""
    legs = np.hypot(*np.moveaxis(np.diff(waypoints, axis=1), -1, 0)) / speed  # (N, P-1)
    n, p = waits.shape
    steps = np.zeros((n, 2 * p))
    steps[:, 1::2] = waits
    steps[:, 2::2] = legs
    return np.cumsum(steps, axis=1), np.repeat(waypoints, 2, axis=1)


def batched_interp(queries: Array, knots: Array, values: Array) -> Array:
    """Row-wise piecewise-linear interpolation: row r of `queries` (R, Q) on knots (R, K)
    with values (R, K, D), clamped at both ends. Knots may repeat (a hover)."""
    rows, k = knots.shape
    span = max(float(knots.max()), float(queries.max()), 0.0) + 1.0
    offset = (np.arange(rows) * span)[:, None]
    idx = np.searchsorted((knots + offset).ravel(), (queries + offset).ravel(), side="right")
    base = np.repeat(np.arange(rows) * k, queries.shape[1])
    right = base + np.clip(idx - base, 1, k - 1)
    flat_t, flat_v = knots.ravel(), values.reshape(rows * k, -1)
    t0, t1 = flat_t[right - 1], flat_t[right]
    span_t = t1 - t0
    frac = np.divide(queries.ravel() - t0, span_t, out=np.ones_like(span_t), where=span_t > 0)
    np.clip(frac, 0.0, 1.0, out=frac)
    v0 = flat_v[right - 1]
    out = v0 + frac[:, None] * (flat_v[right] - v0)
    interpolated: NDArray[np.float64] = out.reshape(*queries.shape, -1)
    return interpolated


def separation_terms(
    times: Array, positions: Array, traffic: Traffic
) -> tuple[Array, NDArray[Any]]:
    """Shortfall of every candidate's distance to the other UAVs at their encounters."""
    n = times.shape[0]
    if traffic.slot.size == 0:
        return np.zeros(n), np.zeros(n)
    at = batched_interp(np.broadcast_to(traffic.times, (n, traffic.times.size)), times, positions)
    gx = np.take(at[..., 0], traffic.slot, axis=1) - traffic.where[:, 0]  # (N, Q)
    gy = np.take(at[..., 1], traffic.slot, axis=1) - traffic.where[:, 1]
    squared = gx * gx + gy * gy
    close = squared < traffic.need * traffic.need
    # Until landing, and half a step past it so the sample nearest to any moment counts.
    close &= traffic.times[traffic.slot][None, :] <= times[:, -1:] + traffic.step / 2
    if not close.any():
        return np.zeros(n), np.zeros(n)
    deficit = np.where(close, traffic.need - np.sqrt(squared), 0.0)
    return deficit.sum(axis=1) * traffic.step, close.sum(axis=1)


@functools.cache
def _fractions(q: int) -> Array:
    return np.linspace(0.0, 1.0, q)


def clearance_terms(
    waypoints: Array, radius: float, field: ClearanceField, margin: float
) -> tuple[Array, NDArray[np.intp]]:
    """Sampled clearance along the legs against blocked cells (and the grid's edge).

    A leg whose ends are both clear by more than half its length plus the radius is
    clear all along (no point of it is further than half its length from an end), so
    only the other legs are sampled.
    """
    n = waypoints.shape[0]
    ends = field.at(waypoints)  # (N, P)
    legs = np.diff(waypoints, axis=1)  # (N, P-1, 2)
    length = np.sqrt(np.einsum("...i,...i->...", legs, legs))
    doubtful = np.minimum(ends[:, :-1], ends[:, 1:]) - length / 2 < radius + margin
    if not doubtful.any():
        return np.zeros(n), np.zeros(n, dtype=np.intp)
    rows, cols = np.nonzero(doubtful)
    q = max(2, int(np.ceil(length[rows, cols].max() / SPACING)) + 1)
    frac = _fractions(q)
    starts = waypoints[rows, cols]  # (M, 2)
    points = starts[:, None, :] + frac[None, :, None] * legs[rows, cols][:, None, :]
    deficit = np.maximum(radius + margin - field.at(points), 0.0)  # (M, q)
    step = np.maximum(length[rows, cols] / (q - 1), SPACING)
    weights = (deficit * step[:, None]).sum(axis=1)
    depth = np.asarray(np.bincount(rows, weights=weights, minlength=n), dtype=np.float64)
    hits = np.bincount(rows, weights=(deficit > 0).sum(axis=1), minlength=n)
    return depth, hits.astype(np.intp)


def evaluate_paths(
    waypoints: Array,
    waits: Array,
    *,
    speed: float,
    radius: float,
    goal: Array,
    traffic: Traffic,
    field: ClearanceField | ExactClearance,
) -> PathTerms:
    """All cost terms of N candidate paths: waypoints (N, P, 2), hover times (N, P)."""
    times, positions = timeline(waypoints, waits, speed)
    steps = np.diff(waypoints, axis=1)
    separation, separation_hits = separation_terms(times, positions, traffic)
    if isinstance(field, ExactClearance):
        clearance, clearance_hits = field.leg_terms(waypoints, radius)
    else:
        clearance, clearance_hits = clearance_terms(waypoints, radius, field, 1.0 / field.scale)
    return PathTerms(
        length=np.hypot(steps[..., 0], steps[..., 1]).sum(axis=1),
        waiting=waits.sum(axis=1),
        end_time=times[:, -1],
        deviation=np.hypot(*(waypoints[:, -1] - goal).T),
        separation_deficit=separation,
        separation_hits=separation_hits,
        clearance_deficit=clearance,
        clearance_hits=clearance_hits,
    )
