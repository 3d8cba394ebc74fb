"""The anytime `qos` planner: a fast safe start, then the black hole shortens what it can.

Algorithm 1 with its exploration made constructive (see docs/planner.md):

1. **Lone paths.** Every UAV's shortest 8-connected path (obstacles and the non-UAV
   objects blocked; a UAV whose obstacle-only path an object touches is the one the
   wormhole step, eq. 9, replans), with its string pulled and tightened round the
   corners it bends at (`planner.any_angle`): the any-angle polyline a UAV alone would
   fly, every shortcut exactly clear of blocked cells.
2. **Safe start (white hole).** While two flights conflict, the UAV in trouble with the
   highest priority ImP (eq. 7) is made safe against all the others, held fixed: first by
   hovering where it must along its own path (safe intervals, `planner.sipp`), else by a
   space-time A* that may step aside (`planner.space_time`). Each success removes every
   conflict of that UAV and creates none, so the loop ends after at most one success per
   UAV; a UAV that cannot be made safe waits until another one's path changes. What is
   left is handed to the optimizer (step 2 of the paper's Algorithm 1) while time lasts.
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
`planner.safety.check_plan`. Nothing here reads the clock for a decision unless a time
budget is set, so without one the same seed gives the same plan.
"""

from __future__ import annotations

import functools
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from planner import space_time
from planner.any_angle import pull_string, tighten
from planner.budget import Budget, StopReason
from planner.clearance import ExactClearance, distance_to_polyline
from planner.conflict_table import ConflictTable
from planner.grid_search import GridGraph, cell_map
from planner.objectives import HOVER_PRICE
from planner.optimizers import get_algorithm
from planner.path_encoding import DetourEncoding, TurnEncoding
from planner.plan import Metrics, Plan, PlannedUAV
from planner.planning import (
    FINISH_S,
    IMPROVEMENT,
    MAX_HOVER,
    MIN_GAIN,
    Best,
    Map,
    PlannerSettings,
    PlanProgress,
    ProgressCallback,
    _Planning,
    adjoining_start_distance,
    as_waypoints,
    finish,
)
from planner.safety import SafetyReport, cell_conflicts, uav_conflicts
from planner.scenario import Scenario
from planner.sipp import Mover, schedule
from planner.space_time import SearchLimits
from planner.trajectory import Trajectory, merge_collinear
from planner.white_hole import Exploration, importance

Array = NDArray[np.float64]
SAFE_START = "safe start"  # the reason recorded for a path of the safe start
RETIME = "re-time"  # what progress reports while the improvement phase re-times a UAV
ROUND_GAIN = 2e-3  # relative: a round of improvement that gains less has converged
MIN_EXCESS = 0.1  # of its lone path's cost: a UAV with less excess than this is left alone,
MIN_SHARE = 1e-2  # unless its excess is at least this share of the plan's cost
IMPROVE_ITERATIONS = 40  # at most, per improvement run
IMPROVE_PATIENCE = 15  # iterations without gain that end an improvement run
WINDOW = 5.0  # cells of lone path searched on either side of where a UAV hovers
SHAPING_SHARE = 0.3  # of the time budget: past it, lone paths are no longer shortened


