"""Space-time A* around the other UAVs: the fallback when a UAV cannot wait its way through.

Hovering along its own path (`planner.search.sipp`) solves most conflicts, but not a head-on
meeting in a corridor: one of the two has to step aside. Then the UAV searches (cell,
time) space, 8-connected without corner cutting and with a wait action, against the
other UAVs' trajectories held fixed (`Search`, the same space-time A* that the reference
`planner.references.prioritized` runs UAV after UAV), every move tested exactly. Time is
continuous: a straight move takes 1/speed, a diagonal √2/speed and a wait `wait`/speed;
states whose times fall in the same `resolution` bucket of a cell are merged, which
bounds the search. What makes it affordable beside fifty flights is an index: the
flights' positions every `BUCKET` seconds, so that a move is tested only against the
flights that can come near it (`search`).
"""

from __future__ import annotations

import functools
import heapq
import itertools
import math
import weakref
from bisect import bisect_right
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from planner.geometry.grid_search import GridGraph
from planner.model.scenario import UAVSpec
from planner.model.trajectory import Trajectory
from planner.search.sipp import Mover

MOVES = ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1), (0, 0))
_EPS = 1e-9
BUCKET = 0.5  # seconds between the indexed positions of the other UAVs
CLOCK_EVERY = 256  # move tests between two looks at the clock
GOALS_KEPT = 8  # distance fields kept per grid: a UAV is searched again after others change


@dataclass(frozen=True)
class SearchLimits:
    """Bounds on each UAV's search. Times are in cell times (1/speed of that UAV)."""

    max_expansions: int = 20_000
    horizon: float | None = None  # default: every planned flight's end + 2 (width + height)
    wait: float = 0.5
    resolution: float = 0.25
    start_hold: float = 1.0


@dataclass(frozen=True)
class Flight:
    """A planned trajectory as plain lists: the move test is pure Python for speed."""

    ts: list[float]
    xs: list[float]
    ys: list[float]
    radius: float

    @classmethod
    def of(cls, trajectory: Trajectory, radius: float) -> Flight:
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


def min_gap(move: Move, flight: Flight) -> float:
    """Smallest centre distance between a straight move and a flight while both fly.

    Between consecutive breakpoints of either, both move linearly, so the distance
    has a closed-form minimum on each piece: exact, nothing sampled. Every move of a
    space-time search is tested by this (thousands per search), so the flight's position
    (`Flight.at`) and the distance to each piece (`_segment_min`) are written out in the
    loop, with the same arithmetic.
    """
    t0, x0, y0, t1, x1, y1 = move
    ts, xs, ys = flight.ts, flight.xs, flight.ys
    lo = ts[0] if ts[0] > t0 else t0  # max(t0, ts[0]), min(t1, ts[-1]), without the calls
    hi = ts[-1] if ts[-1] < t1 else t1
    if lo > hi:
        return math.inf
    inner = ts[bisect_right(ts, lo) : bisect_right(ts, hi)]
    last = len(ts) - 2
    span, mx, my = t1 - t0, x1 - x0, y1 - y0
    best = math.inf
    px = py = 0.0
    for n, t in enumerate([lo, *(t for t in inner if lo < t < hi), hi]):
        u = 0.0 if t1 <= t0 else (t - t0) / span
        k = bisect_right(ts, t) - 1
        k = 0 if k < 0 else k
        k = last if k > last else k
        if k < 0:
            fx, fy = xs[0], ys[0]
        else:
            a, b = ts[k], ts[k + 1]
            v = 0.0 if b <= a else _unit((t - a) / (b - a))
            fx, fy = xs[k] + v * (xs[k + 1] - xs[k]), ys[k] + v * (ys[k + 1] - ys[k])
        cx, cy = x0 + u * mx - fx, y0 + u * my - fy
        if n:
            dx, dy = cx - px, cy - py
            d2 = dx * dx + dy * dy
            w = 0.0 if d2 == 0 else _unit(-(px * dx + py * dy) / d2)
            gap = math.hypot(px + w * dx, py + w * dy)
            best = gap if gap < best else best
        px, py = cx, cy
    return best


def _unit(x: float) -> float:
    """min(max(x, 0.0), 1.0), the same float (NaN and -0.0 included), without two calls."""
    return 0.0 if x < 0.0 else 1.0 if x > 1.0 else x


def _segment_min(p: tuple[float, float], q: tuple[float, float]) -> float:
    """Distance from the origin to the segment p-q."""
    dx, dy = q[0] - p[0], q[1] - p[1]
    d2 = dx * dx + dy * dy
    s = 0.0 if d2 == 0 else min(max(-(p[0] * dx + p[1] * dy) / d2, 0.0), 1.0)
    return math.hypot(p[0] + s * dx, p[1] + s * dy)


