"""Prioritized planning with space-time A*: the classic decoupled reference.

UAVs are planned one after another; each searches (cell, time) space on the
8-connected grid without corner cutting, with a wait action, and treats the UAVs
planned before it as moving obstacles. Time is continuous: a straight move takes
1/speed, a diagonal √2/speed and a wait `wait`/speed, so the timing is physically
right. Every candidate move is tested exactly (closed form on each linear piece,
the same test as `planner.safety.closest_approach`) against the flights already
planned, so a returned plan is safe by OUR continuous-time check, not merely free
of MAPF vertex and edge conflicts. States whose times fall in the same
`resolution` bucket of a cell are merged, which bounds the search.

A UAV is airborne from t = 0 until its last point. A UAV not yet planned is held
on its start for `start_hold` cell times, so that the earlier ones leave it room
to take off; after that it is on its own and may fail, which is the usual price
of prioritized planning (incomplete: an order can fail where another succeeds).
"""

from __future__ import annotations

import heapq
import itertools
import math
import time
from bisect import bisect_right
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.references import ReferenceResult
from planner.scenario import Scenario, UAVSpec
from planner.trajectory import Trajectory

NAME = "prioritized A*"
MOVES = ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1), (0, 0))
_EPS = 1e-9


@dataclass(frozen=True)
class SearchLimits:
    """Bounds on each UAV's search. Times are in cell times (1/speed of that UAV)."""

    max_expansions: int = 20_000
    horizon: float | None = None  # default: every planned flight's end + 2 (width + height)
    wait: float = 0.5
    resolution: float = 0.25
    start_hold: float = 1.0


@dataclass(frozen=True)
class _Flight:
    """A planned trajectory as plain lists: the move test is pure Python for speed."""

    ts: list[float]
    xs: list[float]
    ys: list[float]
    radius: float

    @classmethod
    def of(cls, trajectory: Trajectory, radius: float) -> _Flight:
        t, x, y = trajectory.points.T.tolist()
        return cls(t, x, y, radius)

    def at(self, t: float) -> tuple[float, float]:
        k = min(max(bisect_right(self.ts, t) - 1, 0), len(self.ts) - 2)
        if k < 0:
            return self.xs[0], self.ys[0]
        t0, t1 = self.ts[k], self.ts[k + 1]
        u = 0.0 if t1 <= t0 else min(max((t - t0) / (t1 - t0), 0.0), 1.0)
        return (
            self.xs[k] + u * (self.xs[k + 1] - self.xs[k]),
            self.ys[k] + u * (self.ys[k + 1] - self.ys[k]),
        )


Move = tuple[float, float, float, float, float, float]  # t0, x0, y0, t1, x1, y1


def min_gap(move: Move, flight: _Flight) -> float:
    """Smallest centre distance between a straight move and a flight while both fly.

    Between consecutive breakpoints of either, both move linearly, so the distance
    has a closed-form minimum on each piece: exact, nothing sampled.
    """
    t0, x0, y0, t1, x1, y1 = move
    lo, hi = max(t0, flight.ts[0]), min(t1, flight.ts[-1])
    if lo > hi:
        return math.inf
    inner = flight.ts[bisect_right(flight.ts, lo) : bisect_right(flight.ts, hi)]
    times = [lo, *(t for t in inner if lo < t < hi), hi]

    def gap(t: float) -> tuple[float, float]:
        u = 0.0 if t1 <= t0 else (t - t0) / (t1 - t0)
        fx, fy = flight.at(t)
        return x0 + u * (x1 - x0) - fx, y0 + u * (y1 - y0) - fy

    best = math.inf
    prev = gap(times[0])
    for t in times[1:]:
        cur = gap(t)
        best = min(best, _segment_min(prev, cur))
        prev = cur
    return best


def _segment_min(p: tuple[float, float], q: tuple[float, float]) -> float:
    """Distance from the origin to the segment p-q."""
    dx, dy = q[0] - p[0], q[1] - p[1]
    d2 = dx * dx + dy * dy
    s = 0.0 if d2 == 0 else min(max(-(p[0] * dx + p[1] * dy) / d2, 0.0), 1.0)
    return math.hypot(p[0] + s * dx, p[1] + s * dy)