@dataclass
class _Anytime(_Planning):
    """Algorithm 1's state with each UAV's lone path as the anchor of its searches."""

    geometry: dict[str, Array] = field(default_factory=dict)  # lone any-angle polyline
    lone: dict[str, float] = field(default_factory=dict)  # its length
    free: NDArray[np.bool_] = field(default_factory=lambda: np.zeros((0, 0), dtype=bool))

    def clearance(
        self,
        world: Map,
        region: tuple[Array, Array],
        corridor: tuple[Array, float] | None,
        radius: float,
    ) -> ExactClearance:
        """Exact clearance from the blocked cells the search's paths can reach: those near
        its corridor, else those in its region."""
        if corridor is not None:
            polyline, reach = corridor
        else:
            lo, hi = region
            polyline, reach = np.array([lo, hi]), float(np.hypot(*(hi - lo))) / 2
        return ExactClearance.near(world.searched, polyline, reach + radius)

    def better(
        self, uav: str, trajectory: Trajectory, cost: float, before: float, reason: str
    ) -> bool:
        """An improvement must lower the plan's true cost (length and hover price), not
        only the search's sampled one; making a UAV safe goes by the search's cost."""
        if reason != IMPROVEMENT:
            return super().better(uav, trajectory, cost, before, reason)
        current = self.flight_cost(uav, self.paths[uav])
        return self.flight_cost(uav, trajectory) < current - MIN_GAIN * max(current, 1.0)

    def corridor(self, encoding: DetourEncoding | TurnEncoding) -> tuple[Array, float] | None:
        """Only the other UAVs' samples near the lone path matter to its search."""
        return encoding.corridor() if isinstance(encoding, DetourEncoding) else None

    def run_iterations(self, reason: str) -> int:
        """An improvement run starts from a safe plan and polishes it: a short run, whose
        schedule (MVO's WEP and TDR, eqs. 3.3-3.4 of the MVO paper) anneals within it."""
        if reason == IMPROVEMENT:
            return min(self.settings.iterations, IMPROVE_ITERATIONS)
        return self.settings.iterations

    def patience(self, reason: str) -> int | None:
        """Improvement runs start from a safe plan and only polish it: they converge
        sooner than runs that must first find a safe path."""
        if reason == IMPROVEMENT and self.settings.patience is not None:
            return min(self.settings.patience, IMPROVE_PATIENCE)
        return self.settings.patience

    def encoding(self, uav: str, world: Map) -> DetourEncoding:
        """The optimizer moves the lone path's points and picks a hover at each, only in a
        window round where the UAV now hovers (the rest of its path has nothing to gain):
        a long path then costs a search of a few points, not of all of them."""
        horizon = max((t.end_time for u, t in self.paths.items() if u != uav), default=1.0)
        max_wait = min(horizon + 1.0, MAX_HOVER)
        lone = self.geometry[uav]
        window = _hover_window(self.paths[uav], lone)
        if window is None:
            return DetourEncoding.around(lone, max_wait=max_wait)
        before, inner, after = _split(lone, *window)
        return DetourEncoding.around(inner, max_wait=max_wait, before=before, after=after)

    def record_if_safe(self) -> None:
        """The conflict table holds the exact check's verdict on every pair and every cell
        (`planner.conflict_table`), so a clear table is a fleet that passes it."""
        if not self.table.clear():
            return
        cost = sum(self.base_cost(u) for u in self.paths)
        if self.first_safe_s is None:
            self.first_safe_s, self.first_safe_cost = self.budget.elapsed(), cost
        if self.best is None or cost < self.best.cost:
            replans = {u: list(r) for u, r in self.replans.items()}
            self.best = Best(dict(self.paths), replans, cost)

    def fleet_cost(self, world: Map) -> float:
        """Sum of the UAVs' costs, plus the penalty once per pair in conflict."""
        pairs = len(self.table.pairs) + sum(1 for h in self.table.cell_hits.values() if h)
        return sum(self.base_cost(u) for u in self.paths) + self.penalty(world) * pairs

    def movers(self, uav: str) -> list[Mover]:
        return [
            Mover(self.paths[u], self.specs[u].radius, self.specs[u].speed)
            for u in self.paths
            if u != uav
        ]

    def step(self, uav: str, reason: str, world: Map) -> None:
        """One non-optimizer replan as a run of one iteration, for the history and the
        progress callback (so a service's job shows the safe start moving)."""
        self.runs += 1
        self.iterations_run += 1
        cost = self.fleet_cost(world)
        self.history.append(cost)
        if self.progress is not None:
            self.progress(
                PlanProgress(
                    self.runs,
                    uav,
                    reason,
                    1,
                    1,
                    cost,
                    elapsed_s=self.budget.elapsed(),
                    budget_percent=self.budget.percent(),
                    best_cost=None if self.best is None else self.best.cost,
                    first_safe_s=self.first_safe_s,
                )
            )

    def keep(self, uav: str, trajectory: Trajectory, reason: str) -> bool:
        """As Algorithm 1 keeps a path, in the form the plan will store (`quantised`)."""
        return super().keep(uav, trajectory.quantised(self.specs[uav].speed), reason)

    def adopt(self, uav: str, trajectory: Trajectory, reason: str) -> bool:
        """`uav` flies `trajectory` (as the plan will store it) if the exact check finds it
        in no conflict at all."""
        trajectory = trajectory.quantised(self.specs[uav].speed)
        if cell_conflicts(uav, trajectory, self.specs[uav].radius, self.table.blocked):
            return False
        old = self.paths[uav]
        self.paths[uav] = trajectory
        self.table.update(uav, trajectory)
        if self.table.collision_paths(uav):
            self.paths[uav] = old
            self.table.update(uav, old)
            return False
        self.replans.setdefault(uav, []).append(reason)
        self.record_if_safe()
        return True

    def safe_flight(self, uav: str) -> Trajectory | None:
        """A flight for `uav` clear of every other one: hovering along its lone path, else
        a space-time search (whose path is then pulled and re-timed if that is cheaper)."""
        spec, others = self.specs[uav], self.movers(uav)
        flight = schedule(self.geometry[uav], spec.speed, spec.radius, others)
        if flight is not None:
            return flight
        found = space_time.search(spec, self.free, others, SearchLimits(), self.budget.expired)
        if found is None:
            return None
        pulled = pull_string(_geometry(found), spec.radius, self.table.blocked)
        retimed = schedule(pulled, spec.speed, spec.radius, others)
        if retimed is not None and self.flight_cost(uav, retimed) < self.flight_cost(uav, found):
            return retimed
        return found

    def flight_cost(self, uav: str, trajectory: Trajectory) -> float:
        speed = self.specs[uav].speed
        hover = max(trajectory.end_time - trajectory.length / speed, 0.0)
        return trajectory.length + HOVER_PRICE * speed * hover

    def safe_start(self, world: Map) -> None:
        """Step 2 made constructive: the highest-priority UAV in trouble (eq. 7) is made
        safe against the others; one that cannot be waits for another one's change."""
        failed: Counter[str] = Counter()
        while not self.budget.expired():
            candidates = [u for u in self.table.troubled() if not failed[u]]
            if not candidates:
                return
            uav = candidates[0]
            flight = self.safe_flight(uav)
            if flight is not None and self.adopt(uav, flight, SAFE_START):
                failed.clear()
            else:
                failed[uav] += 1
            self.step(uav, SAFE_START, world)
        self.stopped_by_budget = True

    def excess(self, uav: str) -> float:
        return self.base_cost(uav) - self.lone[uav]

    def improve_anytime(self, world: Map) -> StopReason:
        """Rounds over the UAVs that pay for others being near, most excess first: re-time,
        then search (eq. 8). Ends when a round gains less than ROUND_GAIN of the cost."""
        if self.best is None or self.settings.improve_rounds <= 0:
            return self.algorithm_1_reason()
        if self.best.paths != self.paths:
            self.paths = dict(self.best.paths)
            self.table = ConflictTable.build(self.paths, self.radii, world.blocked)
        self.replans = {u: list(r) for u, r in self.best.replans.items()}
        for _ in range(self.settings.improve_rounds):
            before = self.best.cost
            if not self.worth_improving():
                return "converged"
            for uav in self.worth_improving():
                if self.budget.expired():
                    return "budget"
                self.retime(uav, world)
            for uav in self.worth_improving():
                if self.budget.expired():
                    return "budget"
                self.replan(uav, world, IMPROVEMENT)
            if self.budget.expired() or self.stopped_by_budget:
                return "budget"
            if before - self.best.cost < ROUND_GAIN * before:
                return "converged"
        return "iterations"

    def worth_improving(self) -> list[str]:
        """UAVs whose flight costs noticeably more than their lone path, most first; none
        if all of that excess together is less than a round must gain (the search can
        hardly do better than remove it)."""
        assert self.best is not None
        floor = MIN_SHARE * self.best.cost
        excess = {u: self.excess(u) for u in self.paths}
        worth = [
            u for u in self.paths if excess[u] > min(MIN_EXCESS * max(self.lone[u], 1.0), floor)
        ]
        if sum(excess[u] for u in worth) < ROUND_GAIN * self.best.cost:
            return []
        return sorted(worth, key=lambda u: -excess[u])

    def retime(self, uav: str, world: Map) -> None:
        """Hover again where the others, as they now fly, make it necessary: often less
        than when this UAV was made safe (some of them moved since)."""
        spec = self.specs[uav]
        current = self.paths[uav]
        flight = schedule(_geometry(current), spec.speed, spec.radius, self.movers(uav))
        gain = MIN_GAIN * max(self.flight_cost(uav, current), 1.0)
        if (
            flight is not None
            and self.flight_cost(uav, flight) < self.flight_cost(uav, current) - gain
        ):
            self.adopt(uav, flight, IMPROVEMENT)
        self.step(uav, RETIME, world)