@dataclass
class Search:
    """One UAV's space-time A* against the flights planned before it."""

    spec: UAVSpec
    free: NDArray[np.bool_]  # indexed [x, y]; obstacles and objects are not free
    flights: list[Flight]
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


def to_trajectory(states: list[tuple[float, int, int]]) -> Trajectory:
    """States as a trajectory; a run of waits becomes one hover (two points)."""
    keep = [
        s
        for i, s in enumerate(states)
        if i in (0, len(states) - 1)
        or not (s[1:] == states[i - 1][1:] and s[1:] == states[i + 1][1:])
    ]
    return Trajectory(np.array(keep, dtype=float))


DEFAULT_LIMITS = SearchLimits()


class _OutOfTime(Exception):
    pass


@dataclass
class _IndexedSearch(Search):
    """The reference search, testing each move only against the flights near it."""

    positions: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0, 2)))
    ends: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    reach: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    speeds: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    out_of_time: Callable[[], bool] = lambda: False
    tests: int = 0
    origins: list[tuple[float, float, float]] = field(default_factory=list)  # of moves tested
    touched: set[int] = field(default_factory=set)  # flights any move was tested against
    _near_key: tuple[float, float, float] | None = None
    _near: list[int] = field(default_factory=list)
    to_goal: NDArray[np.float64] | None = None  # cell times to the goal round the obstacles

    def h(self, x: int, y: int) -> float:
        """The time to the goal round the obstacles (`to_goal`), else the octile one.

        Both are admissible and consistent, but the octile distance ignores the
        obstacles: on 250 UAVs on 250x250 (seed 1) it was 219 where the way round them
        is 228, and the search spent its 20,000 expansions on states up to those 9 s
        late; with the true distance the same search took 820."""
        if self.to_goal is None:
            return super().h(x, y)
        return float(self.to_goal.item(x, y))

    def safe(self, move: Move) -> bool:
        self.tests += 1
        if self.tests % CLOCK_EVERY == 0 and self.out_of_time():
            raise _OutOfTime
        t0, x0, y0, _, _, _ = move
        if not self.flights:
            return True
        if self._near_key != (t0, x0, y0):  # the moves of one expansion share their origin
            b = min(int(t0 / BUCKET + 0.5), self.positions.shape[0] - 1)
            gap = np.hypot(self.positions[b, :, 0] - x0, self.positions[b, :, 1] - y0)
            # Within a bucket a flight moves at most speed x (BUCKET / 2 + the move's time):
            # the longest move from here (a diagonal, or a wait) bounds every one of them.
            longest = max(math.sqrt(2.0), self.limits.wait) / self.spec.speed
            near = (gap < self.reach + math.sqrt(2.0) + longest * self.speeds) & (self.ends >= t0)
            self._near_key, self._near = (t0, x0, y0), np.flatnonzero(near).tolist()
            self.origins.append((t0, x0, y0))
            self.touched.update(self._near)
        radius, flights = self.spec.radius, self.flights
        for k in self._near:
            flight = flights[k]
            if not min_gap(move, flight) >= radius + flight.radius:
                return False
        return True


def search(
    spec: UAVSpec,
    free: NDArray[np.bool_],
    others: Sequence[Mover],
    limits: SearchLimits = DEFAULT_LIMITS,
    out_of_time: Callable[[], bool] = lambda: False,
    failures: dict[str, Failure] | None = None,
) -> Trajectory | None:
    """The earliest-arriving grid path with waits that keeps exactly clear of `others`,
    or None (expansion limit, horizon, or `out_of_time`, asked every CLOCK_EVERY moves).

    With `failures`, a search that found nothing is remembered per UAV, and not run
    again while the flights it would meet are those it failed against (`Failure`)."""
    flights = [Flight.of(o.trajectory, o.radius) for o in others]
    side = free.shape[0] + free.shape[1]
    horizon = max((f.ts[-1] for f in flights), default=0.0) + 2 * side / spec.speed
    end = max((f.ts[-1] for f in flights), default=0.0)
    times = np.arange(0.0, end + BUCKET, BUCKET)
    positions = (
        np.stack(
            [o.trajectory.at(np.minimum(times, o.trajectory.end_time)) for o in others], axis=1
        )
        if others
        else np.zeros((1, 0, 2))
    )
    speeds = np.array([o.speed for o in others])
    run = _IndexedSearch(
        spec,
        free,
        flights,
        limits,
        horizon,
        positions=positions,
        ends=np.array([o.trajectory.end_time for o in others]),
        reach=np.array([spec.radius + o.radius for o in others]) + speeds * BUCKET / 2,
        speeds=speeds,
        out_of_time=out_of_time,
    )
    known = None if failures is None else failures.get(spec.id)
    if known is not None and known.fails_again(run, others):
        return None
    run.to_goal = goal_distances(free, spec.goal) / spec.speed
    try:
        states = run.run()
    except _OutOfTime:
        return None
    if failures is not None:
        failures.pop(spec.id, None)
        if isinstance(states, str):
            failures[spec.id] = Failure.of(run, others)
    if isinstance(states, str):
        return None
    return to_trajectory(states)


