"""The anytime `qos` planner: a fast safe start, then the black hole shortens what it can.

Algorithm 1 with its exploration made constructive (see docs/planner.md):

1. **Lone paths.** Every UAV's shortest 8-connected path (obstacles and the non-UAV
   objects blocked; a UAV whose obstacle-only path an object touches is the one the
   wormhole step, eq. 9, replans), with its string pulled and tightened round the
   corners it bends at (`planner.search.any_angle`): the any-angle polyline a UAV alone would
   fly, every shortcut exactly clear of blocked cells.
2. **Safe start (white hole).** While two flights conflict, the UAV in trouble with the
   highest priority ImP (eq. 7) is made safe against all the others, held fixed: first by
   hovering where it must along its own path (safe intervals, `planner.search.sipp`), else
   (on a long trip, after the UAVs it meets tried hovering out of its way) by a space-time
   A* that may step aside (`planner.search.space_time`). Each success removes every
   conflict of that UAV and creates none, so the loop ends after at most one success per
   UAV; a UAV that cannot be made safe waits until another one's path changes. When
   this loop struggles (a dense fleet, a fourth space-time search, a UAV it cannot make
   safe), the whole fleet is also searched at once, beside it (the complete start,
   `planner.flows.complete_start`): its plan is the first safe one, and this loop's, if
   it gets there within half the budget, replaces it when cheaper. What is left
   otherwise is handed to the optimizer (step 2 of the paper's Algorithm 1) while time lasts.
3. **Improvement (black hole, eq. 8).** Only UAVs whose flight costs noticeably more than
   their lone path (they hover or detour because others are near) are worked on, most
   excess first: first they are re-timed (their hovers recomputed against the others as
   they now fly), then the optimizer searches a window of their lone path round where
   they hover for a cheaper flight, against only the others near it. A change is kept
   only if it lowers the true cost and the exact check still passes. A round that gains
   less than `ROUND_GAIN` of the plan's cost ends planning as converged: that is where
   improvement stops paying.

The conflict table keeps the exact check's verdict for every pair as paths change, so the
first safe plan is known the moment it exists; the final plan is checked once more by
`planner.check.safety.check_plan`. Steps 1 and 2 never read the clock (unless the hard limit
`safe_start_limit_s` is set), so the first safe plan is the same however loaded the
machine is; the time budget decides only how long step 3 (and the optimizer's repair of
what step 2 left) runs. Without a budget the same seed gives the same plan.
"""

from __future__ import annotations

import functools
import itertools
from collections import Counter

import numpy as np
from numpy.typing import NDArray

from planner.check.safety import cell_conflicts
from planner.flows import lone_paths
from planner.flows.algorithm_1 import exploit, stop_reason
from planner.flows.budget import Budget, StopReason
from planner.flows.complete_start import complete_start
from planner.flows.conflict_table import ConflictTable
from planner.flows.engine import Engine
from planner.flows.plan_report import finish, refused, table_report
from planner.flows.planning import (
    FINISH_S,
    MIN_GAIN,
    Map,
    Phase,
    PlannerSettings,
    PlanningState,
    ProgressCallback,
    adjoining_start_distance,
    flight_cost,
)
from planner.flows.policies import AnytimeFlow
from planner.flows.white_hole import Exploration, importance
from planner.geometry.grid_search import cell_map
from planner.model.plan import Plan
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory, merge_collinear
from planner.search import space_time
from planner.search.any_angle import pull_strings
from planner.search.sipp import Mover, schedule
from planner.search.space_time import SearchLimits

ROUND_GAIN = 2e-3  # relative: a round of improvement that gains less has converged
MIN_EXCESS = 0.1  # of its lone path's cost: a UAV with less excess than this is left alone,
MIN_SHARE = 1e-2  # unless its excess is at least this share of the plan's cost
DENSE = 0.1  # UAVs per free cell from which the complete start runs first: MovingAI's
# room and maze maps with 100 agents (0.15), where the safe start took 8 to 40 s to finish
SEARCHES_BEFORE_COMPLETE = 4  # space-time searches: the benchmark's families need at most 2
# (random-32-32-10 with 50 agents 4), MovingAI's maze with 25 agents 7 taking 1.2 s, 50 agents 16
SAFE_START_SHARE = 50.0  # percent of the budget a safe start may take with a safe plan in hand
LONG_TRIP = 100.0  # cells of lone path from which the others are asked to make way first
PULLED_PIECES = (1, 4, 16)  # a search's path pulled whole and in runs: the cheapest is kept


