"""Safe-interval scheduling along a fixed path: when a UAV should hover so that it is safe.

The fast safe start of the anytime planner. A UAV keeps the geometry of its path and
only chooses when to fly it: at full speed, with hovers anywhere along it. The other
UAVs are held fixed. This is safe-interval path planning (SIPP) on the chain of points
that samples the path every `step` cells, in continuous time and with the radii:

- For every sample point, the times at which a UAV hovering there would come within
  the sum of the radii plus a margin of some other UAV are found (a k-d tree of the
  path's samples against the other UAVs' positions every `step / v_j` seconds) and
  merged into forbidden intervals; between them lie the point's safe intervals.
- Earliest arrival over the chain (the SIPP recursion): from a safe interval of one
  point the UAV may hover until the interval ends and then reach the next point
  `step / v` later, inside one of that point's safe intervals. The first arrival at
  the last point is the fastest safe flight along the path.

The margin covers what sampling cannot see: half a sample apart along the path, and
half a sampling period of the other UAV's motion. A UAV is near one sample point for a
period (`step / v`) around the moment it passes it, so each forbidden interval is
widened by half of that. Every schedule is nevertheless checked exactly by the caller
(`planner.check.safety`) before it is used.
"""

from __future__ import annotations

import functools
import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planner.model.trajectory import Trajectory

Array = NDArray[np.float64]
STEP = 0.1  # cells between sample points, and cells another UAV moves between samples
CHUNK = 32  # another UAV's samples are first tested in runs of this many


@dataclass(frozen=True)
class Mover:
    """Another UAV, held fixed."""

    trajectory: Trajectory
    radius: float
    speed: float


def forbidden_intervals(
    samples: Array, spacing: float, speed: float, radius: float, others: Sequence[Mover]
) -> tuple[NDArray[np.intp], Array, Array]:
    """Per sample point k: merged intervals (k, lo, hi) in which hovering at it is unsafe,
    widened by half the time to pass one sample, sorted by k then lo.

    Each other UAV's positions every `step / v_j` seconds are sampled once per flight
    (`_sampled`). Those in the path's box widened by the pair's reach, and in a square of
    a coarse raster next to one of the path's own, go into one k-d tree, queried once
    against the path's samples with the largest reach; each pair is then kept by its own
    UAV's reach, tested as the tree tests it (squared distance against squared reach)."""
    lower = samples.min(axis=0)
    upper = samples.max(axis=0)
    passing = spacing / speed / 2
    flights = []
    for other in others:
        period = STEP / max(other.speed, 1e-9)
        flights.append((radius + other.radius + spacing / 2 + STEP / 2, period, other))
    if not flights:
        return _none()
    need = np.array([f[0] for f in flights])
    sampled = [_sampled(f[2].trajectory, f[1]) for f in flights]
    box_low = np.array([s.box[0] for s in sampled])
    box_high = np.array([s.box[1] for s in sampled])
    low = lower - need[:, None]
    high = upper + need[:, None]
    # Never near: its points' box is apart from the path's, widened (a margin for the
    # interpolation's rounding: its positions lie in the box of its points).
    apart = np.any(box_low > high + 1e-9, axis=1) | np.any(box_high < low - 1e-9, axis=1)
    kept = np.flatnonzero(~apart).tolist()
    if not kept:
        return _none()
    side = 1.5 * float(need[kept].max())
    raster = _Raster.of(samples, lower, side)
    # Runs of CHUNK samples whose box meets both the widened path's box and the raster
    # (a superset of those holding a point that matters), then their points one by one.
    chunk_low = np.concatenate([sampled[k].chunk_low for k in kept])
    chunk_high = np.concatenate([sampled[k].chunk_high for k in kept])
    chunks = [len(sampled[k].chunk_low) for k in kept]
    chunk_owner = np.repeat(np.array(kept), chunks)
    meets = np.all(
        (chunk_high >= low[chunk_owner]) & (chunk_low <= high[chunk_owner]), axis=1
    ) & raster.meets(chunk_low, chunk_high)
    if not meets.any():
        return _none()
    counts = np.array([len(sampled[k].times) for k in kept])
    offsets = np.concatenate([[0], np.cumsum(counts)[:-1]])
    first_chunk = np.concatenate([[0], np.cumsum(chunks)[:-1]])
    mover = np.repeat(np.arange(len(kept)), chunks)[meets]
    start = (np.flatnonzero(meets) - first_chunk[mover]) * CHUNK
    lengths = np.minimum(CHUNK, counts[mover] - start)
    base = np.repeat(offsets[mover] + start - np.cumsum(lengths) + lengths, lengths)
    index = base + np.arange(int(lengths.sum()))
    where = np.concatenate([sampled[k].where for k in kept])[index]
    times = np.concatenate([sampled[k].times for k in kept])[index]
    owner = np.repeat(np.array(kept)[mover], lengths)
    near = np.all((where >= low[owner]) & (where <= high[owner]), axis=1)
    near[near] = raster.holds(where[near])
    where, times, owner = where[near], times[near], owner[near]
    if not len(where):
        return _none()
    pairs = cKDTree(where).sparse_distance_matrix(
        cKDTree(samples), float(need[owner].max()), output_type="ndarray"
    )
    i, j = pairs["i"], pairs["j"]
    reach = need[owner[i]]
    gap = where[i] - samples[j]
    keep = gap[:, 0] * gap[:, 0] + gap[:, 1] * gap[:, 1] <= reach * reach
    if not keep.any():
        return _none()
    i, j = i[keep], j[keep]
    at = times[i]
    periods = np.array([f[1] for f in flights])
    wide = periods[owner[i]] / 2 + passing
    return _merge(j.astype(np.intp), at - wide, at + wide)