def _hover_window(trajectory: Trajectory, lone: Array) -> tuple[float, float] | None:
    """The stretch of the lone path (arc lengths) within WINDOW cells of the points where
    `trajectory` hovers, or None (no hover, or a flight that left its lone path)."""
    waypoints, waits = as_waypoints(trajectory)
    if not waits.any() or distance_to_polyline(waypoints, lone).max() > 1e-6:
        return None
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(lone, axis=0).T))])
    hovering = waypoints[waits > 0]
    at = [_arc_position(p, lone, along) for p in hovering]
    return max(min(at) - WINDOW, 0.0), min(max(at) + WINDOW, float(along[-1]))


def _arc_position(point: Array, polyline: Array, along: Array) -> float:
    """Arc length along `polyline` of its point nearest to `point`."""
    a, b = polyline[:-1], polyline[1:]
    d = b - a
    length2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    u = np.clip(np.einsum("ij,ij->i", point - a, d) / length2, 0.0, 1.0)
    gap = np.hypot(*(a + u[:, None] * d - point).T)
    k = int(np.argmin(gap))
    return float(along[k] + u[k] * np.sqrt(length2[k]))


def _split(polyline: Array, s0: float, s1: float) -> tuple[Array | None, Array, Array | None]:
    """The polyline before arc length s0, between s0 and s1, and after s1 (None: empty)."""
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(polyline, axis=0).T))])

    def at(s: float) -> Array:
        return np.array([np.interp(s, along, polyline[:, 0]), np.interp(s, along, polyline[:, 1])])

    inside = polyline[(along > s0) & (along < s1)]
    inner = np.vstack([at(s0), inside, at(s1)])
    before = np.vstack([polyline[along < s0], at(s0)]) if s0 > 0 else None
    after = np.vstack([at(s1), polyline[along > s1]]) if s1 < along[-1] else None
    return before, inner, after