@dataclass
class _Search:
    """One UAV's space-time A* against the flights planned before it."""

    spec: UAVSpec
    free: NDArray[np.bool_]  # indexed [x, y]; obstacles and objects are not free
    flights: list[_Flight]
    limits: SearchLimits
    horizon: float
    expansions: int = 0

    def h(self, x: int, y: int) -> float:
        dx, dy = abs(x - self.spec.goal[0]), abs(y - self.spec.goal[1])
        return (max(dx, dy) + (math.sqrt(2) - 1) * min(dx, dy)) / self.spec.speed

    def can_step(self, x: int, y: int, dx: int, dy: int) -> bool:
        """On the grid, onto a free cell, never cutting the corner of a blocked one."""
        nx, ny = x + dx, y + dy
        width, height = self.free.shape
        if not (0 <= nx < width and 0 <= ny < height and self.free[nx, ny]):
            return False
        return not (dx and dy) or bool(self.free[nx, y] and self.free[x, ny])

    def safe(self, move: Move) -> bool:
        return all(min_gap(move, f) >= self.spec.radius + f.radius for f in self.flights)

    def run(self) -> list[tuple[float, int, int]] | str:
        """The earliest-arrival path as (t, x, y) states, or why there is none."""
        cell_time = 1.0 / self.spec.speed
        bucket = self.limits.resolution * cell_time
        sx, sy = self.spec.start
        nodes: list[tuple[float, int, int, int]] = [(0.0, sx, sy, -1)]
        tie = itertools.count()
        heap = [(self.h(sx, sy), self.h(sx, sy), next(tie), 0)]
        closed: set[tuple[int, int, int]] = set()
        while heap:
            _, _, _, k = heapq.heappop(heap)
            t, x, y, _ = nodes[k]
            key = (x, y, int(t / bucket + _EPS))
            if key in closed:
                continue
            closed.add(key)
            if (x, y) == self.spec.goal:
                return _unwind(nodes, k)
            self.expansions += 1
            if self.expansions > self.limits.max_expansions:
                return f"expansion limit ({self.limits.max_expansions}) reached"
            for dx, dy in MOVES:
                if (dx or dy) and not self.can_step(x, y, dx, dy):
                    continue
                duration = math.hypot(dx, dy) * cell_time or self.limits.wait * cell_time
                nt, nx, ny = t + duration, x + dx, y + dy
                if nt > self.horizon or (nx, ny, int(nt / bucket + _EPS)) in closed:
                    continue
                if not self.safe((t, x, y, nt, nx, ny)):
                    continue
                nodes.append((nt, nx, ny, k))
                h = self.h(nx, ny)
                heapq.heappush(heap, (nt + h, h, next(tie), len(nodes) - 1))
        return f"no safe path within the horizon of {self.horizon:.1f} s"


def _unwind(nodes: list[tuple[float, int, int, int]], k: int) -> list[tuple[float, int, int]]:
    out = []
    while k >= 0:
        t, x, y, k = nodes[k]
        out.append((t, x, y))
    return out[::-1]


def _trajectory(states: list[tuple[float, int, int]]) -> Trajectory:
    """States as a trajectory; a run of waits becomes one hover (two points)."""
    keep = [
        s
        for i, s in enumerate(states)
        if i in (0, len(states) - 1)
        or not (s[1:] == states[i - 1][1:] and s[1:] == states[i + 1][1:])
    ]
    return Trajectory(np.array(keep, dtype=float))


def _held(spec: UAVSpec, hold: float) -> _Flight:
    """A UAV not planned yet: hovering on its start for `hold` cell times."""
    x, y = map(float, spec.start)
    return _Flight([0.0, hold / spec.speed], [x, x], [y, y], spec.radius)


def plan_order(
    scenario: Scenario, order: Sequence[str], limits: SearchLimits
) -> tuple[dict[str, Trajectory] | str, int]:
    """Plan the UAVs in `order`; the trajectories, or which UAV failed and why."""
    specs = {u.id: u for u in scenario.uavs}
    free = ~scenario.blocked()
    for cell in scenario.object_cells():
        free[cell] = False
    side = scenario.grid.width + scenario.grid.height
    planned: dict[str, Trajectory] = {}
    flights: list[_Flight] = []
    expansions = 0
    for k, uid in enumerate(order):
        spec = specs[uid]
        waiting = [_held(specs[u], limits.start_hold) for u in order[k + 1 :]]
        horizon = limits.horizon
        if horizon is None:
            horizon = max((f.ts[-1] for f in flights), default=0.0) + 2 * side / spec.speed
        search = _Search(spec, free, flights + waiting, limits, horizon)
        states = search.run()
        expansions += search.expansions
        if isinstance(states, str):
            after = f" (after {', '.join(order[:k])})" if k else ""
            return f"{uid} found no path{after}: {states}", expansions
        planned[uid] = _trajectory(states)
        flights.append(_Flight.of(planned[uid], spec.radius))
    return planned, expansions


def plan_prioritized(
    scenario: Scenario,
    order: Sequence[str] | None = None,
    limits: SearchLimits = SearchLimits(),
    restarts: int = 0,
    seed: int = 0,
) -> ReferenceResult:
    """Prioritized planning in `order` (default: the scenario's), then, while it fails,
    in up to `restarts` random other orders."""
    started = time.perf_counter()
    ids = [u.id for u in scenario.uavs]
    first = list(order) if order is not None else ids
    if sorted(first) != sorted(ids):
        raise ValueError(f"order {first} is not a permutation of the UAV ids {ids}")
    notes: list[str] = []
    total = 0
    for attempt, current in enumerate(_orders(first, restarts, seed)):
        outcome, expansions = plan_order(scenario, current, limits)
        total += expansions
        if not isinstance(outcome, str):
            note = f"order {', '.join(current)}"
            if attempt:
                note += f" (attempt {attempt + 1}; earlier: {'; '.join(notes)})"
            return ReferenceResult(NAME, outcome, True, time.perf_counter() - started, note, total)
        notes.append(outcome)
    seconds = time.perf_counter() - started
    return ReferenceResult(NAME, None, False, seconds, "; ".join(notes), total)


def _orders(first: list[str], restarts: int, seed: int) -> Iterator[list[str]]:
    """`first`, then its reverse, then random orders: `restarts` more at most, all distinct."""
    rng = np.random.default_rng(seed)
    seen: set[tuple[str, ...]] = set()
    candidates = itertools.chain(
        [first, first[::-1]],
        ([first[i] for i in rng.permutation(len(first))] for _ in range(100 * (restarts + 1))),
    )
    for order in candidates:
        if len(seen) > restarts:
            return
        if tuple(order) not in seen:
            seen.add(tuple(order))
            yield order