def _none() -> tuple[NDArray[np.intp], Array, Array]:
    return np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0)


@dataclass(frozen=True)
class _Raster:
    """Squares of side `side` from `origin`: those holding one of a path's samples and
    their eight neighbours. Every point within side / 1.5 of a sample lies in one (the
    squares' indices of two points that close differ by at most one, whatever the
    rounding)."""

    origin: Array
    side: float
    marked: NDArray[np.bool_]
    counts: NDArray[np.intp]  # marked squares below and left of each corner (summed table)

    @classmethod
    def of(cls, samples: Array, origin: Array, side: float) -> _Raster:
        cells = np.floor((samples - origin) / side).astype(np.intp) + 1
        size = cells.max(axis=0) + 2
        raster = np.zeros(size, dtype=bool)
        raster[cells[:, 0], cells[:, 1]] = True
        grown = raster.copy()
        grown[1:] |= raster[:-1]
        grown[:-1] |= raster[1:]
        marked = grown.copy()
        marked[:, 1:] |= grown[:, :-1]
        marked[:, :-1] |= grown[:, 1:]
        counts = np.zeros(size + 1, dtype=np.intp)
        counts[1:, 1:] = marked.cumsum(axis=0).cumsum(axis=1)
        return cls(origin, side, marked, counts)

    def _square(self, points: Array) -> NDArray[np.intp]:
        return np.floor((points - self.origin) / self.side).astype(np.intp) + 1

    def holds(self, points: Array) -> NDArray[np.bool_]:
        """Which points lie in a marked square."""
        at = self._square(points)
        inside = np.all((at >= 0) & (at < self.marked.shape), axis=1)
        out = np.zeros(len(points), dtype=bool)
        out[inside] = self.marked[at[inside, 0], at[inside, 1]]
        return out

    def meets(self, low: Array, high: Array) -> NDArray[np.bool_]:
        """Which boxes [low, high] overlap a marked square."""
        top = np.array(self.marked.shape) - 1
        a = np.clip(self._square(low), 0, top + 1)
        b = np.clip(self._square(high), -1, top) + 1
        c = self.counts
        total = (
            c[b[:, 0], b[:, 1]] - c[a[:, 0], b[:, 1]] - c[b[:, 0], a[:, 1]] + c[a[:, 0], a[:, 1]]
        )
        meets: NDArray[np.bool_] = np.all(a < b, axis=1) & (total > 0)
        return meets


