"""The plan as returned: the fleet judged by the exact check, with its metrics.

`finish` builds it from the planning state; `table_report` is the exact check's
report read from the conflict table (for a plan that is not safe, at no extra cost);
`refused` is the anytime flow's answer when the safe start's time limit ran out before
the fleet's lone paths were even known to conflict or not.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.check.safety import SafetyReport, cell_conflicts, check_plan, uav_conflicts
from planner.flows.budget import Budget, StopReason
from planner.flows.planning import Map, PlannerSettings, PlanningState
from planner.flows.white_hole import Exploration
from planner.model.plan import Metrics, Plan, PlannedUAV
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory, merge_collinear
from planner.optimizers import get_algorithm
from planner.search.objectives import paper_fitness

Route = list[tuple[int, int]]


def finish(
    state: PlanningState,
    world: Map,
    first: Exploration,
    reason: StopReason,
    report: SafetyReport | None = None,
) -> Plan:
    """The plan as returned, judged by the exact check (or by `report`, an exact verdict
    already at hand for a plan that is not safe)."""
    if report is None:
        report = check_plan(state.paths, state.radii, world.blocked, state.objects)
    count = len(state.specs) + len(state.objects)
    uavs, fitness = [], []
    for uid, spec in state.specs.items():
        trajectory = state.paths[uid]
        deviation = float(np.hypot(*(trajectory.end - np.array(spec.goal))))
        fitness.append(
            float(paper_fitness(count, trajectory.length, deviation, state.start_distance[uid]))
        )
        uavs.append(
            PlannedUAV(
                id=uid,
                trajectory=trajectory.to_json(),
                length=round(trajectory.length, 6),
                deviation=round(deviation, 6),
                priority=round(first.priority[uid], 6),
                moving_rate=round(first.moving_rate[uid], 6),
                threat=round(first.threat[uid], 6),
                shortest_length=round(state.shortest[uid], 6),
                replanned=state.replans.get(uid, []),
            )
        )
    closest = report.min_separation
    final_cost = state.fleet_cost()
    improvement = None
    if report.safe and state.first_safe_cost:
        improvement = (state.first_safe_cost - final_cost) / state.first_safe_cost
    metrics = Metrics(
        conflicts=len(report.conflicts),
        min_separation=None if not np.isfinite(closest) else round(closest, 6),
        mean_deviation=round(float(np.mean([u.deviation for u in uavs])), 6),
        total_length=round(sum(u.length for u in uavs), 6),
        J=round(float(np.mean(fitness)), 6),
        nfe=state.nfe,
        seconds=round(state.budget.elapsed(), 4),
        replans=state.runs,
        iterations_run=state.iterations_run,
        first_safe_s=_rounded(state.first_safe_s, 4),
        first_safe_cost=_rounded(state.first_safe_cost, 6),
        cost=round(final_cost, 6),
        improvement=_rounded(improvement, 6),
        complete_start=state.complete_start,
    )
    settings = state.settings
    return Plan(
        stop_reason=reason,
        time_budget_s=settings.time_budget_s,
        feasible=report.safe,
        algorithm=get_algorithm(settings.algorithm).name,
        objective=settings.objective,
        seed=settings.seed,
        population=settings.population,
        iterations=settings.iterations,
        scenario=state.scenario.name,
        uavs=uavs,
        non_uav_objects=[list(c) for c in state.objects],
        metrics=metrics,
        conflicts=[c.to_json() for c in report.conflicts],
        history=[round(h, 6) for h in state.history],
    )


def _rounded(value: float | None, digits: int) -> float | None:
    return None if value is None else round(value, digits)


def table_report(
    state: PlanningState, obstacles: NDArray[np.bool_], objects: NDArray[np.bool_]
) -> SafetyReport:
    """The exact check's report from the conflict table: its pairs in conflict (in fleet
    order) and the cells of the UAVs it counts inside one."""
    order = {u: k for k, u in enumerate(state.specs)}
    conflicts = sorted(state.table.pairs.values(), key=lambda c: sorted(order[u] for u in c.uavs))
    for uav, hits in state.table.cell_hits.items():
        if hits:
            radius = state.specs[uav].radius
            conflicts += cell_conflicts(uav, state.paths[uav], radius, obstacles, "obstacle")
            conflicts += cell_conflicts(uav, state.paths[uav], radius, objects, "non_uav_object")
    if state.table.pairs:
        closest = min(c.separation for c in state.table.pairs.values())
    else:
        closest = uav_conflicts(state.paths, state.radii)[1]
    return SafetyReport(conflicts, closest)


def refused(
    scenario: Scenario,
    settings: PlannerSettings,
    budget: Budget,
    routes: dict[str, Route],
    shortest: dict[str, float],
    doing: str,
) -> Plan:
    """The plan when the safe start's time limit (`safe_start_limit_s`) ran out before the
    fleet's lone paths were even known to conflict or not (`doing` says which limit, what
    was being done and how long it would have needed): infeasible, the routed UAVs on
    their grid paths, the others on their starts, and one conflict that says so (no exact
    check: nothing here is meant to be flown)."""
    missing = [u.id for u in scenario.uavs if u.id not in routes] or [u.id for u in scenario.uavs]
    message = f"planning refused: {doing}; give it more time or plan fewer UAVs"
    uavs = []
    for u in scenario.uavs:
        cells = routes.get(u.id, [u.start])
        trajectory = Trajectory.from_waypoints(merge_collinear(np.array(cells, float)), u.speed)
        uavs.append(
            PlannedUAV(
                id=u.id,
                trajectory=trajectory.to_json(),
                length=round(trajectory.length, 6),
                deviation=round(float(np.hypot(*(trajectory.end - np.array(u.goal)))), 6),
                priority=0.0,
                moving_rate=round(shortest.get(u.id, float("nan")), 6),
                threat=0.0,
                shortest_length=round(shortest.get(u.id, float("nan")), 6),
                replanned=[],
            )
        )
    return Plan(
        stop_reason="budget",
        time_budget_s=settings.time_budget_s,
        feasible=False,
        algorithm=get_algorithm(settings.algorithm).name,
        objective=settings.objective,
        seed=settings.seed,
        population=settings.population,
        iterations=settings.iterations,
        scenario=scenario.name,
        uavs=uavs,
        non_uav_objects=[list(c) for c in scenario.object_cells()],
        metrics=Metrics(
            conflicts=1,
            min_separation=None,
            mean_deviation=round(float(np.mean([u.deviation for u in uavs])), 6),
            total_length=round(sum(u.length for u in uavs), 6),
            J=0.0,
            nfe=0,
            seconds=round(budget.elapsed(), 4),
            replans=0,
            iterations_run=0,
        ),
        conflicts=[{"kind": "budget", "uavs": missing, "message": message}],
        history=[],
    )
