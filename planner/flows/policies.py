"""The two flows of Algorithm 1, side by side: two policies over one planning engine.

`planner.flows.engine.Engine` replans one UAV at a time over one `PlanningState`; where the
two flows differ, it asks its flow. Everything else (the white hole's table, the black
hole's search, the wormhole, the exact check) is the same code for both.

How they differ, question by question (`PaperFlow`, Algorithm 1 as the paper runs it;
`AnytimeFlow`, `qos` with a safe start):

- what a search moves (`encoding`): the searched grid's shortest path, detoured and
  held (`qos`), or one-grid turns (`paper`); the anytime flow: the UAV's lone any-angle
  path, only in a window round where it hovers;
- which other UAVs a search sees (`corridor`): all inside the encoding's region; the
  anytime flow: only those near the lone path's corridor;
- clearance from blocked cells (`clearance`): the map's raster; the anytime flow:
  exact, per leg, from the cells near the corridor;
- how long a run is (`iterations`, `patience`): the settings'; the anytime flow's
  improvement runs: at most 40 iterations, 15 without gain;
- whether a result is better (`better`): by the search's cost (improving: by
  `MIN_GAIN` too); the anytime flow's improvement: by the true cost (length and hover);
- the form a kept path takes (`stored`): as the search made it; the anytime flow:
  quantised, as the plan will store it;
- whether the fleet is safe now (`fleet_passes`): no pair in the conflict table, then
  the exact check; the anytime flow: a clear table (it holds the exact check's verdict);
- a wait probe before a search (`probes`): with `qos` and an improvement phase; the
  anytime flow: with an improvement phase.

The steps each flow runs are in `planner.flows.algorithm_1` (explore, exploit, wormhole,
improvement in turn) and `planner.flows.anytime` (lone paths, safe start, improvement where
it pays); `planner.pipeline.plan` picks the flow.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from planner.flows.lone_paths import hover_window, split
from planner.flows.planning import (
    MAX_HOVER,
    MIN_GAIN,
    Map,
    Phase,
    PlannerSettings,
    PlanningState,
    flight_cost,
)
from planner.geometry.clearance import ClearanceField, ExactClearance
from planner.geometry.path_encoding import DetourEncoding, TurnEncoding, grid_steps
from planner.model.trajectory import Trajectory, merge_collinear

Array = NDArray[np.float64]
IMPROVE_ITERATIONS = 40  # at most, per improvement run of the anytime flow
IMPROVE_PATIENCE = 15  # iterations without gain that end an improvement run
Encoding = DetourEncoding | TurnEncoding
Region = tuple[Array, Array]
Corridor = tuple[Array, float]


class Flow(Protocol):
    """Where the two flows differ; see the module's list."""

    @property
    def probes(self) -> bool: ...

    def encoding(self, state: PlanningState, uav: str, world: Map) -> Encoding | None: ...

    def corridor(self, encoding: Encoding) -> Corridor | None: ...

    def clearance(
        self, world: Map, region: Region, corridor: Corridor | None, radius: float
    ) -> ClearanceField | ExactClearance: ...

    def iterations(self, settings: PlannerSettings, phase: Phase) -> int: ...

    def patience(self, settings: PlannerSettings, phase: Phase) -> int | None: ...

    def better(
        self,
        state: PlanningState,
        uav: str,
        trajectory: Trajectory,
        cost: float,
        before: float,
        phase: Phase,
    ) -> bool: ...

    def stored(self, trajectory: Trajectory, speed: float) -> Trajectory: ...

    def fleet_passes(self, state: PlanningState) -> bool: ...


def horizon_wait(state: PlanningState, uav: str) -> float:
    """The longest hover worth searching: until the others are down, at most MAX_HOVER."""
    horizon = max((t.end_time for u, t in state.paths.items() if u != uav), default=1.0)
    return min(horizon + 1.0, MAX_HOVER)


def better_by_search(before: float, cost: float, phase: Phase) -> bool:
    """By the search's own cost, lower than the current path's (by at least MIN_GAIN
    when improving)."""
    gain = MIN_GAIN * max(abs(before), 1.0) if phase is Phase.IMPROVEMENT else 0.0
    return cost < before - gain