@dataclass(frozen=True)
class _Samples:
    """Another UAV's positions every `period` seconds, and the box of its points."""

    times: Array
    where: Array
    box: tuple[Array, Array]
    chunk_low: Array  # box of each run of CHUNK samples
    chunk_high: Array


_SAMPLED: dict[tuple[int, float], tuple[weakref.ref[Trajectory], _Samples]] = {}
"""Samples of the flights being held fixed, by flight (its identity) and period: the
safe start asks about the same flights again and again while only one changes at a
time. An entry goes when its flight is dropped."""


def _sampled(trajectory: Trajectory, period: float) -> _Samples:
    key = (id(trajectory), period)
    hit = _SAMPLED.get(key)
    if hit is not None and hit[0]() is trajectory:
        return hit[1]
    times = np.arange(0.0, trajectory.end_time + period, period)
    times[-1] = min(times[-1], trajectory.end_time)
    xy = trajectory.xy
    where = trajectory.at(times)
    padded = np.concatenate([where, np.repeat(where[-1:], -len(where) % CHUNK, axis=0)])
    runs = padded.reshape(-1, CHUNK, 2)
    samples = _Samples(
        times, where, (xy.min(axis=0), xy.max(axis=0)), runs.min(axis=1), runs.max(axis=1)
    )
    _SAMPLED[key] = (weakref.ref(trajectory, functools.partial(_forget, key)), samples)
    return samples


def _forget(key: tuple[int, float], ref: weakref.ref[Trajectory]) -> None:
    hit = _SAMPLED.get(key)
    if hit is not None and hit[0] is ref:
        del _SAMPLED[key]


def _merge(slot: NDArray[np.intp], lo: Array, hi: Array) -> tuple[NDArray[np.intp], Array, Array]:
    """Union of the intervals of each slot, sorted (one vectorised pass)."""
    order = np.lexsort((lo, slot))
    slot, lo, hi = slot[order], lo[order], hi[order]
    span = float(hi.max() - lo.min()) + 1.0
    shift = slot * span - lo.min()  # slots far apart on one line: merging never crosses
    reach = np.maximum.accumulate(hi + shift)
    starts = np.ones(len(lo), dtype=bool)
    starts[1:] = lo[1:] + shift[1:] > reach[:-1]
    first = np.flatnonzero(starts)
    last = np.append(first[1:], len(lo)) - 1
    return slot[first], lo[first], reach[last] - shift[last]


def schedule(
    waypoints: Array, speed: float, radius: float, others: Sequence[Mover], step: float = STEP
) -> Trajectory | None:
    """The earliest-arriving flight along `waypoints` (hovering where it must) that keeps
    clear of `others`, or None when there is none (the start itself is unsafe, or every
    way along the path is cut off)."""
    legs = np.hypot(*np.diff(waypoints, axis=0).T)
    along = np.concatenate([[0.0], np.cumsum(legs)])
    total = float(along[-1])
    if total == 0.0:  # already at the goal: it lands at once
        return Trajectory.from_waypoints(waypoints[:1], speed)
    count = max(2, int(np.ceil(total / step)) + 1)
    s = np.linspace(0.0, total, count)
    spacing = total / (count - 1)
    samples = np.column_stack(
        [np.interp(s, along, waypoints[:, 0]), np.interp(s, along, waypoints[:, 1])]
    )
    slot, lo, hi = forbidden_intervals(samples, spacing, speed, radius, others)
    hover = _earliest(count, spacing / speed, slot, lo, hi)
    if hover is None:
        return None
    return _flight(waypoints, along, s, hover, speed)