def plan_anytime(
    scenario: Scenario, settings: PlannerSettings, progress: ProgressCallback | None
) -> Plan:
    """The `qos` plan: lone paths, safe start, improvement; see the module docstring.

    The time budget bounds only what follows the safe start (the optimizer's repair of
    what it left, and the improvement): the lone paths, their shaping, the conflict table
    and the safe start itself never read the clock, so the first safe plan is the same
    on an idle machine and on a loaded one. Only `safe_start_limit_s`, when set, stops
    them: the plan is then refused with how long they would have needed.
    """
    budget = Budget(settings.time_budget_s)
    start = Budget(settings.safe_start_limit_s, started=budget.started)
    specs = {u.id: u for u in scenario.uavs}
    obstacles = scenario.blocked()
    objects = scenario.object_cells()
    object_map = cell_map(objects, obstacles.shape)
    blocked = obstacles | object_map
    routes, first_routes, shortest = lone_paths.routes(scenario, obstacles, blocked, start)
    refuse = functools.partial(refused, scenario, settings, budget, routes, shortest)
    if len(routes) < len(specs):
        missing = [u.id for u in scenario.uavs if u.id not in routes]
        if start.expired():
            return refuse(_out_of_time(start, "routing", len(routes), len(specs)))
        return refuse(f"routing {len(routes)} of {len(specs)} UAVs ({_some(missing)} have no path)")
    geometry = lone_paths.shaped(scenario, routes, blocked, start)
    paths = {u.id: Trajectory.from_waypoints(geometry[u.id], u.speed) for u in scenario.uavs}
    world = Map(blocked, None, blocked)
    checked = budget.elapsed()
    table = ConflictTable({u.id: u.radius for u in scenario.uavs}, blocked)
    for count, (uav, trajectory) in enumerate(paths.items()):
        if start.expired():
            return refuse(_out_of_time(start, "checking the lone paths", count, len(paths)))
        table.update(uav, trajectory)
    # The final exact check covers every pair as the table's build did: keep its time back.
    budget.keep_back(2.0 * (budget.elapsed() - checked) + FINISH_S)
    rng = np.random.default_rng(settings.seed)
    state = PlanningState(
        scenario, settings, progress, rng, specs, paths, shortest, {}, objects, budget, table
    )
    lone = {u: Trajectory.from_waypoints(g, 1.0).length for u, g in geometry.items()}
    engine = Engine(state, AnytimeFlow(settings.improve_rounds > 0, geometry, lone))
    for uav in state.paths:
        if routes[uav] != first_routes[uav]:
            state.replans[uav] = [Phase.OBJECT.value]
    first = exploration(state, object_map, first_routes)
    state.start_distance = adjoining_start_distance(scenario, first.priority)
    engine.record_if_safe()
    safe_start(engine, world, ~blocked, start)
    if not state.table.clear() and state.best is None and not budget.expired():
        exploit(engine, world)  # what waiting and stepping aside could not solve
    reason = improve_where_it_pays(engine, world)
    judged = Map(obstacles, None, obstacles)
    if state.best is None:  # not safe: the table's exact verdict says why, at no extra cost
        return finish(state, judged, first, reason, table_report(state, obstacles, object_map))
    state.paths = state.best.paths
    state.replans = state.best.replans
    return finish(state, judged, first, reason)  # a fresh exact check has the last word


def _out_of_time(start: Budget, doing: str, done: int, total: int) -> str:
    """What a refusal says: the limit, how far the safe start got, and at the rate it
    went, at least how long it would have needed."""
    spent = start.elapsed()
    needed = spent * total / max(done, 1)
    return (
        f"the safe start's time limit of {start.seconds:g} s ran out while {doing} "
        f"({done} of {total} UAVs done in {spent:.2f} s); it would need at least "
        f"{needed:.1f} s (safe_start_limit_s)"
    )


def exploration(
    state: PlanningState, objects: NDArray[np.bool_], first: dict[str, lone_paths.Route]
) -> Exploration:
    """The white hole's metrics of the lone paths, from the conflict table (the same exact
    numbers as `planner.flows.white_hole.explore`, without a second pass over all pairs); OTP
    (eq. 4) counts the objects on each UAV's obstacle-only path, before the wormhole."""
    table = state.table
    collision_paths = {u: table.collision_paths(u) for u in state.paths}
    total = int(objects.sum())
    others = max(len(state.paths) - 1, 1)
    priority, threat = {}, {}
    for uav, trajectory in state.paths.items():
        pc = collision_paths[uav]
        priority[uav] = importance(pc, trajectory.end_time)
        share = _on_path(state, uav, first[uav], objects) / total if total else 0.0
        threat[uav] = len(pc) / others * share
    closest = min(table.closest.values(), default=float("inf"))
    conflicts = list(table.pairs.values())
    return Exploration(conflicts, collision_paths, priority, dict(state.shortest), threat, closest)


