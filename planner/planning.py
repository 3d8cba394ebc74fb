"""The state Algorithm 1 works on, shared by its two flows.

`planner.pipeline.plan` runs Algorithm 1 as the paper does (explore, exploit, wormhole,
with the metaheuristic repairing conflicts); `planner.anytime` runs it with a fast safe
start. Both keep the fleet's paths, the conflict table (the white hole's numbers, exact),
the budget and the cheapest plan that passed the exact check in a `_Planning`, and build
the returned plan with `finish`.
"""

from __future__ import annotations

import dataclasses
import itertools
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from planner.black_hole import Search, search_path, wait_probe
from planner.budget import Budget, StopReason
from planner.clearance import PIXELS_PER_CELL, ClearanceField, ExactClearance
from planner.conflict_table import NEAR, ConflictTable
from planner.grid_search import GridGraph, cell_map
from planner.objectives import (
    HOVER_PRICE,
    ObjectiveName,
    PaperObjective,
    QosObjective,
    paper_fitness,
)
from planner.optimizers import Progress, get_algorithm
from planner.path_cost import Traffic
from planner.path_encoding import DetourEncoding, TurnEncoding, grid_steps
from planner.plan import Metrics, Plan, PlannedUAV
from planner.run_stop import RunStop
from planner.safety import SafetyReport, cell_conflicts, check_plan
from planner.scenario import Scenario, UAVSpec
from planner.trajectory import Trajectory, merge_collinear
from planner.white_hole import Exploration, explore

Array = NDArray[np.float64]
ATTEMPTS = 3  # searches a UAV in trouble gets before the others take over
MAX_HOVER = 10.0  # seconds a UAV may hover at one waypoint to let others pass
IMPROVEMENT = "improvement"  # the reason recorded for a replan of the improvement phase
MIN_GAIN = 1e-3  # relative: an improvement smaller than this is not one
FINISH_S = 0.05  # seconds kept back for building the plan, besides the final exact check


@dataclass(frozen=True)
class PlannerSettings:
    algorithm: str = "mvo"
    objective: ObjectiveName = "qos"
    seed: int = 1
    population: int = 30
    iterations: int = 1000  # per optimizer run, at most
    time_budget_s: float | None = 5.0  # wall time for the whole plan; None: iterations only
    patience: int | None = 100  # a run stops after this many iterations without gain
    improve_rounds: int = 3  # qos only: rounds of the improvement phase, 0 for none
    # qos only: start from safe flights (safe intervals, space-time A*; planner.anytime)
    # rather than from the shortest paths the optimizer must then repair.
    safe_start: bool = True

    def iterations_only(self) -> PlannerSettings:
        """These settings as the paper runs Algorithm 1: no time budget, every run all of
        its iterations, no safe start, no improvement phase (what the Table III
        reproduction uses)."""
        return replace(self, time_budget_s=None, patience=None, improve_rounds=0, safe_start=False)


@dataclass(frozen=True)
class PlanProgress:
    """What a progress callback sees after every optimizer iteration."""

    run: int  # 1-based count of optimizer runs so far
    uav: str
    reason: str
    iteration: int
    iterations: int
    plan_cost: float  # the fleet's cost with this run's best path for `uav`
    elapsed_s: float = 0.0
    budget_percent: float | None = None  # share of the time budget used; None: no budget
    best_cost: float | None = None  # cost of the cheapest plan that passed the exact check
    first_safe_s: float | None = None  # when the first plan passed it


ProgressCallback = Callable[[PlanProgress], None]


