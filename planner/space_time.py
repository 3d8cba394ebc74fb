"""Space-time A* around the other UAVs: the fallback when a UAV cannot wait its way through.

Hovering along its own path (`planner.sipp`) solves most conflicts, but not a head-on
meeting in a corridor: one of the two has to step aside. Then the UAV searches (cell,
time) space, 8-connected without corner cutting and with a wait action, against the
other UAVs' trajectories held fixed: the project's prioritized space-time A*
(`planner.references.prioritized`), whose every move is tested exactly. What makes it
affordable beside fifty flights is an index: the flights' positions every `BUCKET`
seconds, so that a move is tested only against the flights that can come near it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from planner.references.prioritized import (
    Move,
    SearchLimits,
    _Flight,
    _Search,
    _trajectory,
    min_gap,
)
from planner.scenario import UAVSpec
from planner.sipp import Mover
from planner.trajectory import Trajectory

BUCKET = 0.5  # seconds between the indexed positions of the other UAVs
DEFAULT_LIMITS = SearchLimits()
CLOCK_EVERY = 256  # move tests between two looks at the clock


class _OutOfTime(Exception):
    pass


@dataclass
class _IndexedSearch(_Search):
    """The reference search, testing each move only against the flights near it."""

    positions: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0, 2)))
    ends: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    reach: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    speeds: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    out_of_time: Callable[[], bool] = lambda: False
    tests: int = 0

    def safe(self, move: Move) -> bool:
        self.tests += 1
        if self.tests % CLOCK_EVERY == 0 and self.out_of_time():
            raise _OutOfTime
        t0, x0, y0, t1, _, _ = move
        if not self.flights:
            return True
        b = min(int(t0 / BUCKET + 0.5), self.positions.shape[0] - 1)
        gap = np.hypot(self.positions[b, :, 0] - x0, self.positions[b, :, 1] - y0)
        # Within a bucket a flight moves at most speed x (BUCKET / 2 + the move's time).
        near = (gap < self.reach + math.sqrt(2.0) + (t1 - t0) * self.speeds) & (self.ends >= t0)
        return all(
            min_gap(move, self.flights[k]) >= self.spec.radius + self.flights[k].radius
            for k in np.flatnonzero(near)
        )


def search(
    spec: UAVSpec,
    free: NDArray[np.bool_],
    others: Sequence[Mover],
    limits: SearchLimits = DEFAULT_LIMITS,
    out_of_time: Callable[[], bool] = lambda: False,
) -> Trajectory | None:
    """The earliest-arriving grid path with waits that keeps exactly clear of `others`,
    or None (expansion limit, horizon, or `out_of_time`, asked every CLOCK_EVERY moves)."""
    flights = [_Flight.of(o.trajectory, o.radius) for o in others]
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
    try:
        states = run.run()
    except _OutOfTime:
        return None
    if isinstance(states, str):
        return None
    return _trajectory(states)
