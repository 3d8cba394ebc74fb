"""pymapf 0.9.0's LaCAM and prioritized planning as reference planners, run in-process.

Both plan on pymapf's discrete grid (see `planner.references.cbs` for its
conventions): one move per time step, obstacles and non-UAV objects blocked, and only
vertex and swap conflicts seen. We time every step on one clock for the whole fleet:
a straight step takes one cell time of the slowest UAV and, with diagonals, √2 of
them, so that no UAV ever flies faster than its speed. The plans are then judged by
our exact check (`planner.references.judge`).

LaCAM stops itself at its time limit. pymapf's prioritized planning has no limit of
its own, so it is interrupted by a timer signal when it runs in the main thread.
"""

from __future__ import annotations

import contextlib
import math
import signal
import threading
import time
from collections.abc import Iterator
from typing import Any

from planner.model.scenario import Scenario
from planner.references import ReferenceResult
from planner.references.cbs import from_mapf, require_pymapf, to_mapf


class _OutOfTime(Exception):
    pass


@contextlib.contextmanager
def _deadline(seconds: float) -> Iterator[None]:
    """Raise _OutOfTime in the main thread after `seconds` (no limit elsewhere)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum: int, frame: Any) -> None:
        raise _OutOfTime

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _problem(scenario: Scenario, diagonals: bool) -> Any:
    pymapf = require_pymapf()
    grid, agents = to_mapf(scenario)
    return pymapf.MAPFProblem(
        pymapf.GridMap(grid),
        [pymapf.Agent(name, start, goal) for name, start, goal in agents],
        allow_diagonals=diagonals,
    )


def _solve(
    name: str, scenario: Scenario, solver: Any, diagonals: bool, limit: float
) -> ReferenceResult:
    problem = _problem(scenario, diagonals)
    started = time.perf_counter()
    try:
        with _deadline(limit + 1.0):  # LaCAM stops itself; this bounds the others
            solution = solver.solve(problem)
    except _OutOfTime:
        solution = None
    seconds = time.perf_counter() - started
    if solution is None:
        return ReferenceResult(name, None, False, seconds, f"no plan within {limit:g} s")
    step = (math.sqrt(2) if diagonals else 1.0) / min(u.speed for u in scenario.uavs)
    paths = {uid: [tuple(c) for c in cells] for uid, cells in solution.paths.items()}
    note = f"one grid step per {step:.3g} s"
    return ReferenceResult(name, from_mapf(paths, step), True, seconds, note)


def plan_lacam(
    scenario: Scenario, time_limit: float = 5.0, diagonals: bool = False, seed: int = 0
) -> ReferenceResult:
    """LaCAM's first solution (pymapf 0.9.0), 4- or 8-connected."""
    pymapf = require_pymapf()
    solver = pymapf.LaCAM(time_limit=time_limit, seed=seed)
    name = f"LaCAM (pymapf), {'8' if diagonals else '4'}-connected"
    return _solve(name, scenario, solver, diagonals, time_limit)


def plan_pymapf_prioritized(
    scenario: Scenario, time_limit: float = 5.0, diagonals: bool = False
) -> ReferenceResult:
    """pymapf's prioritized planning in the scenario's order of UAVs."""
    pymapf = require_pymapf()
    heuristic = "chebyshev" if diagonals else "manhattan"
    solver = pymapf.PrioritizedPlanning(heuristic=heuristic)
    name = f"prioritized (pymapf), {'8' if diagonals else '4'}-connected"
    return _solve(name, scenario, solver, diagonals, time_limit)
