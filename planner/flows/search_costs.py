"""What one UAV's search (the black hole, eq. 8) costs against the fleet as it stands.

A `Search` scores paths of one UAV against every other UAV's flight, held fixed, and
the blocked cells (read as the flow says: a raster or exactly); the costs here are the
current path's and the rest of the fleet's, as the progress reports and the history
count them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.flows.conflict_table import NEAR
from planner.flows.planning import Map, PlanningState, as_waypoints
from planner.flows.policies import Corridor, Flow, Region
from planner.search.black_hole import Search
from planner.search.objectives import PaperObjective, QosObjective
from planner.search.path_cost import Traffic

Array = NDArray[np.float64]


def objective(state: PlanningState, uav: str, penalty: float) -> QosObjective | PaperObjective:
    """`qos`, or eq. (10) with the UAV's Dist(t0)."""
    if state.settings.objective == "qos":
        return QosObjective(state.specs[uav].speed, penalty)
    count = len(state.specs) + len(state.objects)
    return PaperObjective(count, state.start_distance[uav], penalty)


def search(
    state: PlanningState,
    flow: Flow,
    uav: str,
    world: Map,
    region: Region,
    ignore: str | None = None,
    alone: bool = False,
    corridor: Corridor | None = None,
) -> Search:
    """Costs for `uav`'s paths inside `region` (and `corridor`, if given) against
    everything else (but `ignore`), held fixed; against the map only if `alone`."""
    spec = state.specs[uav]
    others = [
        (state.paths[u], state.specs[u].radius, state.specs[u].speed)
        for u in state.paths
        if u not in (uav, ignore) and not alone
    ]
    traffic = Traffic.around(
        others,
        radius=spec.radius,
        speed=spec.speed,
        start=np.array(spec.start, dtype=float),
        lower=region[0],
        upper=region[1],
        corridor=corridor,
    )
    return Search(
        spec.speed,
        spec.radius,
        np.array(spec.goal, dtype=float),
        traffic,
        flow.clearance(world, region, corridor, spec.radius),
        objective(state, uav, state.penalty(world)),
    )


def current_cost(
    state: PlanningState, flow: Flow, uav: str, world: Map, ignore: str | None = None
) -> float:
    """`uav`'s search cost of its own current path."""
    waypoints, waits = as_waypoints(state.paths[uav])
    region = (waypoints.min(axis=0), waypoints.max(axis=0))
    found = search(state, flow, uav, world, region, ignore)
    return float(found.cost(waypoints[None], waits[None])[0])


def lone_cost(state: PlanningState, flow: Flow, uav: str, world: Map) -> float:
    """`uav`'s search cost with no other UAV about, cached per path and map."""
    trajectory = state.paths[uav]
    cached = state.lone_costs.get(uav)
    if cached is None or cached[0] is not trajectory or cached[1] is not world:
        waypoints, waits = as_waypoints(trajectory)
        region = (waypoints.min(axis=0), waypoints.max(axis=0))
        alone = search(state, flow, uav, world, region, alone=True)
        cached = (trajectory, world, float(alone.cost(waypoints[None], waits[None])[0]))
        state.lone_costs[uav] = cached
    return cached[2]


def others_cost(state: PlanningState, flow: Flow, uav: str, world: Map) -> float:
    """The sum of every other UAV's search cost with `uav` left out of its traffic
    (the fleet cost of the progress reports and the history).

    Only a UAV that comes near another needs its traffic sampled: for the rest the
    sampled separation terms are zero, and the cost without traffic is the same
    number. With a time budget that sampling is skipped (it can take a quarter of
    the time on fifty UAVs): a conflict between two other UAVs then counts the
    penalty once, without its depth.
    """
    if state.settings.time_budget_s is not None:
        clash = state.penalty(world) * state.table.conflicts_without(uav)
        return clash + sum(lone_cost(state, flow, u, world) for u in state.paths if u != uav)
    total = 0.0
    for u in state.paths:
        if u == uav:
            continue
        if state.table.comes_near(u, NEAR, leave_out=uav):
            total += current_cost(state, flow, u, world, ignore=uav)
        else:
            total += lone_cost(state, flow, u, world)
    return total


def table_cost(state: PlanningState, world: Map) -> float:
    """Sum of the UAVs' costs, plus the penalty once per pair (or UAV in a blocked
    cell) in conflict: the fleet cost of a step that runs no search."""
    pairs = len(state.table.pairs) + sum(1 for h in state.table.cell_hits.values() if h)
    return sum(state.base_cost(u) for u in state.paths) + state.penalty(world) * pairs
