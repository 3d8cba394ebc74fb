"""The complete start: when the safe start struggles, plan the whole fleet at once.

The safe start (`planner.flows.anytime.safe_start`) makes one UAV safe at a time against
the others held fixed. That is fast and gives short plans, but it is incomplete: in a
maze, a crowded room or a corridor swap one UAV can be walled in by flights already
fixed, and where it is not, a maze's space-time searches can take seconds each. Then
(`planner.flows.anytime.safe_start` says when) the fleet is searched as a whole
(`planner.search.lacam`, complete on the 4-connected grid) and its steps become flights:

- every step lasts `step_s` = one cell at the slowest UAV's speed (rounded up to the
  plan's time grid), so no UAV flies faster than its speed and all move in lockstep;
- in lockstep, two UAVs that never share a cell or swap come no closer than √½ cell
  (one turning in behind another that turns away); so the flights are safe whenever
  every pair's radii add up to less than that (CORNER_REACH; the default radius 0.3 of
  a cell gives 0.6), and they stay inside free cells while every radius is below half a
  cell. They are recorded without a pass of the exact check (for 200 UAVs that pass
  costs ten times the search); the plan returned is checked from scratch as every
  plan is, and `tests/unit/test_complete_start.py` checks the geometry exactly.

The flights are then the first safe plan. The safe start goes on from where it was (now
within the time budget): its plan, if it gets there, is kept when it is cheaper, as it
mostly is (any-angle, fewer hovers). The improvement phase then shortens whichever is
kept while the budget lasts.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from planner.flows.budget import Budget
from planner.flows.engine import Engine
from planner.flows.planning import Map, Phase
from planner.model.trajectory import DIGITS, Trajectory
from planner.search import lacam

CORNER_REACH = 0.7  # below √½: the closest two lockstep UAVs come, in cells
MAX_TABLE_CELLS = 25_000_000  # UAVs x free cells: the search's distance tables, int32
MAX_NODES = 200_000


def why_not(engine: Engine, free: NDArray[np.bool_]) -> str | None:
    """Why the complete start cannot plan this fleet (None: it can)."""
    specs = list(engine.state.specs.values())
    radii = sorted((s.radius for s in specs), reverse=True)
    if radii and radii[0] >= 0.5:
        return f"a radius of {radii[0]:g} cells leaves its cell"
    if len(radii) > 1 and radii[0] + radii[1] >= CORNER_REACH:
        return f"two radii add up to {radii[0] + radii[1]:g} cells (at most {CORNER_REACH})"
    goals = [s.goal for s in specs]
    if len(set(goals)) < len(goals):
        return "two UAVs share a goal cell"
    if len(specs) * int(free.sum()) > MAX_TABLE_CELLS:
        return f"{len(specs)} UAVs on {int(free.sum())} free cells is too large"
    return None


def complete_start(engine: Engine, world: Map, free: NDArray[np.bool_], start: Budget) -> str:
    """Plan the whole fleet at once beside the safe start: if the complete search solves
    it, its flights are recorded as a safe plan (the first one, or a cheaper one), and
    the safe start goes on from where it was, its paths untouched. Returns what
    happened, in a few words (the plan's `complete_start`)."""
    reason = why_not(engine, free)
    if reason is not None:
        return f"not tried: {reason}"
    state = engine.state
    specs = list(state.specs.values())
    found = lacam.search(
        free,
        [s.start for s in specs],
        [s.goal for s in specs],
        np.random.default_rng(state.settings.seed),  # the safe start's own draws unchanged
        MAX_NODES,
        start.expired,
    )
    if found.outcome != "solved":
        return f"{found.outcome} after {found.nodes} configurations"
    step = step_s(min(s.speed for s in specs))
    flights = {
        spec.id: lockstep_flight(cells, step).quantised(spec.speed)
        for spec, cells in zip(specs, zip(*found.steps, strict=True), strict=True)
    }
    replans = {u: [*state.replans.get(u, []), Phase.COMPLETE_START.value] for u in flights}
    engine.record(flights, replans)
    engine.step(specs[0].id, Phase.COMPLETE_START, world)
    return f"safe: {len(found.steps) - 1} steps of {step:g} s"


def step_s(slowest: float) -> float:
    """One cell at `slowest` cells per second, rounded up to the plan's time grid."""
    scale = 10.0**DIGITS
    return math.ceil(scale / slowest) / scale


def lockstep_flight(cells: Sequence[tuple[int, int] | None], step: float) -> Trajectory:
    """A UAV's cells, one a step (None once it has left), as a flight: its breakpoints
    where it starts, stops or turns, and its last cell when it leaves."""
    xy = np.array([c for c in cells if c is not None], dtype=float)
    times = np.arange(len(xy)) * step
    moves = np.diff(xy, axis=0)
    turns = np.any(moves[1:] != moves[:-1], axis=1)
    keep = np.concatenate([[True], turns, [True]]) if len(xy) > 1 else np.array([True])
    return Trajectory(np.column_stack([times, xy])[keep])
