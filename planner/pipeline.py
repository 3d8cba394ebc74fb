"""`plan`: a scenario to a plan, by one of the two flows of Algorithm 1.

The anytime `qos` flow (`planner.flows.anytime`: lone paths, a safe start, then the optimizer
where it pays) unless the objective is `paper` or `safe_start` is off; then Algorithm 1
as the paper runs it (`planner.flows.algorithm_1`: explore, exploit, wormhole), followed with
`qos` by the improvement phase. How the two flows differ: `planner.flows.policies`.

The planner is anytime: `time_budget_s` (default 5 s) bounds the wall time, every
optimizer run also stops when it has converged (`patience`), and every moment the
fleet passes the exact check is recorded (the first one's time is reported). With
`time_budget_s=None` only the iteration budgets bound it and the same seed gives the
same plan, bit for bit. The plan is judged by the exact continuous-time check: it is
feasible only if that check finds nothing; the cheapest plan that passed it is returned.
"""

from __future__ import annotations

import numpy as np

from planner.flows.algorithm_1 import algorithm_1, improve_in_turn
from planner.flows.anytime import plan_anytime
from planner.flows.budget import Budget
from planner.flows.conflict_table import ConflictTable
from planner.flows.engine import Engine
from planner.flows.plan_report import finish
from planner.flows.planning import (
    ATTEMPTS,
    IMPROVEMENT,
    MAX_HOVER,
    MIN_GAIN,
    Map,
    Phase,
    PlannerSettings,
    PlanningState,
    PlanProgress,
    ProgressCallback,
)
from planner.flows.policies import paper_flow
from planner.geometry.grid_search import shortest_lengths
from planner.model.plan import Plan
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory, merge_collinear
from planner.optimizers import get_algorithm

__all__ = [
    "ATTEMPTS",
    "IMPROVEMENT",
    "MAX_HOVER",
    "MIN_GAIN",
    "Phase",
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
    return plan_paper(scenario, settings, progress)


def plan_paper(
    scenario: Scenario, settings: PlannerSettings, progress: ProgressCallback | None
) -> Plan:
    """Algorithm 1 from every UAV's shortest grid path, then (qos) the improvement."""
    budget = Budget(settings.time_budget_s)
    obstacles = Map.of(scenario.blocked())
    specs = {u.id: u for u in scenario.uavs}
    paths = {}
    for u in scenario.uavs:
        cells = obstacles.route(u.start, u.goal)
        assert cells is not None, "the scenario's validation guarantees a path"
        paths[u.id] = Trajectory.from_waypoints(merge_collinear(cells), u.speed)
    rng = np.random.default_rng(settings.seed)
    radii = {u.id: u.radius for u in scenario.uavs}
    table = ConflictTable.build(paths, radii, obstacles.blocked)
    shortest = shortest_lengths(scenario)
    objects = scenario.object_cells()
    state = PlanningState(
        scenario, settings, progress, rng, specs, paths, shortest, {}, objects, budget, table
    )
    engine = Engine(state, paper_flow(settings))
    first, world = algorithm_1(engine, obstacles)
    reason = improve_in_turn(engine, world)
    if state.best is not None:
        state.paths = state.best.paths
        state.replans = state.best.replans
    return finish(state, obstacles, first, reason)