def _on_path(
    state: PlanningState, uav: str, route: lone_paths.Route, objects: NDArray[np.bool_]
) -> int:
    """How many non-UAV objects `uav`'s obstacle-only path touches (OTP's count, eq. 4)."""
    spec = state.specs[uav]
    flight = Trajectory.from_waypoints(merge_collinear(route), spec.speed)
    return len(cell_conflicts(uav, flight, spec.radius, objects))


def safe_start(engine: Engine, world: Map, free: NDArray[np.bool_], start: Budget) -> None:
    """Step 2 made constructive: the highest-priority UAV in trouble (eq. 7) is made
    safe against the others; one that cannot be waits for another one's change.

    When the fleet is dense (DENSE), when this loop has needed SEARCHES_BEFORE_COMPLETE
    space-time searches, or when a UAV cannot be made safe, whichever comes first, the
    complete start plans the whole fleet at once beside it (`planner.flows.complete_start`):
    a safe plan in hand, whatever this loop then manages. From then on this loop is
    improvement, and it ends at half the time budget (the other half is the improvement
    phase's); until then only `start`, the optional hard limit, is read here."""
    state = engine.state
    failed: Counter[str] = Counter()
    searches: dict[str, space_time.Failure] = {}  # the space-time searches that failed
    searched = 0

    def complete_if(needed: bool) -> None:
        if needed and state.complete_start is None:
            state.complete_start = complete_start(engine, world, free, start)

    complete_if(len(state.specs) >= DENSE * free.sum())
    while not start.expired() and not (
        state.best is not None and (state.budget.percent() or 0.0) >= SAFE_START_SHARE
    ):
        candidates = [u for u in state.table.troubled() if not failed[u]]
        if not candidates:
            return
        uav = candidates[0]
        flight = hover_flight(engine, uav)
        if flight is None and long_trip(engine, uav) and make_way(engine, uav, world):
            failed.clear()
            continue
        if flight is None:
            searched += 1
            complete_if(searched >= SEARCHES_BEFORE_COMPLETE)
            flight = stepped_aside(engine, uav, free, start, searches)
        if flight is not None and engine.adopt(uav, flight, Phase.SAFE_START):
            failed.clear()
        else:
            failed[uav] += 1
            complete_if(True)
        engine.step(uav, Phase.SAFE_START, world)
    state.stopped_by_budget = True


def hover_flight(engine: Engine, uav: str) -> Trajectory | None:
    """`uav` along its lone path, hovering where the others make it (`schedule`)."""
    state, flow = engine.state, engine.flow
    assert isinstance(flow, AnytimeFlow)
    spec = state.specs[uav]
    return schedule(flow.geometry[uav], spec.speed, spec.radius, movers(state, uav))


def long_trip(engine: Engine, uav: str) -> bool:
    """Whether `uav`'s lone path is at least LONG_TRIP cells: there a search's detour
    (8-connected, then pulled) costs more than the others' hovering (250 UAVs on 250x250:
    seeds 1 and 2 shorter than without `make_way`); on the dense families' short trips
    (10 to 80 cells) letting the others hover first made 3 of 12 plans longer, 3 shorter."""
    flow = engine.flow
    assert isinstance(flow, AnytimeFlow)
    return flow.lone[uav] >= LONG_TRIP


def make_way(engine: Engine, uav: str, world: Map) -> bool:
    """Whether any of the UAVs `uav` meets (on their lone paths too: those made safe meet
    nobody) hovered along its own path, each made safe in turn, so that `uav` may not
    have to step aside: a head-on meeting that one side cannot wait out, the other often
    can. Stepping aside costs length; hovering, only time. Tried before `uav`'s
    space-time search; all of them at once, so `uav` is tried again only once."""
    state = engine.state
    partners = {u for c in state.table.collision_paths(uav) for u in c.uavs if u != uav}
    moved = False
    for other in [u for u in state.table.troubled() if u in partners]:
        flight = hover_flight(engine, other)
        if flight is not None and engine.adopt(other, flight, Phase.SAFE_START):
            engine.step(other, Phase.SAFE_START, world)
            moved = True
    return moved