@dataclass
class Map:
    """What counts as blocked (for judging paths) and what searches keep away from."""

    blocked: NDArray[np.bool_]
    graph: GridGraph | None  # None: this map's user routes on graphs of its own
    searched: NDArray[np.bool_]  # blocked cells and those the searches avoid besides
    scale: int = PIXELS_PER_CELL  # of the clearance raster
    routes: dict[tuple[tuple[int, int], tuple[int, int]], list[tuple[int, int]] | None] = (
        dataclasses.field(default_factory=dict)
    )
    _field: ClearanceField | None = None

    @classmethod
    def of(
        cls,
        blocked: NDArray[np.bool_],
        avoid: NDArray[np.bool_] | None = None,
        scale: int = PIXELS_PER_CELL,
    ) -> Map:
        searched = blocked if avoid is None else blocked | avoid
        return cls(blocked, GridGraph.build(searched), searched, scale)

    @property
    def field(self) -> ClearanceField:
        """The clearance raster the optimizer's cost reads, built when a search first needs
        it (a fleet that needs no search never pays for it)."""
        if self._field is None:
            self._field = ClearanceField.build(self.searched, self.scale)
        return self._field

    def route(self, start: tuple[int, int], goal: tuple[int, int]) -> list[tuple[int, int]] | None:
        """The searched grid's shortest path (computed once per pair of cells)."""
        if (start, goal) not in self.routes:
            assert self.graph is not None, "this map was built without a grid graph"
            self.routes[start, goal] = self.graph.shortest_path(start, goal)
        return self.routes[start, goal]


@dataclass
class Best:
    """The cheapest fleet that has passed the exact check so far."""

    paths: dict[str, Trajectory]
    replans: dict[str, list[str]]
    cost: float


