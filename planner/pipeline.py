"""Algorithm 1 of the paper: explore (white hole), exploit (black hole), wormhole.

1. Every UAV starts on its shortest grid path.
2. While two UAVs' paths conflict, the conflicting UAV with the highest priority
   (eq. 7) searches a new path with the optimizer against the others' paths (eq. 8),
   and the white hole is run again on the result.
3. The non-UAV objects are placed; only the UAVs whose path one of them touches
   replan (eq. 9), now with the objects blocked, and step 2 runs again if that
   created a new conflict.
4. The plan is judged by the exact continuous-time check: it is feasible only
   if that check finds nothing.
"""

from __future__ import annotations

import itertools
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from planner.black_hole import Search, search_path
from planner.clearance import ClearanceField
from planner.grid_search import GridGraph, cell_map
from planner.objectives import ObjectiveName, PaperObjective, QosObjective, paper_fitness
from planner.optimizers import get_algorithm
from planner.path_cost import Traffic
from planner.path_encoding import DetourEncoding, TurnEncoding, grid_steps
from planner.plan import Metrics, Plan, PlannedUAV
from planner.references import shortest_lengths
from planner.safety import cell_conflicts, check_plan
from planner.scenario import Scenario, UAVSpec
from planner.trajectory import Trajectory, merge_collinear
from planner.white_hole import Exploration, explore

Array = NDArray[np.float64]
ATTEMPTS = 3  # searches a UAV in trouble gets before the others take over
MAX_HOVER = 10.0  # seconds a UAV may hover at one waypoint to let others pass


@dataclass(frozen=True)
class PlannerSettings:
    algorithm: str = "mvo"
    objective: ObjectiveName = "qos"
    seed: int = 1
    population: int = 30
    iterations: int = 1000


@dataclass(frozen=True)
class PlanProgress:
    """What a progress callback sees after every optimizer iteration."""

    run: int  # 1-based count of optimizer runs so far
    uav: str
    reason: str
    iteration: int
    iterations: int
    plan_cost: float


ProgressCallback = Callable[[PlanProgress], None]


@dataclass
class _Map:
    """What counts as blocked (for judging paths) and what searches keep away from."""

    blocked: NDArray[np.bool_]
    graph: GridGraph
    field: ClearanceField

    @classmethod
    def of(cls, blocked: NDArray[np.bool_], avoid: NDArray[np.bool_] | None = None) -> _Map:
        searched = blocked if avoid is None else blocked | avoid
        return cls(blocked, GridGraph.build(searched), ClearanceField.build(searched))


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
    replans: dict[str, list[str]] = field(default_factory=dict)
    history: list[float] = field(default_factory=list)
    nfe: int = 0
    runs: int = 0

    @property
    def radii(self) -> dict[str, float]:
        return {u: s.radius for u, s in self.specs.items()}

    def explore(self, world: _Map) -> Exploration:
        return explore(self.paths, self.radii, self.shortest, self.objects, world.blocked.shape)

    def objective(self, uav: str, penalty: float) -> QosObjective | PaperObjective:
        if self.settings.objective == "qos":
            return QosObjective(self.specs[uav].speed, penalty)
        count = len(self.specs) + len(self.objects)
        return PaperObjective(count, self.start_distance[uav], penalty)

    def search(
        self, uav: str, world: _Map, region: tuple[Array, Array], ignore: str | None = None
    ) -> Search:
        """Costs for `uav`'s paths inside `region` against everything else (but `ignore`),
        held fixed."""
        spec = self.specs[uav]
        others = [
            (self.paths[u], self.specs[u].radius, self.specs[u].speed)
            for u in self.paths
            if u not in (uav, ignore)
        ]
        traffic = Traffic.around(
            others,
            radius=spec.radius,
            speed=spec.speed,
            start=np.array(spec.start, dtype=float),
            lower=region[0],
            upper=region[1],
        )
        penalty = 100.0 * (world.blocked.shape[0] + world.blocked.shape[1] + 10)
        return Search(
            spec.speed,
            spec.radius,
            np.array(spec.goal, dtype=float),
            traffic,
            world.field,
            self.objective(uav, penalty),
        )

    def current_cost(self, uav: str, world: _Map, ignore: str | None = None) -> float:
        waypoints, waits = _as_waypoints(self.paths[uav])
        region = (waypoints.min(axis=0), waypoints.max(axis=0))
        search = self.search(uav, world, region, ignore)
        return float(search.cost(waypoints[None], waits[None])[0])

    def replan(self, uav: str, world: _Map, reason: str) -> bool:
        """One optimizer run for `uav`; keeps the new path if it costs less. True if kept."""
        spec = self.specs[uav]
        if self.settings.objective == "qos":
            cells = world.graph.shortest_path(spec.start, spec.goal)
            if cells is None:
                return False
            horizon = max((t.end_time for u, t in self.paths.items() if u != uav), default=1.0)
            encoding: DetourEncoding | TurnEncoding = DetourEncoding.around(
                np.array(cells, dtype=float), max_wait=min(horizon + 1.0, MAX_HOVER)
            )
        else:
            offset = self.paths[uav].end - np.array(spec.goal, dtype=float)
            same_way = np.sign(offset) if np.any(offset) else None
            encoding = TurnEncoding(grid_steps(merge_collinear(self.paths[uav].xy)), same_way)
        search = self.search(uav, world, encoding.region())
        before = self.current_cost(uav, world)
        # The others' costs leave out their conflicts with `uav`: its own cost counts them.
        others = sum(self.current_cost(u, world, ignore=uav) for u in self.paths if u != uav)
        scale = 1.0 if self.settings.objective == "qos" else 1.0 / len(self.paths)
        self.runs += 1
        run = self.runs

        def on_iteration(p) -> None:
            cost = scale * (others + min(p.best_cost, before))
            self.history.append(cost)
            if self.progress is not None:
                self.progress(PlanProgress(run, uav, reason, p.iteration, p.iterations, cost))

        outcome = search_path(
            encoding,
            search,
            algorithm=self.settings.algorithm,
            population=self.settings.population,
            iterations=self.settings.iterations,
            rng=self.rng,
            on_iteration=on_iteration,
        )
        self.nfe += outcome.result.nfe
        if outcome.cost >= before or cell_conflicts(
            uav, outcome.trajectory, spec.radius, world.blocked
        ):  # the search reads clearance from a raster; the exact check has the last word
            return False
        self.paths[uav] = outcome.trajectory
        self.replans.setdefault(uav, []).append(reason)
        return True

    def troubled(self, world: _Map) -> list[str]:
        """UAVs in conflict with another UAV or inside a blocked cell, highest priority first."""
        exploration = self.explore(world)
        hit = {
            u
            for u in self.specs
            if cell_conflicts(u, self.paths[u], self.specs[u].radius, world.blocked)
        }
        trouble = [u for u in self.specs if exploration.collision_paths[u] or u in hit]
        # Ties keep the scenario's order: the paper's UAV1 turns when priorities are equal.
        return sorted(trouble, key=lambda u: -exploration.priority[u])

    def resolve_conflicts(self, world: _Map, reason: str = "uav conflict") -> None:
        """Step 2: the highest-priority UAV in trouble replans until none is left, or until
        every UAV in trouble has failed ATTEMPTS times since the last success (the search
        is random, so a second try from where the first left off often succeeds)."""
        failures: Counter[str] = Counter()
        for _ in range(6 * len(self.specs)):
            candidates = [u for u in self.troubled(world) if failures[u] < ATTEMPTS]
            if not candidates:
                return
            uav = candidates[0]
            if self.replan(uav, world, reason) and uav not in self.troubled(world):
                failures.clear()
            else:
                failures[uav] += 1

    def wormhole(self, world: _Map) -> _Map:
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
        world = _Map.of(world.blocked | object_map)
        priority = self.explore(world).priority
        for uav in sorted(touched, key=lambda u: -priority[u]):
            self.replan(uav, world, "non-UAV object")
        self.resolve_conflicts(world)
        return world


