"""The optimal CBS solver of `pymapf` (0.9.0) as a reference planner.

pymapf plans on a `GridMap` built from `grid[row][col]` (truthy = blocked) with
cells as (row, col), i.e. (y, x); moves are 4-connected by default and one time
step each, with an optional 8-connected mode (`allow_diagonals`) whose diagonals
also take one step and whose corners are not cut. A solution is a list of cells per
agent, index = time step, ending on the goal where the agent then stays. Only
vertex conflicts (same cell, same step) and swaps count as collisions.

We block obstacles and non-UAV objects, run CBS in a child process that is killed
at the time limit, and time its steps on one clock for the whole fleet: one step
per cell time of the slowest UAV, so that CBS's synchronous steps still line up
and no UAV flies straight faster than its speed. In 8-connected mode a diagonal
then goes √2 times too fast, as CBS assumes; `planner.references.judge` reports it,
and it reports the UAVs that cross on a diagonal, which CBS does not see.
"""

from __future__ import annotations

import multiprocessing
import time
from multiprocessing.connection import Connection
from multiprocessing.context import ForkContext, SpawnContext
from typing import Any

import numpy as np

from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory
from planner.references import ReferenceResult

NAME = "CBS (pymapf)"
INSTALL_HINT = "pip install -e '.[mapf]'"
GRACE = 1.0
"""Seconds past the time limit before the child is killed (CBS stops itself first)."""

RowCol = tuple[int, int]
Agents = list[tuple[str, RowCol, RowCol]]


class MapfDependencyError(ImportError):
    """pymapf (the 'mapf' extra) is not installed."""


def require_pymapf() -> Any:
    """The pymapf module, or an error that says how to install it."""
    try:
        import pymapf
    except ImportError as exc:
        raise MapfDependencyError(
            f"the CBS reference needs pymapf 0.9.0 ({exc}); install it with: {INSTALL_HINT}"
        ) from exc
    return pymapf


def to_mapf(scenario: Scenario) -> tuple[list[list[int]], Agents]:
    """pymapf's occupancy rows (y) of columns (x), objects blocked, and (id, start, goal)."""
    blocked = scenario.blocked()
    for cell in scenario.object_cells():
        blocked[cell] = True
    agents = [(u.id, (u.start[1], u.start[0]), (u.goal[1], u.goal[0])) for u in scenario.uavs]
    return blocked.T.astype(int).tolist(), agents


def from_mapf(paths: dict[str, list[RowCol]], step: float) -> dict[str, Trajectory]:
    """One cell per `step` seconds; a run of waits becomes one hover (two points)."""
    out = {}
    for uid, cells in paths.items():
        points = [(k * step, float(c), float(r)) for k, (r, c) in enumerate(cells)]
        keep = [
            p
            for k, p in enumerate(points)
            if k in (0, len(points) - 1) or not (p[1:] == points[k - 1][1:] == points[k + 1][1:])
        ]
        out[uid] = Trajectory(np.array(keep, dtype=float))
    return out


def _solve(
    conn: Connection,
    grid: list[list[int]],
    agents: Agents,
    diagonals: bool,
    time_limit: float,
    max_expansions: int,
) -> None:
    """Child process: run CBS and send back ("solved", paths, expansions) or ("failed", why)."""
    try:
        pymapf = require_pymapf()
        problem = pymapf.MAPFProblem(
            pymapf.GridMap(grid),
            [pymapf.Agent(name, start, goal) for name, start, goal in agents],
            allow_diagonals=diagonals,
        )
        reasons: list[str] = []

        def observe(event: Any) -> None:
            if event.kind == "failed":
                reasons.append(event.get("reason", ""))

        solver = pymapf.ConflictBasedSearch(
            # Manhattan overestimates with unit-cost diagonals; Chebyshev keeps CBS optimal.
            heuristic="chebyshev" if diagonals else "manhattan",
            max_expansions=max_expansions,
            time_limit=time_limit,
        )
        solution = solver.solve(problem, observer=observe)
        if solution is None:
            conn.send(("failed", "; ".join(reasons) or "no solution"))
        else:
            paths = {name: [tuple(c) for c in p] for name, p in solution.paths.items()}
            conn.send(("solved", paths, solution.expansions))
    except Exception as exc:  # the parent reports it; a child traceback would be lost
        conn.send(("failed", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def _context() -> ForkContext | SpawnContext:
    """Fork where there is one: the child then starts in milliseconds, imports done."""
    if "fork" in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("fork")
    return multiprocessing.get_context("spawn")


def _run_child(args: tuple[Any, ...], time_limit: float) -> tuple[Any, ...] | None:
    """The child's message, or None if it had to be killed at the time limit."""
    ctx = _context()
    receive, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_solve, args=(send, *args), daemon=True)
    child.start()
    send.close()
    try:
        if receive.poll(time_limit + GRACE):
            message: tuple[Any, ...] = receive.recv()
            return message
        return None
    except EOFError:
        return ("failed", f"the CBS process died (exit code {child.exitcode})")
    finally:
        if child.is_alive():
            child.kill()
        child.join()
        receive.close()


def plan_cbs(
    scenario: Scenario,
    time_limit: float = 10.0,
    diagonals: bool = False,
    max_expansions: int = 100_000,
) -> ReferenceResult:
    """CBS on the scenario's grid; 'timed out' in the note if it did not finish in time."""
    require_pymapf()  # fail here, with the install hint, not inside the child
    started = time.perf_counter()
    grid, agents = to_mapf(scenario)
    message = _run_child((grid, agents, diagonals, time_limit, max_expansions), time_limit)
    seconds = time.perf_counter() - started
    name = f"{NAME}, {'8' if diagonals else '4'}-connected"
    if message is None:
        return ReferenceResult(name, None, False, seconds, f"timed out after {time_limit:g} s")
    if message[0] == "failed":
        reason = message[1]
        note = f"timed out: {reason}" if reason.startswith("time limit") else reason
        return ReferenceResult(name, None, False, seconds, note)
    _, paths, expansions = message
    step = 1.0 / min(u.speed for u in scenario.uavs)
    note = f"{expansions} constraint-tree nodes; one grid step per {step:g} s"
    return ReferenceResult(name, from_mapf(paths, step), True, seconds, note, expansions)
