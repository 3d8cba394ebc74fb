"""The one planning state both flows of Algorithm 1 work on, and the words they share.

`PlanningState` is data: the fleet's paths, the conflict table (the white hole's
numbers, exact), the budget, the counters a plan reports and the cheapest fleet that
passed the exact check. `planner.flows.engine.Engine` changes it (one UAV's replan at a time),
as a flow of `planner.flows.policies` says; `Phase` says why a path changed.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

from planner.check.safety import SafetyReport, check_plan
from planner.flows.budget import Budget
from planner.flows.conflict_table import ConflictTable
from planner.geometry.clearance import PIXELS_PER_CELL, ClearanceField
from planner.geometry.grid_search import GridGraph
from planner.model.scenario import Scenario, UAVSpec
from planner.model.trajectory import Trajectory
from planner.search.objectives import HOVER_PRICE, ObjectiveName, paper_fitness

Array = NDArray[np.float64]
ATTEMPTS = 3  # searches a UAV in trouble gets before the others take over
MAX_HOVER = 10.0  # seconds a UAV may hover at one waypoint to let others pass
MIN_GAIN = 1e-3  # relative: an improvement smaller than this is not one
FINISH_S = 0.05  # seconds kept back for building the plan, besides the final exact check


class Phase(StrEnum):
    """Why a UAV's path changes: what a plan's `replanned` and the progress reports say."""

    SAFE_START = "safe start"  # anytime: the white hole's exploration made constructive
    COMPLETE_START = "complete start"  # anytime: the whole fleet searched at once (LaCAM)
    CONFLICT = "uav conflict"  # exploit: the black hole (eq. 8) resolves a conflict
    OBJECT = "non-UAV object"  # wormhole (eq. 9): an object touches the path
    IMPROVEMENT = "improvement"  # the fleet is safe: a cheaper flight (qos)
    RETIME = "re-time"  # anytime improvement: hovers recomputed (progress reports only)


IMPROVEMENT = Phase.IMPROVEMENT  # the reason recorded for a replan of the improvement phase


@dataclass(frozen=True)
class PlannerSettings:
    algorithm: str = "mvo"
    objective: ObjectiveName = "qos"
    seed: int = 1
    population: int = 30
    iterations: int = 1000  # per optimizer run, at most
    time_budget_s: float | None = 5.0  # wall time for the whole plan; None: iterations only
    # qos with a safe start: the budget bounds only the improvement; the safe start runs
    # to its end, unless this hard limit (wall seconds from the plan's start) is set and
    # runs out first: then the plan is refused, saying how long it would have needed.
    safe_start_limit_s: float | None = None
    patience: int | None = 100  # a run stops after this many iterations without gain
    improve_rounds: int = 3  # qos only: rounds of the improvement phase, 0 for none
    # qos only: start from safe flights (safe intervals, space-time A*; planner.flows.anytime)
    # rather than from the shortest paths the optimizer must then repair.
    safe_start: bool = True

    def iterations_only(self) -> PlannerSettings:
        """These settings as the paper runs Algorithm 1: no time budget, every run all of
        its iterations, no safe start, no improvement phase (what the Table III
        reproduction uses)."""
        return replace(self, time_budget_s=None, patience=None, improve_rounds=0, safe_start=False)

    def candidate(self, k: int, of: int) -> PlannerSettings:
        """The settings of the k-th (from 0) of `of` plans made in turn to choose from: the
        next seed on, and its share of the time budget and of the safe start's limit."""

        def share(seconds: float | None) -> float | None:
            return None if seconds is None else seconds / of

        return replace(
            self,
            seed=self.seed + k,
            time_budget_s=share(self.time_budget_s),
            safe_start_limit_s=share(self.safe_start_limit_s),
        )