def _earliest(
    count: int, travel: float, slot: NDArray[np.intp], lo: Array, hi: Array
) -> dict[int, float] | None:
    """SIPP on the chain of sample points: hover seconds per sample of the fastest safe
    flight, or None. A state is (end of its safe interval, earliest arrival, parent);
    between points with no forbidden interval nothing can happen, so those stretches are
    jumped. Plain Python: a point has one to three safe intervals, too few for numpy; the
    arrivals and the ends of their intervals are kept in lists of their own, as the loop
    runs once per sample point that has a forbidden interval (hundreds per path)."""
    points = np.unique(slot).tolist()
    bounds = np.searchsorted(slot, [*points, count]).tolist()
    his, los = hi.tolist(), lo.tolist()
    inf, n_points, last = math.inf, len(points), count - 1
    nxt = 1 if points and points[0] == 0 else 0
    start = _safe(his, los, bounds, 0) if nxt else [(-inf, inf)]
    inside = [d for c, d in start if c <= 0.0 < d]
    if not inside:
        return None  # hovering at the start is unsafe from t = 0
    ends, arrivals = inside[:1], [0.0]
    # Trail entries: (sample, [(arrival, parent index in the previous entry)]).
    trail: list[tuple[int, list[tuple[float, int]]]] = [(0, [(0.0, -1)])]
    k = 0
    while k < last:
        target = points[nxt] if nxt < n_points else last
        if target > k + 1:  # free points up to target - 1: fly on from the best state
            best = min(range(len(arrivals)), key=arrivals.__getitem__)
            arrivals = [arrivals[best] + (target - 1 - k) * travel]
            trail.append((target - 1, [(arrivals[0], best)]))
            ends, k = [inf], target - 1
        if nxt < n_points and points[nxt] == k + 1:
            a, b = bounds[nxt], bounds[nxt + 1]
            nxt += 1
        else:
            a = b = 0  # no forbidden interval: one safe interval, (-inf, inf)
        states, new_ends, new_arrivals = [], [], []
        latest = max(ends)  # no state departs later: later safe intervals are out of reach
        for m in range(a, b + 1):  # safe interval (his[m - 1], los[m]), -inf and inf at the ends
            c = his[m - 1] if m > a else -inf
            if c - travel > latest:
                break
            d = los[m] if m < b else inf
            first, parent, earliest = inf, -1, c - travel
            for i, arrival in enumerate(arrivals):
                depart = max(arrival, earliest)
                if depart <= ends[i] and depart + travel <= d and depart + travel < first:
                    first, parent = depart + travel, i
            if parent >= 0:
                states.append((first, parent))
                new_ends.append(d)
                new_arrivals.append(first)
        if not states:
            return None
        trail.append((k + 1, states))
        ends, arrivals = new_ends, new_arrivals
        k += 1
    return _hovers(trail, travel)


def _safe(
    his: list[float], los: list[float], bounds: list[int], index: int
) -> list[tuple[float, float]]:
    """Safe intervals of the index-th point with forbidden intervals: between them."""
    a, b = bounds[index], bounds[index + 1]
    return list(zip([-math.inf, *his[a:b]], [*los[a:b], math.inf], strict=True))


def _hovers(trail: list[tuple[int, list[tuple[float, int]]]], travel: float) -> dict[int, float]:
    """Walk the chosen states back from the goal: how long the UAV hovers at each point."""
    hover: dict[int, float] = {}
    last = trail[-1][1]
    index = min(range(len(last)), key=lambda i: last[i][0])
    for (k, states), (k_prev, previous) in zip(
        reversed(trail[1:]), reversed(trail[:-1]), strict=True
    ):
        arrival, parent = states[index]
        wait = arrival - (k - k_prev) * travel - previous[parent][0]
        if wait > 1e-9:
            hover[k_prev] = wait
        index = parent
    return hover


def _flight(
    waypoints: Array, along: Array, s: Array, hover: dict[int, float], speed: float
) -> Trajectory:
    """The path with a hover inserted at each chosen sample point."""
    stops = {float(a): 0.0 for a in along}
    corners = np.array(sorted(stops))
    for k, wait in hover.items():
        near = corners[np.argmin(np.abs(corners - s[k]))]
        where = float(near) if abs(near - s[k]) < 1e-9 else float(s[k])
        stops[where] = stops.get(where, 0.0) + wait
    at = np.array(sorted(stops))
    points = np.column_stack(
        [np.interp(at, along, waypoints[:, 0]), np.interp(at, along, waypoints[:, 1])]
    )
    return Trajectory.from_waypoints(points, speed, np.array([stops[a] for a in at]))
