"""Algorithm 1 of the paper: explore (white hole), exploit (black hole), wormhole.

`algorithm_1` is the algorithm as the paper states it; the steps below it are what it
calls. Both flows use `exploit` (the anytime flow for what its safe start left) and
`stop_reason`; the paper's flow also `improve_in_turn` with `qos`.
"""

from __future__ import annotations

import time
from collections import Counter

from planner.check.safety import cell_conflicts
from planner.flows.budget import StopReason
from planner.flows.engine import Engine
from planner.flows.planning import ATTEMPTS, FINISH_S, Map, Phase, adjoining_start_distance
from planner.flows.white_hole import Exploration, explore
from planner.geometry.grid_search import cell_map


def algorithm_1(engine: Engine, obstacles: Map) -> tuple[Exploration, Map]:
    """Algorithm 1 of the paper, from every UAV's shortest grid path:

    1. explore (white hole): CPS(i, j), PC_i, UMR (eq. 3), OTP (eq. 4), ImP (eq. 7);
    2. exploit (black hole, eq. 8): while UAVs conflict, the one with the highest ImP
       searches a new path against the others, held fixed;
    3. wormhole (eq. 9): the objects block their cells, only the UAVs they touch
       replan, and step 2 runs again on what that changed.

    Returns what the white hole found first (the plan reports it) and the map the plan
    is finished on. The paper meets the objects only in step 3; with `qos` the searches
    of step 2 already keep clear of them, so that a detour never runs into one.
    """
    state = engine.state
    first = explore_fleet(engine, obstacles)  # 1
    state.start_distance = adjoining_start_distance(state.scenario, first.priority)  # eq. 10
    engine.record_if_safe()
    known = cell_map(state.objects, obstacles.blocked.shape)
    qos = state.settings.objective == "qos"
    exploit(engine, Map.of(obstacles.blocked, known) if qos else obstacles)  # 2
    world = wormhole(engine, obstacles)  # 3
    if state.objects and world is obstacles:  # no UAV touched an object: block them anyway
        world = Map.of(obstacles.blocked | known)
    engine.record_if_safe()
    return first, world


def explore_fleet(engine: Engine, world: Map) -> Exploration:
    """The white hole on every pair, as the final check does: its time is kept back."""
    state = engine.state
    started = time.perf_counter()
    first = explore(state.paths, state.radii, state.shortest, state.objects, world.blocked.shape)
    state.budget.keep_back(2.0 * (time.perf_counter() - started) + FINISH_S)
    return first


def exploit(engine: Engine, world: Map) -> None:
    """The black hole (eq. 8): the UAV in trouble with the highest ImP (eq. 7) replans
    until none is left, or until every UAV in trouble has failed ATTEMPTS times since the
    last success (the search is random, so a second try from where the first left off
    often succeeds). With a time budget each run gets a fair share of what is left."""
    state = engine.state
    state.use_world(world)
    failures: Counter[str] = Counter()
    for _ in range(6 * len(state.specs)):
        if state.budget.expired():
            state.stopped_by_budget = True
            return
        troubled = state.table.troubled()
        candidates = [u for u in troubled if failures[u] < ATTEMPTS]
        if not candidates:
            return
        uav = candidates[0]
        share = state.budget.remaining() / (len(troubled) + 1)
        if engine.replan(uav, world, Phase.CONFLICT, share) and uav not in state.table.troubled():
            failures.clear()
        else:
            failures[uav] += 1


def wormhole(engine: Engine, world: Map) -> Map:
    """The wormhole (eq. 9): the objects block their cells; only the UAVs they touch
    replan, highest ImP first, and the black hole runs again on what that changed."""
    state = engine.state
    if not state.objects:
        return world
    object_map = cell_map(state.objects, world.blocked.shape)
    touched = [
        u
        for u in state.specs
        if cell_conflicts(u, state.paths[u], state.specs[u].radius, object_map)
    ]
    if not touched:
        return world
    world = Map.of(world.blocked | object_map)
    state.use_world(world)
    for uav in sorted(touched, key=lambda u: -state.table.priority(u)):
        if state.budget.expired():
            state.stopped_by_budget = True
            break
        share = state.budget.remaining() / (len(touched) + 1)
        engine.replan(uav, world, Phase.OBJECT, share)
    exploit(engine, world)
    return world


def improve_in_turn(engine: Engine, world: Map) -> StopReason:
    """The paper's flow with `qos`: with the fleet safe, each UAV in turn, most excess
    cost first, searches again against the others; rounds end when none improves."""
    state = engine.state
    wanted = state.settings.objective == "qos" and state.settings.improve_rounds > 0
    if state.best is None or not wanted:
        return stop_reason(engine)
    state.back_to_best(world)
    state.use_world(world)
    for _ in range(state.settings.improve_rounds):
        excess = {u: state.base_cost(u) - state.shortest[u] for u in state.paths}
        improved = False
        for uav in sorted(state.paths, key=lambda u: -excess[u]):
            if state.budget.expired():
                state.stopped_by_budget = True
                return "budget"
            improved |= engine.replan(uav, world, Phase.IMPROVEMENT)
        if state.stopped_by_budget:
            return "budget"
        if not improved:
            return "converged"
    return "iterations"


def stop_reason(engine: Engine) -> StopReason:
    """Without an improvement phase: the budget if it cut a run short, converged if
    every run converged (or none was needed), else the iteration budget."""
    state = engine.state
    if state.stopped_by_budget:
        return "budget"
    return "converged" if state.converged_runs == state.runs else "iterations"
