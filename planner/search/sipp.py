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

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planner.model.trajectory import Trajectory

Array = NDArray[np.float64]
STEP = 0.1  # cells between sample points, and cells another UAV moves between samples


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
    widened by half the time to pass one sample, sorted by k then lo."""
    lower = samples.min(axis=0)
    upper = samples.max(axis=0)
    passing = spacing / speed / 2
    slots, los, his = [], [], []
    tree = cKDTree(samples)
    for other in others:
        need = radius + other.radius + spacing / 2 + STEP / 2
        period = STEP / max(other.speed, 1e-9)
        traj = other.trajectory
        if _apart(traj.xy, lower - need, upper + need):
            continue  # never near: no need to sample it
        times = np.arange(0.0, traj.end_time + period, period)
        times[-1] = min(times[-1], traj.end_time)
        where = traj.at(times)
        near = np.all((where >= lower - need) & (where <= upper + need), axis=1)
        if not near.any():
            continue
        times, where = times[near], where[near]
        pairs = cKDTree(where).sparse_distance_matrix(tree, need, output_type="ndarray")
        if not len(pairs):
            continue
        slots.append(pairs["j"].astype(np.intp))
        at = times[pairs["i"]]
        widen = period / 2 + passing
        los.append(at - widen)
        his.append(at + widen)
    if not slots:
        return np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0)
    return _merge(np.concatenate(slots), np.concatenate(los), np.concatenate(his))


def _apart(xy: Array, lower: Array, upper: Array) -> bool:
    """Whether a flight through the points `xy` stays outside the box [lower, upper]
    (its positions lie in the box of its points; a margin for interpolation's rounding)."""
    return bool(np.any(xy.min(axis=0) > upper + 1e-9) or np.any(xy.max(axis=0) < lower - 1e-9))


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
    jumped. Plain Python: a point has one to three safe intervals, too few for numpy."""
    points = np.unique(slot).tolist()
    bounds = np.searchsorted(slot, [*points, count]).tolist()
    his, los = hi.tolist(), lo.tolist()

    def gaps(index: int) -> list[tuple[float, float]]:
        """Safe intervals of the index-th point with forbidden intervals."""
        a, b = bounds[index], bounds[index + 1]
        return list(zip([-math.inf, *his[a:b]], [*los[a:b], math.inf], strict=True))

    # Trail entries: (sample, [(arrival, parent index in the previous entry)]).
    start = gaps(0) if points and points[0] == 0 else [(-math.inf, math.inf)]
    inside = [(lo_, hi_) for lo_, hi_ in start if lo_ <= 0.0 < hi_]
    if not inside:
        return None  # hovering at the start is unsafe from t = 0
    ends = [inside[0][1]]
    trail: list[tuple[int, list[tuple[float, int]]]] = [(0, [(0.0, -1)])]
    k, nxt = 0, 1 if points and points[0] == 0 else 0
    while k < count - 1:
        target = points[nxt] if nxt < len(points) else count - 1
        arrivals = trail[-1][1]
        if target > k + 1:  # free points up to target - 1: fly on from the best state
            best = min(range(len(arrivals)), key=lambda i: arrivals[i][0])
            k_free = target - 1
            trail.append((k_free, [(arrivals[best][0] + (k_free - k) * travel, best)]))
            ends, k = [math.inf], k_free
            arrivals = trail[-1][1]
        nexts = gaps(nxt) if nxt < len(points) and points[nxt] == k + 1 else [(-math.inf, math.inf)]
        states, new_ends = [], []
        for c, d in nexts:
            first, parent = math.inf, -1
            for i, (arrival, _) in enumerate(arrivals):
                depart = max(arrival, c - travel)
                if depart <= ends[i] and depart + travel <= d and depart + travel < first:
                    first, parent = depart + travel, i
            if parent >= 0:
                states.append((first, parent))
                new_ends.append(d)
        if not states:
            return None
        trail.append((k + 1, states))
        ends = new_ends
        if nxt < len(points) and points[nxt] == k + 1:
            nxt += 1
        k += 1
    return _hovers(trail, travel)


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
