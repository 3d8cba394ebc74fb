"""Algorithm 1 of the paper: explore (white hole), exploit (black hole), wormhole.

`plan` runs the anytime `qos` flow of `planner.anytime` (a safe start, then the
optimizer where it pays) unless the objective is `paper` or `safe_start` is off; then
it runs Algorithm 1 as the paper does, below.

1. Every UAV starts on its shortest grid path.
2. While two UAVs' paths conflict, the conflicting UAV with the highest priority
   (eq. 7) searches a new path with the optimizer against the others' paths (eq. 8),
   and the white hole is run again on the result.
3. The non-UAV objects are placed; only the UAVs whose path one of them touches
   replan (eq. 9), now with the objects blocked, and step 2 runs again if that
   created a new conflict.
4. With the `qos` objective, what time is left improves the plan: each UAV in turn,
   most excess length first, searches again against the others; a new path is kept
   only if it is cheaper and the exact check still passes.
5. The plan is judged by the exact continuous-time check: it is feasible only
   if that check finds nothing. The cheapest plan that passed it is returned.

The planner is anytime: `time_budget_s` (default 5 s) bounds the wall time, every
optimizer run also stops when it has converged (`patience`), and every moment the
fleet passes the exact check is recorded (the first one's time is reported). With
`time_budget_s=None` only the iteration budgets bound it and the same seed gives the
same plan, bit for bit.
"""

from __future__ import annotations

import time

import numpy as np

from planner.anytime import plan_anytime
from planner.budget import Budget
from planner.conflict_table import ConflictTable
from planner.grid_search import cell_map, shortest_lengths
from planner.optimizers import get_algorithm
from planner.plan import Plan
from planner.planning import (
    ATTEMPTS,
    FINISH_S,
    IMPROVEMENT,
    MAX_HOVER,
    MIN_GAIN,
    Map,
    PlannerSettings,
    PlanProgress,
    ProgressCallback,
    _Planning,
    adjoining_start_distance,
    finish,
)
from planner.scenario import Scenario
from planner.trajectory import Trajectory, merge_collinear

__all__ = [
    "ATTEMPTS",
    "IMPROVEMENT",
    "MAX_HOVER",
    "MIN_GAIN",
    "PlanProgress",
    "PlannerSettings",
    "ProgressCallback",
    "plan",
]


DEFAULT_SETTINGS = PlannerSettings()


def plan(
    scenario: Scenario,
    settings: PlannerSettings = DEFAULT_SETTINGS,
    progress: ProgressCallback | None = None,
) -> Plan:
    """Collision-free paths for every UAV of the scenario, or an infeasible plan that says why."""
    get_algorithm(settings.algorithm)  # fail fast on an unknown name
    if settings.objective == "qos" and settings.safe_start:
        return plan_anytime(scenario, settings, progress)
    budget = Budget(settings.time_budget_s)
    obstacles = Map.of(scenario.blocked())
    specs = {u.id: u for u in scenario.uavs}
    objects = scenario.object_cells()
    paths = {}
    for u in scenario.uavs:
        cells = obstacles.route(u.start, u.goal)
        assert cells is not None, "the scenario's validation guarantees a path"
        paths[u.id] = Trajectory.from_waypoints(merge_collinear(cells), u.speed)
    shortest = shortest_lengths(scenario)
    rng = np.random.default_rng(settings.seed)
    radii = {u.id: u.radius for u in scenario.uavs}
    table = ConflictTable.build(paths, radii, obstacles.blocked)
    state = _Planning(
        scenario, settings, progress, rng, specs, paths, shortest, {}, objects, budget, table
    )
    checked = time.perf_counter()
    first = state.explore(obstacles)  # every pair, as the final check does: time it
    budget.keep_back(2.0 * (time.perf_counter() - checked) + FINISH_S)
    state.start_distance = adjoining_start_distance(scenario, first.priority)
    state.record_if_safe()

    # The paper plans around the UAVs first and meets the objects only in the wormhole
    # step. With `qos` the searches already keep clear of the objects the scenario
    # declares, so a detour never runs into one; the wormhole step still replans the
    # UAVs whose first paths the objects touch, and only those.
    known = cell_map(objects, obstacles.blocked.shape)
    first_world = Map.of(obstacles.blocked, known) if settings.objective == "qos" else obstacles
    state.resolve_conflicts(first_world)
    world = state.wormhole(obstacles)
    if state.objects and world is obstacles:  # no UAV touched an object: block them anyway
        world = Map.of(obstacles.blocked | known)
    state.record_if_safe()
    reason = state.improve(world)
    if state.best is not None:
        state.paths = state.best.paths
        state.replans = state.best.replans
    return finish(state, obstacles, first, reason)