@dataclass(frozen=True)
class PlanProgress:
    """What a progress callback sees after every optimizer iteration."""

    run: int  # 1-based count of optimizer runs so far
    uav: str
    reason: str  # a `Phase`'s value
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
    raster: ClearanceField | None = None  # built when a search first needs it

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
        if self.raster is None:
            self.raster = ClearanceField.build(self.searched, self.scale)
        return self.raster

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
class PlanningState:
    """The fleet's paths while Algorithm 1 runs, and what the plan will report of it."""

    scenario: Scenario
    settings: PlannerSettings
    progress: ProgressCallback | None
    rng: np.random.Generator
    specs: dict[str, UAVSpec]
    paths: dict[str, Trajectory]
    shortest: dict[str, float]
    start_distance: dict[str, float]  # Dist(t0) of eq. 10
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
    complete_start: str | None = None  # what it did, if the safe start called it
    # each UAV's search cost with no other UAV about, per path and map (identities)
    lone_costs: dict[str, tuple[Trajectory, Map, float]] = field(default_factory=dict)

    @property
    def radii(self) -> dict[str, float]:
        return {u: s.radius for u, s in self.specs.items()}

    @property
    def scale(self) -> float:
        """The plan cost is a sum over UAVs (qos) or the mean J (paper)."""
        return 1.0 if self.settings.objective == "qos" else 1.0 / len(self.paths)

    def penalty(self, world: Map) -> float:
        """The cost of a conflict: more than any detour on this map."""
        return float(100.0 * (world.blocked.shape[0] + world.blocked.shape[1] + 10))

    def base_cost(self, uav: str, trajectory: Trajectory | None = None) -> float:
        """The objective of `uav`'s path (its current one if None) without any penalty."""
        spec = self.specs[uav]
        if trajectory is None:
            trajectory = self.paths[uav]
        if self.settings.objective == "qos":
            return flight_cost(trajectory, spec.speed)
        deviation = float(np.hypot(*(trajectory.end - np.array(spec.goal))))
        count = len(self.specs) + len(self.objects)
        return float(paper_fitness(count, trajectory.length, deviation, self.start_distance[uav]))

    def fleet_cost(self, paths: dict[str, Trajectory] | None = None) -> float:
        """The plan cost of `paths` (the current ones if None)."""
        paths = self.paths if paths is None else paths
        return self.scale * sum(self.base_cost(u, t) for u, t in paths.items())

    def check(self) -> SafetyReport:
        return check_plan(self.paths, self.radii, self.scenario.blocked(), self.objects)

    def back_to_best(self, world: Map) -> None:
        """Continue from the cheapest fleet that passed the exact check (what the
        improvement phase starts from)."""
        assert self.best is not None
        if any(self.paths[u] is not flight for u, flight in self.best.paths.items()):
            self.paths = dict(self.best.paths)
            self.table = ConflictTable.build(self.paths, self.radii, world.blocked)
        self.replans = {u: list(r) for u, r in self.best.replans.items()}

    def use_world(self, world: Map) -> None:
        """Judge cell hits against `world`'s blocked cells from now on."""
        if self.table.blocked is not world.blocked:
            self.table.on_map(world.blocked)


def flight_cost(trajectory: Trajectory, speed: float) -> float:
    """The `qos` cost of a flight: its length and the price of its hovers."""
    hover = trajectory.end_time - trajectory.length / speed
    return trajectory.length + HOVER_PRICE * speed * max(hover, 0.0)


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
    """Waypoints and hover times of a trajectory (a hover is two points at one place:
    `np.allclose` of consecutive positions, its test written out for all of them at once,
    since a space-time search's flight has a point per step and this is asked of every
    flight a search or a re-timing looks at)."""
    points = trajectory.points
    a, b = points[:-1, 1:], points[1:, 1:]
    with np.errstate(invalid="ignore"):
        close = (np.abs(a - b) <= 1e-08 + 1e-05 * np.abs(b)) & np.isfinite(b) | (a == b)
    times = points[:, 0].tolist()
    keep, waits = [0], [0.0]
    for k, hover in enumerate(close.all(axis=1).tolist()):
        if hover:
            waits[-1] += times[k + 1] - times[k]
        else:
            keep.append(k + 1)
            waits.append(0.0)
    return points[keep, 1:], np.array(waits)