@dataclass
class _Planning:
    """The fleet's paths while Algorithm 1 runs."""

    scenario: Scenario
    settings: PlannerSettings
    progress: ProgressCallback | None
    rng: np.random.Generator
    specs: dict[str, UAVSpec]
    paths: dict[str, Trajectory]
    shortest: dict[str, float]
    start_distance: dict[str, float]
    objects: list[tuple[int, int]]
    budget: Budget
    table: ConflictTable
    replans: dict[str, list[str]] = field(default_factory=dict)
    history: list[float] = field(default_factory=list)
    nfe: int = 0
    runs: int = 0
    iterations_run: int = 0
    stopped_by_budget: bool = False
    best: Best | None = None
    first_safe_s: float | None = None
    first_safe_cost: float | None = None
    converged_runs: int = 0
    _lone: dict[str, tuple[Trajectory, Map, float]] = field(default_factory=dict)

    @property
    def radii(self) -> dict[str, float]:
        return {u: s.radius for u, s in self.specs.items()}

    def explore(self, world: Map) -> Exploration:
        return explore(self.paths, self.radii, self.shortest, self.objects, world.blocked.shape)

    def penalty(self, world: Map) -> float:
        return 100.0 * (world.blocked.shape[0] + world.blocked.shape[1] + 10)

    @property
    def scale(self) -> float:
        """The plan cost is a sum over UAVs (qos) or the mean J (paper)."""
        return 1.0 if self.settings.objective == "qos" else 1.0 / len(self.paths)

    def objective(self, uav: str, penalty: float) -> QosObjective | PaperObjective:
        if self.settings.objective == "qos":
            return QosObjective(self.specs[uav].speed, penalty)
        count = len(self.specs) + len(self.objects)
        return PaperObjective(count, self.start_distance[uav], penalty)

    def base_cost(self, uav: str) -> float:
        """The objective of `uav`'s current path without any penalty, from its trajectory."""
        trajectory, spec = self.paths[uav], self.specs[uav]
        if self.settings.objective == "qos":
            hover = trajectory.end_time - trajectory.length / spec.speed
            return trajectory.length + HOVER_PRICE * spec.speed * max(hover, 0.0)
        deviation = float(np.hypot(*(trajectory.end - np.array(spec.goal))))
        count = len(self.specs) + len(self.objects)
        return float(paper_fitness(count, trajectory.length, deviation, self.start_distance[uav]))

    def others_cost(self, uav: str, world: Map) -> float:
        """The sum of every other UAV's search cost with `uav` left out of its traffic
        (the fleet cost of the progress reports and the history).

        Only a UAV that comes near another needs its traffic sampled: for the rest the
        sampled separation terms are zero, and the cost without traffic is the same
        number. With a time budget that sampling is skipped (it can take a quarter of
        the time on fifty UAVs): a conflict between two other UAVs then counts the
        penalty once, without its depth.
        """
        if self.settings.time_budget_s is not None:
            clash = self.penalty(world) * self.table.conflicts_without(uav)
            return clash + sum(self.lone_cost(u, world) for u in self.paths if u != uav)
        total = 0.0
        for u in self.paths:
            if u == uav:
                continue
            if self.table.comes_near(u, NEAR, leave_out=uav):
                total += self.current_cost(u, world, ignore=uav)
            else:
                total += self.lone_cost(u, world)
        return total

    def lone_cost(self, uav: str, world: Map) -> float:
        """`uav`'s search cost with no other UAV about, cached per path and map."""
        trajectory = self.paths[uav]
        cached = self._lone.get(uav)
        if cached is None or cached[0] is not trajectory or cached[1] is not world:
            waypoints, waits = as_waypoints(trajectory)
            region = (waypoints.min(axis=0), waypoints.max(axis=0))
            search = self.search(uav, world, region, alone=True)
            cached = (trajectory, world, float(search.cost(waypoints[None], waits[None])[0]))
            self._lone[uav] = cached
        return cached[2]

    def search(
        self,
        uav: str,
        world: Map,
        region: tuple[Array, Array],
        ignore: str | None = None,
        alone: bool = False,
        corridor: tuple[Array, float] | None = None,
    ) -> Search:
        """Costs for `uav`'s paths inside `region` (and `corridor`, if given) against
        everything else (but `ignore`), held fixed; against the map only if `alone`."""
        spec = self.specs[uav]
        others = [
            (self.paths[u], self.specs[u].radius, self.specs[u].speed)
            for u in self.paths
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
            self.clearance(world, region, corridor, spec.radius),
            self.objective(uav, self.penalty(world)),
        )

    def clearance(
        self,
        world: Map,
        region: tuple[Array, Array],
        corridor: tuple[Array, float] | None,
        radius: float,
    ) -> ClearanceField | ExactClearance:
        """What a search reads clearance from: the map's raster."""
        return world.field

    def current_cost(self, uav: str, world: Map, ignore: str | None = None) -> float:
        waypoints, waits = as_waypoints(self.paths[uav])
        region = (waypoints.min(axis=0), waypoints.max(axis=0))
        search = self.search(uav, world, region, ignore)
        return float(search.cost(waypoints[None], waits[None])[0])

    def encoding(self, uav: str, world: Map) -> DetourEncoding | TurnEncoding | None:
        spec = self.specs[uav]
        if self.settings.objective == "qos":
            cells = world.route(spec.start, spec.goal)
            if cells is None:
                return None
            horizon = max((t.end_time for u, t in self.paths.items() if u != uav), default=1.0)
            return DetourEncoding.around(
                np.array(cells, dtype=float), max_wait=min(horizon + 1.0, MAX_HOVER)
            )
        offset = self.paths[uav].end - np.array(spec.goal, dtype=float)
        same_way = np.sign(offset) if np.any(offset) else None
        return TurnEncoding(grid_steps(merge_collinear(self.paths[uav].xy)), same_way)

    def replan(self, uav: str, world: Map, reason: str, share: float = float("inf")) -> bool:
        """One optimizer run for `uav`, of at most `share` seconds; keeps the new path if it
        costs less and the exact check finds no new conflict. True if kept."""
        spec = self.specs[uav]
        encoding = self.encoding(uav, world)
        if encoding is None:
            return False
        search = self.search(uav, world, encoding.region(), corridor=self.corridor(encoding))
        before = self.current_cost(uav, world)
        if self.probing(reason) and isinstance(encoding, DetourEncoding):
            probe = wait_probe(encoding, search)
            self.nfe += probe.evaluations
            if probe.safe and probe.cost < before and self.keep(uav, probe.trajectory, reason):
                return True
        # The others' costs leave out their conflicts with `uav`: its own cost counts them.
        others = self.others_cost(uav, world)
        self.runs += 1
        run = self.runs
        # Making a UAV safe needs no polish: once its best is safe the run may end soon.
        resolving = reason != IMPROVEMENT and self.settings.objective == "qos"
        stop = RunStop(
            self.budget,
            self.patience(reason),
            safe_below=self.penalty(world) if resolving else None,
        )
        ends = self.budget.elapsed() + share

        def on_iteration(p: Progress) -> bool:
            cost = self.scale * (others + min(p.best_cost, before))
            self.history.append(cost)
            self.iterations_run += 1
            if self.progress is not None:
                self.progress(self._report(run, uav, reason, p, cost))
            return stop(p.best_cost) or self.budget.elapsed() >= ends

        outcome = search_path(
            encoding,
            search,
            algorithm=self.settings.algorithm,
            population=self.settings.population,
            iterations=self.run_iterations(reason),
            rng=self.rng,
            on_iteration=on_iteration,
        )
        self.nfe += outcome.result.nfe
        if stop.reason == "budget" or self.budget.expired():
            self.stopped_by_budget = True
        self.converged_runs += stop.reason == "converged"
        if not self.better(uav, outcome.trajectory, outcome.cost, before, reason) or cell_conflicts(
            uav, outcome.trajectory, spec.radius, world.blocked
        ):  # the search reads clearance from a raster; the exact check has the last word
            return False
        return self.keep(uav, outcome.trajectory, reason)

    def better(
        self, uav: str, trajectory: Trajectory, cost: float, before: float, reason: str
    ) -> bool:
        """Is a search's result worth keeping? By the search's own cost, lower than the
        current path's (by at least MIN_GAIN when improving)."""
        gain = MIN_GAIN * max(abs(before), 1.0) if reason == IMPROVEMENT else 0.0
        return cost < before - gain

    def corridor(self, encoding: DetourEncoding | TurnEncoding) -> tuple[Array, float] | None:
        """Where every path of `encoding` stays (None: only its region is known)."""
        return None

    def run_iterations(self, reason: str) -> int:
        """The iteration budget of one optimizer run for `reason`."""
        return self.settings.iterations

    def patience(self, reason: str) -> int | None:
        """Iterations without gain after which a run for `reason` has converged."""
        return self.settings.patience

    def probing(self, reason: str) -> bool:
        """The anytime mode (qos with an improvement phase) tries a hover before a search
        when a UAV must be made safe: the improvement phase shortens it later."""
        anytime = self.settings.objective == "qos" and self.settings.improve_rounds > 0
        return anytime and reason != IMPROVEMENT

    def keep(self, uav: str, trajectory: Trajectory, reason: str) -> bool:
        """`uav` flies `trajectory` from now on, unless (improving or probing) the exact
        check finds more conflicts for it than before, or it enters a blocked cell."""
        spec = self.specs[uav]
        if cell_conflicts(uav, trajectory, spec.radius, self.table.blocked):
            return False
        old = self.paths[uav]
        conflicts = len(self.table.collision_paths(uav))
        self.paths[uav] = trajectory
        self.table.update(uav, trajectory)
        strict = reason == IMPROVEMENT or self.probing(reason)
        if strict and len(self.table.collision_paths(uav)) > conflicts:
            self.paths[uav] = old  # cheaper by the sampled cost, but not by the exact check
            self.table.update(uav, old)
            return False
        self.replans.setdefault(uav, []).append(reason)
        self.record_if_safe()
        return True

    def _report(self, run: int, uav: str, reason: str, p: Progress, cost: float) -> PlanProgress:
        return PlanProgress(
            run,
            uav,
            reason,
            p.iteration,
            p.iterations,
            cost,
            elapsed_s=self.budget.elapsed(),
            budget_percent=self.budget.percent(),
            best_cost=None if self.best is None else self.best.cost,
            first_safe_s=self.first_safe_s,
        )

    def check(self) -> SafetyReport:
        obstacles = self.scenario.blocked()
        return check_plan(self.paths, self.radii, obstacles, self.objects)

    def record_if_safe(self) -> None:
        """If the fleet as it stands passes the exact check, remember it (the first time,
        and whenever it is the cheapest yet)."""
        if self.table.pairs:
            return  # the check would find these; no need to run it
        started = time.perf_counter()
        safe = self.check().safe
        self.budget.keep_back(2.0 * (time.perf_counter() - started))  # for the final check
        if not safe:
            return
        cost = self.scale * sum(self.base_cost(u) for u in self.paths)
        if self.first_safe_s is None:
            self.first_safe_s, self.first_safe_cost = self.budget.elapsed(), cost
        if self.best is None or cost < self.best.cost:
            replans = {u: list(r) for u, r in self.replans.items()}
            self.best = Best(dict(self.paths), replans, cost)

    def use_world(self, world: Map) -> None:
        """Judge cell hits against `world`'s blocked cells from now on."""
        if self.table.blocked is not world.blocked:
            self.table.on_map(world.blocked)

    def resolve_conflicts(self, world: Map, reason: str = "uav conflict") -> None:
        """Step 2: the highest-priority UAV in trouble replans until none is left, or until
        every UAV in trouble has failed ATTEMPTS times since the last success (the search
        is random, so a second try from where the first left off often succeeds). With a
        time budget each run gets a fair share of what is left."""
        self.use_world(world)
        failures: Counter[str] = Counter()
        for _ in range(6 * len(self.specs)):
            if self.budget.expired():
                self.stopped_by_budget = True
                return
            troubled = self.table.troubled()
            candidates = [u for u in troubled if failures[u] < ATTEMPTS]
            if not candidates:
                return
            uav = candidates[0]
            share = self.budget.remaining() / (len(troubled) + 1)
            if self.replan(uav, world, reason, share) and uav not in self.table.troubled():
                failures.clear()
            else:
                failures[uav] += 1

    def wormhole(self, world: Map) -> Map:
        """Step 3: the objects block their cells; only the UAVs they touch replan."""
        if not self.objects:
            return world
        object_map = cell_map(self.objects, world.blocked.shape)
        touched = [
            u
            for u in self.specs
            if cell_conflicts(u, self.paths[u], self.specs[u].radius, object_map)
        ]
        if not touched:
            return world
        world = Map.of(world.blocked | object_map)
        self.use_world(world)
        for uav in sorted(touched, key=lambda u: -self.table.priority(u)):
            if self.budget.expired():
                self.stopped_by_budget = True
                break
            share = self.budget.remaining() / (len(touched) + 1)
            self.replan(uav, world, "non-UAV object", share)
        self.resolve_conflicts(world)
        return world

    def improve(self, world: Map) -> StopReason:
        """Step 4 (qos): with the fleet safe, each UAV in turn, most excess cost first,
        searches again against the others; rounds end when none improves."""
        wanted = self.settings.objective == "qos" and self.settings.improve_rounds > 0
        if self.best is None or not wanted:
            return self.algorithm_1_reason()
        if self.best.paths != self.paths:
            self.paths = dict(self.best.paths)
            self.table = ConflictTable.build(self.paths, self.radii, world.blocked)
        self.replans = {u: list(r) for u, r in self.best.replans.items()}
        self.use_world(world)
        for _ in range(self.settings.improve_rounds):
            excess = {u: self.base_cost(u) - self.shortest[u] for u in self.paths}
            improved = False
            for uav in sorted(self.paths, key=lambda u: -excess[u]):
                if self.budget.expired():
                    self.stopped_by_budget = True
                    return "budget"
                improved |= self.replan(uav, world, IMPROVEMENT)
            if self.stopped_by_budget:
                return "budget"
            if not improved:
                return "converged"
        return "iterations"

    def algorithm_1_reason(self) -> StopReason:
        """Without an improvement phase: the budget if it cut a run short, converged if
        every run converged (or none was needed), else the iteration budget."""
        if self.stopped_by_budget:
            return "budget"
        return "converged" if self.converged_runs == self.runs else "iterations"


def adjoining_start_distance(scenario: Scenario, priority: dict[str, float]) -> dict[str, float]:
    """Dist(t0) of Table III: start distance to the UAV of adjoining priority."""
    order = sorted(scenario.uavs, key=lambda u: -priority[u.id])  # stable: ties keep order
    if len(order) == 1:
        return {order[0].id: 1.0}
    out = {}
    for k, u in enumerate(order):
        other = order[k + 1] if k + 1 < len(order) else order[k - 1]
        out[u.id] = float(np.hypot(u.start[0] - other.start[0], u.start[1] - other.start[1]))
    return out


def as_waypoints(trajectory: Trajectory) -> tuple[Array, Array]:
    """Waypoints and hover times of a trajectory (a hover is two points at one place)."""
    points = trajectory.points
    waypoints, waits = [points[0, 1:]], [0.0]
    for prev, cur in itertools.pairwise(points):
        if np.allclose(prev[1:], cur[1:]):
            waits[-1] += cur[0] - prev[0]
        else:
            waypoints.append(cur[1:])
            waits.append(0.0)
    return np.array(waypoints), np.array(waits)


def finish(
    state: _Planning,
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
    final_cost = state.scale * sum(state.base_cost(u) for u in state.paths)
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