@dataclass(frozen=True)
class PaperFlow:
    """Algorithm 1 as the paper runs it: the optimizer repairs the shortest paths."""

    probes: bool  # qos with an improvement phase: a hover is tried before a search

    def encoding(self, state: PlanningState, uav: str, world: Map) -> Encoding | None:
        spec = state.specs[uav]
        if state.settings.objective == "qos":
            cells = world.route(spec.start, spec.goal)
            if cells is None:
                return None
            max_wait = horizon_wait(state, uav)
            return DetourEncoding.around(np.array(cells, dtype=float), max_wait=max_wait)
        offset = state.paths[uav].end - np.array(spec.goal, dtype=float)
        same_way = np.sign(offset) if np.any(offset) else None
        return TurnEncoding(grid_steps(merge_collinear(state.paths[uav].xy)), same_way)

    def corridor(self, encoding: Encoding) -> Corridor | None:
        return None  # only the encoding's region is known

    def clearance(
        self, world: Map, region: Region, corridor: Corridor | None, radius: float
    ) -> ClearanceField:
        return world.field

    def iterations(self, settings: PlannerSettings, phase: Phase) -> int:
        return settings.iterations

    def patience(self, settings: PlannerSettings, phase: Phase) -> int | None:
        return settings.patience

    def better(
        self,
        state: PlanningState,
        uav: str,
        trajectory: Trajectory,
        cost: float,
        before: float,
        phase: Phase,
    ) -> bool:
        return better_by_search(before, cost, phase)

    def stored(self, trajectory: Trajectory, speed: float) -> Trajectory:
        return trajectory

    def fleet_passes(self, state: PlanningState) -> bool:
        if state.table.pairs:
            return False  # the check would find these; no need to run it
        started = time.perf_counter()
        safe = state.check().safe
        state.budget.keep_back(2.0 * (time.perf_counter() - started))  # for the final check
        return safe


@dataclass(frozen=True)
class AnytimeFlow:
    """The anytime `qos` flow: every search anchored on the UAV's lone any-angle path."""

    probes: bool  # an improvement phase follows: a hover is tried before a search
    geometry: dict[str, Array] = field(default_factory=dict)  # each UAV's lone polyline
    lone: dict[str, float] = field(default_factory=dict)  # its length

    def encoding(self, state: PlanningState, uav: str, world: Map) -> DetourEncoding:
        """The optimizer moves the lone path's points and picks a hover at each, only in a
        window round where the UAV now hovers (the rest of its path has nothing to gain):
        a long path then costs a search of a few points, not of all of them."""
        max_wait = horizon_wait(state, uav)
        lone = self.geometry[uav]
        window = hover_window(state.paths[uav], lone)
        if window is None:
            return DetourEncoding.around(lone, max_wait=max_wait)
        before, inner, after = split(lone, *window)
        return DetourEncoding.around(inner, max_wait=max_wait, before=before, after=after)

    def corridor(self, encoding: Encoding) -> Corridor | None:
        """Only the other UAVs' samples near the lone path matter to its search."""
        return encoding.corridor() if isinstance(encoding, DetourEncoding) else None

    def clearance(
        self, world: Map, region: Region, corridor: Corridor | None, radius: float
    ) -> ExactClearance:
        """Exact clearance from the blocked cells the search's paths can reach: those near
        its corridor, else those in its region."""
        if corridor is not None:
            polyline, reach = corridor
        else:
            lo, hi = region
            polyline, reach = np.array([lo, hi]), float(np.hypot(*(hi - lo))) / 2
        return ExactClearance.near(world.searched, polyline, reach + radius)

    def iterations(self, settings: PlannerSettings, phase: Phase) -> int:
        """An improvement run starts from a safe plan and polishes it: a short run, whose
        schedule (MVO's WEP and TDR, eqs. 3.3-3.4 of the MVO paper) anneals within it."""
        if phase is Phase.IMPROVEMENT:
            return min(settings.iterations, IMPROVE_ITERATIONS)
        return settings.iterations

    def patience(self, settings: PlannerSettings, phase: Phase) -> int | None:
        """Improvement runs only polish a safe plan: they converge sooner."""
        if phase is Phase.IMPROVEMENT and settings.patience is not None:
            return min(settings.patience, IMPROVE_PATIENCE)
        return settings.patience

    def better(
        self,
        state: PlanningState,
        uav: str,
        trajectory: Trajectory,
        cost: float,
        before: float,
        phase: Phase,
    ) -> bool:
        """An improvement must lower the plan's true cost (length and hover price), not
        only the search's sampled one; making a UAV safe goes by the search's cost."""
        if phase is not Phase.IMPROVEMENT:
            return better_by_search(before, cost, phase)
        speed = state.specs[uav].speed
        current = flight_cost(state.paths[uav], speed)
        return flight_cost(trajectory, speed) < current - MIN_GAIN * max(current, 1.0)

    def stored(self, trajectory: Trajectory, speed: float) -> Trajectory:
        return trajectory.quantised(speed)

    def fleet_passes(self, state: PlanningState) -> bool:
        """The conflict table holds the exact check's verdict on every pair and every cell
        (`planner.flows.conflict_table`), so a clear table is a fleet that passes it."""
        return state.table.clear()


def paper_flow(settings: PlannerSettings) -> PaperFlow:
    return PaperFlow(probes=settings.objective == "qos" and settings.improve_rounds > 0)