def plan(
    scenario: Scenario,
    settings: PlannerSettings = PlannerSettings(),
    progress: ProgressCallback | None = None,
) -> Plan:
    """Collision-free paths for every UAV of the scenario, or an infeasible plan that says why."""
    get_algorithm(settings.algorithm)  # fail fast on an unknown name
    started = time.perf_counter()
    obstacles = _Map.of(scenario.blocked())
    specs = {u.id: u for u in scenario.uavs}
    objects = scenario.object_cells()
    paths = {}
    for u in scenario.uavs:
        cells = obstacles.graph.shortest_path(u.start, u.goal)
        assert cells is not None, "the scenario's validation guarantees a path"
        paths[u.id] = Trajectory.from_waypoints(merge_collinear(cells), u.speed)
    shortest = shortest_lengths(scenario)
    rng = np.random.default_rng(settings.seed)
    state = _Planning(scenario, settings, progress, rng, specs, paths, shortest, {}, objects)
    first = state.explore(obstacles)
    state.start_distance = _adjoining_start_distance(scenario, first.priority)

    # The paper plans around the UAVs first and meets the objects only in the wormhole
    # step. With `qos` the searches already keep clear of the objects the scenario
    # declares, so a detour never runs into one; the wormhole step still replans the
    # UAVs whose first paths the objects touch, and only those.
    known = cell_map(objects, obstacles.blocked.shape)
    first_world = _Map.of(obstacles.blocked, known) if settings.objective == "qos" else obstacles
    state.resolve_conflicts(first_world)
    state.wormhole(obstacles)
    return _finish(state, obstacles, first, time.perf_counter() - started)


def _adjoining_start_distance(scenario: Scenario, priority: dict[str, float]) -> dict[str, float]:
    """Dist(t0) of Table III: start distance to the UAV of adjoining priority."""
    order = sorted(scenario.uavs, key=lambda u: -priority[u.id])  # stable: ties keep order
    if len(order) == 1:
        return {order[0].id: 1.0}
    out = {}
    for k, u in enumerate(order):
        other = order[k + 1] if k + 1 < len(order) else order[k - 1]
        out[u.id] = float(np.hypot(u.start[0] - other.start[0], u.start[1] - other.start[1]))
    return out


def _as_waypoints(trajectory: Trajectory) -> tuple[Array, Array]:
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


def _finish(state: _Planning, world: _Map, first: Exploration, seconds: float) -> Plan:
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
    metrics = Metrics(
        conflicts=len(report.conflicts),
        min_separation=None if not np.isfinite(closest) else round(closest, 6),
        mean_deviation=round(float(np.mean([u.deviation for u in uavs])), 6),
        total_length=round(sum(u.length for u in uavs), 6),
        J=round(float(np.mean(fitness)), 6),
        nfe=state.nfe,
        seconds=round(seconds, 4),
        replans=state.runs,
    )
    settings = state.settings
    return Plan(
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