def _geometry(trajectory: Trajectory) -> Array:
    """A flight's polyline without its hovers."""
    waypoints, _ = as_waypoints(trajectory)
    return merge_collinear(waypoints)


Route = list[tuple[int, int]]


def _lone_paths(
    scenario: Scenario, obstacles: NDArray[np.bool_], blocked: NDArray[np.bool_], budget: Budget
) -> tuple[dict[str, Route], dict[str, Route], dict[str, float]]:
    """Each UAV's shortest grid path with the objects blocked, its obstacle-only one (they
    differ for the UAVs an object touches: the ones the wormhole step, eq. 9, replans),
    and the first one's length; only the UAVs routed before the budget ran out.

    One bounded Dijkstra per UAV on the obstacle grid (`GridGraph.route`); a second only
    for a touched UAV. Where the objects wall a goal off, the obstacle-only path is kept
    (and the plan will say so).
    """
    plain = GridGraph.build(obstacles)
    with_objects = GridGraph.build(blocked) if (blocked != obstacles).any() else plain
    routes, first, lengths = {}, {}, {}
    for u in scenario.uavs:
        if budget.expired():
            break
        length, cells = plain.route(u.start, u.goal)
        assert cells is not None, "the scenario's validation guarantees a path"
        first[u.id], lengths[u.id] = cells, length
        if with_objects is not plain and not _valid(cells, blocked):
            around, detour = with_objects.route(u.start, u.goal)
            if detour is not None:
                cells, lengths[u.id] = detour, around
        routes[u.id] = cells
    return routes, first, lengths


def _valid(cells: list[tuple[int, int]], blocked: NDArray[np.bool_]) -> bool:
    """No blocked cell on the path and no diagonal past one (the grid's own rule)."""
    xy = np.array(cells)
    if blocked[xy[:, 0], xy[:, 1]].any():
        return False
    a, b = xy[:-1], xy[1:]
    diagonal = (a[:, 0] != b[:, 0]) & (a[:, 1] != b[:, 1])
    side_1 = blocked[b[diagonal, 0], a[diagonal, 1]]
    side_2 = blocked[a[diagonal, 0], b[diagonal, 1]]
    return not (side_1.any() or side_2.any())


def _exploration(
    state: _Anytime, objects: NDArray[np.bool_], first: dict[str, Route]
) -> Exploration:
    """The white hole's metrics of the lone paths, from the conflict table (the same exact
    numbers as `planner.white_hole.explore`, without a second pass over all pairs); OTP
    (eq. 4) counts the objects on each UAV's obstacle-only path, before the wormhole."""
    table = state.table
    collision_paths = {u: table.collision_paths(u) for u in state.paths}
    total = int(objects.sum())
    others = max(len(state.paths) - 1, 1)
    priority, threat = {}, {}
    for uav, trajectory in state.paths.items():
        pc = collision_paths[uav]
        priority[uav] = importance(pc, trajectory.end_time)
        spec = state.specs[uav]
        flight = Trajectory.from_waypoints(merge_collinear(first[uav]), spec.speed)
        on_path = len(cell_conflicts(uav, flight, spec.radius, objects)) if total else 0
        threat[uav] = len(pc) / others * (on_path / total if total else 0.0)
    closest = min(table.closest.values(), default=float("inf"))
    conflicts = list(table.pairs.values())
    return Exploration(conflicts, collision_paths, priority, dict(state.shortest), threat, closest)