def stepped_aside(
    engine: Engine,
    uav: str,
    free: NDArray[np.bool_],
    start: Budget,
    failures: dict[str, space_time.Failure] | None = None,
) -> Trajectory | None:
    """A flight for `uav` clear of every other one when hovering along its lone path is
    not (`hover_flight`): a space-time search, whose path is then pulled (whole and in
    runs) and re-timed where that is cheaper; `failures`: the searches that failed, not
    run again where nothing they met changed."""
    state = engine.state
    spec, others, blocked = state.specs[uav], movers(state, uav), state.table.blocked
    found = space_time.search(spec, free, others, SearchLimits(), start.expired, failures)
    if found is None:
        return None
    best, cost = found, flight_cost(found, spec.speed)
    geometry = lone_paths.geometry_of(found)
    tried: list[NDArray[np.float64]] = []
    for pieces in PULLED_PIECES:
        runs = max(min(pieces, len(geometry) - 1), 1)
        pulled = pulled_in_pieces(geometry, runs, spec.radius, blocked)
        if any(np.array_equal(pulled, t) for t in tried):
            continue
        tried.append(pulled)
        retimed = schedule(pulled, spec.speed, spec.radius, others)
        if retimed is not None and flight_cost(retimed, spec.speed) < cost:
            best, cost = retimed, flight_cost(retimed, spec.speed)
    return best


def pulled_in_pieces(
    geometry: NDArray[np.float64], pieces: int, radius: float, blocked: NDArray[np.bool_]
) -> NDArray[np.float64]:
    """`geometry`'s string pulled in `pieces` runs of its corners, each end kept: the
    fewer the pieces, the shorter, but the further from where the search found a way."""
    cut = np.linspace(0, len(geometry) - 1, pieces + 1).round().astype(int)
    runs = [geometry[a : b + 1] for a, b in itertools.pairwise(cut)]
    pulled = pull_strings(runs, [radius] * len(runs), blocked)
    return np.concatenate([pulled[0], *(p[1:] for p in pulled[1:])])


def movers(state: PlanningState, uav: str) -> list[Mover]:
    """Every other UAV's flight, as the safe intervals see it."""
    return [
        Mover(state.paths[u], state.specs[u].radius, state.specs[u].speed)
        for u in state.paths
        if u != uav
    ]


def improve_where_it_pays(engine: Engine, world: Map) -> StopReason:
    """Rounds over the UAVs that pay for others being near, most excess first: re-time,
    then search (eq. 8). Ends when a round gains less than ROUND_GAIN of the cost."""
    state = engine.state
    if state.best is None or state.settings.improve_rounds <= 0:
        return stop_reason(engine)
    state.back_to_best(world)
    for _ in range(state.settings.improve_rounds):
        before = state.best.cost
        if not worth_improving(engine):
            return "converged"
        for uav in worth_improving(engine):
            if state.budget.expired():
                return "budget"
            retime(engine, uav, world)
        for uav in worth_improving(engine):
            if state.budget.expired():
                return "budget"
            engine.replan(uav, world, Phase.IMPROVEMENT)
        if state.budget.expired() or state.stopped_by_budget:
            return "budget"
        if before - state.best.cost < ROUND_GAIN * before:
            return "converged"
    return "iterations"


def worth_improving(engine: Engine) -> list[str]:
    """UAVs whose flight costs noticeably more than their lone path, most first; none
    if all of that excess together is less than a round must gain (the search can
    hardly do better than remove it)."""
    state, flow = engine.state, engine.flow
    assert state.best is not None and isinstance(flow, AnytimeFlow)
    floor = MIN_SHARE * state.best.cost
    excess = {u: state.base_cost(u) - flow.lone[u] for u in state.paths}
    worth = [u for u in state.paths if excess[u] > min(MIN_EXCESS * max(flow.lone[u], 1.0), floor)]
    if sum(excess[u] for u in worth) < ROUND_GAIN * state.best.cost:
        return []
    return sorted(worth, key=lambda u: -excess[u])


def retime(engine: Engine, uav: str, world: Map) -> None:
    """Hover again where the others, as they now fly, make it necessary: often less
    than when this UAV was made safe (some of them moved since)."""
    state = engine.state
    spec = state.specs[uav]
    current = state.paths[uav]
    geometry = lone_paths.geometry_of(current)
    flight = schedule(geometry, spec.speed, spec.radius, movers(state, uav))
    now = flight_cost(current, spec.speed)
    if flight is not None and flight_cost(flight, spec.speed) < now - MIN_GAIN * max(now, 1.0):
        engine.adopt(uav, flight, Phase.IMPROVEMENT)
    engine.step(uav, Phase.RETIME, world)


def _some(ids: list[str]) -> str:
    return ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "")