@dataclass
class _Goals:
    """A grid's graph and the distance fields of the goals searched last."""

    graph: GridGraph
    fields: OrderedDict[tuple[int, int], NDArray[np.float64]] = field(default_factory=OrderedDict)


_GOALS: dict[int, tuple[weakref.ref[NDArray[np.bool_]], _Goals]] = {}
"""By grid (its free map's identity): the safe start searches on one grid, often the
same UAV again. An entry goes when its free map is dropped."""


def goal_distances(free: NDArray[np.bool_], goal: tuple[int, int]) -> NDArray[np.float64]:
    """Every cell's shortest 8-connected distance to `goal` without cutting corners, the
    moves `Search` makes (inf where cut off), as [x, y]: one Dijkstra, kept for the
    GOALS_KEPT goals asked last on this grid."""
    key = id(free)
    hit = _GOALS.get(key)
    if hit is None or hit[0]() is not free:
        hit = (weakref.ref(free, functools.partial(_forget, key)), _Goals(GridGraph.build(~free)))
        _GOALS[key] = hit
    goals = hit[1]
    distances = goals.fields.get(goal)
    if distances is None:
        distances = goals.graph.distances_to(goal)
        goals.fields[goal] = distances
        if len(goals.fields) > GOALS_KEPT:
            goals.fields.popitem(last=False)
    goals.fields.move_to_end(goal)
    return distances


def _forget(key: int, ref: weakref.ref[NDArray[np.bool_]]) -> None:
    hit = _GOALS.get(key)
    if hit is not None and hit[0] is ref:
        del _GOALS[key]


@dataclass(frozen=True)
class Failure:
    """A search that found nothing, and all it read besides the grid: the other flights
    and which of them any move was tested against, from where. Searching again, the
    same UAV on the same grid and horizon, against flights that changed only where no
    move looked (none tested against before, none near any tested origin now), would
    test every move alike and fail alike: the safe start retries a UAV after each other
    UAV's change, and on 250 UAVs on 250x250 (seed 1) one UAV's search ran out of
    expansions 16 times, 1.7 s each, the same way each time."""

    spec: UAVSpec
    limits: SearchLimits
    free: NDArray[np.bool_]
    horizon: float
    buckets: int
    others: list[tuple[Trajectory, float, float]]  # trajectory, radius, speed
    touched: frozenset[int]
    origins: NDArray[np.float64]  # (E, 3): t, x, y of every move's origin tested

    @classmethod
    def of(cls, run: _IndexedSearch, others: Sequence[Mover]) -> Failure:
        return cls(
            run.spec,
            run.limits,
            run.free,
            run.horizon,
            run.positions.shape[0],
            [(o.trajectory, o.radius, o.speed) for o in others],
            frozenset(run.touched),
            np.array(run.origins, dtype=float).reshape(-1, 3),
        )

    def fails_again(self, run: _IndexedSearch, others: Sequence[Mover]) -> bool:
        """Whether `run` (not started) would test every move as this one did."""
        same = (
            run.spec == self.spec
            and run.limits == self.limits
            and run.free is self.free
            and run.horizon == self.horizon
            and run.positions.shape[0] == self.buckets
            and len(others) == len(self.others)
        )
        if not same:
            return False
        for k, (o, (trajectory, radius, speed)) in enumerate(zip(others, self.others, strict=True)):
            if (o.radius, o.speed) != (radius, speed):
                return False
            moved = o.trajectory is not trajectory and not np.array_equal(
                o.trajectory.points, trajectory.points
            )
            if moved and (k in self.touched or self._comes_near(run, k)):
                return False
        return True

    def _comes_near(self, run: _IndexedSearch, k: int) -> bool:
        """Whether flight k passes `_IndexedSearch.safe`'s index test at any origin tested
        (the same arithmetic, for all origins at once)."""
        t0, x0, y0 = self.origins.T
        b = np.minimum((t0 / BUCKET + 0.5).astype(int), run.positions.shape[0] - 1)
        gap = np.hypot(run.positions[b, k, 0] - x0, run.positions[b, k, 1] - y0)
        longest = max(math.sqrt(2.0), run.limits.wait) / run.spec.speed
        reach = run.reach[k] + math.sqrt(2.0) + longest * run.speeds[k]
        return bool(np.any((gap < reach) & (run.ends[k] >= t0)))