def plan_anytime(
    scenario: Scenario, settings: PlannerSettings, progress: ProgressCallback | None
) -> Plan:
    """The `qos` plan: lone paths, safe start, improvement; see the module docstring."""
    budget = Budget(settings.time_budget_s)
    specs = {u.id: u for u in scenario.uavs}
    obstacles = scenario.blocked()
    objects = scenario.object_cells()
    object_map = cell_map(objects, obstacles.shape)
    blocked = obstacles | object_map
    routes, first_routes, shortest = _lone_paths(scenario, obstacles, blocked, budget)
    refuse = functools.partial(_refused, scenario, settings, budget, routes, shortest)
    if len(routes) < len(specs):
        missing = [u.id for u in scenario.uavs if u.id not in routes]
        return refuse(f"routing {len(routes)} of {len(specs)} UAVs ({_some(missing)} have no path)")
    # Shortcuts and tightening only shorten the lone paths: with a budget they stop at a
    # share of it, and the rest of the fleet keeps its grid paths (as safe, a bit longer).
    shaping = budget.seconds is None or budget.elapsed() < SHAPING_SHARE * budget.seconds
    geometry, paths = {}, {}
    for u in scenario.uavs:
        cells = merge_collinear(np.array(routes[u.id], dtype=float))
        if shaping:
            cells = tighten(pull_string(cells, u.radius, blocked), u.radius, blocked)
            shaping = budget.seconds is None or budget.elapsed() < SHAPING_SHARE * budget.seconds
        geometry[u.id] = cells
        paths[u.id] = Trajectory.from_waypoints(cells, u.speed)
    world = Map(blocked, None, blocked)
    radii = {u.id: u.radius for u in scenario.uavs}
    checked = budget.elapsed()
    table = ConflictTable(radii, blocked)
    for count, (uav, trajectory) in enumerate(paths.items()):
        if budget.expired():
            return refuse(f"checking {count} of {len(paths)} lone paths against the others")
        table.update(uav, trajectory)
    # The final exact check covers every pair as the table's build did: keep its time back.
    budget.keep_back(2.0 * (budget.elapsed() - checked) + FINISH_S)
    rng = np.random.default_rng(settings.seed)
    state = _Anytime(
        scenario,
        settings,
        progress,
        rng,
        specs,
        paths,
        shortest,
        {},
        objects,
        budget,
        table,
        geometry=geometry,
        lone={u: Trajectory.from_waypoints(g, 1.0).length for u, g in geometry.items()},
        free=~blocked,
    )
    for uav in state.paths:
        if routes[uav] != first_routes[uav]:
            state.replans[uav] = ["non-UAV object"]
    first = _exploration(state, object_map, first_routes)
    state.start_distance = adjoining_start_distance(scenario, first.priority)
    state.record_if_safe()
    state.safe_start(world)
    if not state.table.clear() and not budget.expired():
        state.resolve_conflicts(world)  # what waiting and stepping aside could not solve
    reason = state.improve_anytime(world)
    judged = Map(obstacles, None, obstacles)
    if state.best is None:  # not safe: the table's exact verdict says why, at no extra cost
        return finish(state, judged, first, reason, _table_report(state, obstacles, object_map))
    state.paths = state.best.paths
    state.replans = state.best.replans
    return finish(state, judged, first, reason)  # a fresh exact check has the last word


def _table_report(
    state: _Anytime, obstacles: NDArray[np.bool_], objects: NDArray[np.bool_]
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


def _some(ids: list[str]) -> str:
    return ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "")


def _refused(
    scenario: Scenario,
    settings: PlannerSettings,
    budget: Budget,
    routes: dict[str, Route],
    shortest: dict[str, float],
    doing: str,
) -> Plan:
    """The plan when the budget ran out before the fleet's lone paths were even known to
    conflict or not: infeasible, the routed UAVs on their grid paths, the others on their
    starts, and one conflict that says what was being done (no exact check: nothing here
    is meant to be flown)."""
    missing = [u.id for u in scenario.uavs if u.id not in routes] or [u.id for u in scenario.uavs]
    message = (
        f"planning refused: the time budget of {settings.time_budget_s:g} s ran out while "
        f"{doing}; give it more time or plan fewer UAVs"
    )
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
