"""The wormhole step (eq. 9) done live: a non-UAV object reported during the flight.

In Algorithm 1 the wormhole F_WO places the non-UAV objects once the UAVs are
deconflicted and lets only the UAVs whose path an object touches replan. The paper's
future work asks for this in flight: "tell only the UAVs that must change". An object
reported at plan time `now` (a cell, there during a window or from now on) is met with
the same rule on what is left of every flight:

- a UAV is touched if its disc enters the object's cell on its remaining path while
  the object is there (the exact check's cell rule, restricted to the window);
- the touched UAVs replan one at a time, earliest threatened first (eq. 7 with the
  object as the collision: 1 / (t_c x T)), from where each is now to its goal, with
  the black hole's search (eq. 8) against everyone else's remaining flight, held fixed;
- nobody else changes, and the answer is feasible only if the exact check finds
  nothing on the whole remaining fleet. A UAV that no search makes safe keeps its old
  trajectory and is reported, never handed an unsafe new one.

Objects are honoured in time: a new path may cross the cell before the object appears
or after it has gone, and a UAV whose goal is under an object with a window hovers
nearby until it has gone. Inside this module (and `planner.live.objects`, what the
objects block, and `planner.live.search`, one UAV's search) time runs from `now`,
because the search and the exact check both take every flight to start at t = 0;
results are in plan time.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.check.safety import Conflict
from planner.flows.planning import PlannerSettings
from planner.live.objects import (
    Blocking,
    NewObject,
    fleet_conflicts,
    timed_conflicts,
    window_from,
)
from planner.live.search import replan_one
from planner.model.plan import Plan
from planner.model.scenario import Scenario, UAVSpec
from planner.model.trajectory import Trajectory
from planner.optimizers import get_algorithm

__all__ = ["LIVE_SETTINGS", "LiveReplan", "NewObject", "replan_live"]

Array = NDArray[np.float64]
Cell = tuple[int, int]
LIVE_SETTINGS = PlannerSettings(population=20, iterations=150)


@dataclass(frozen=True)
class LiveReplan:
    """What a reported object changes; trajectories are `[t, x, y]` in plan time."""

    now: float
    touched: list[str]  # UAVs whose remaining path the object touches, in replanning order
    changed: dict[str, Trajectory]  # new trajectories, from the position at `now`
    unresolved: list[str]  # touched UAVs that keep their old trajectory: no safe path
    feasible: bool  # the exact check finds nothing on the whole remaining fleet
    conflicts: list[dict[str, Any]]  # what it found (Conflict.to_json(), times in plan seconds)
    explanation: str  # one sentence for the operator

    def to_json(self) -> dict[str, Any]:
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        return fields | {"changed": {u: t.to_json() for u, t in self.changed.items()}}


def replan_live(
    scenario: Scenario,
    plan: Plan,
    new_object: NewObject,
    *,
    now: float,
    positions: Mapping[str, tuple[float, float]] | None = None,
    progress: Mapping[str, float] | None = None,
    known_objects: Sequence[NewObject] = (),
    settings: PlannerSettings = LIVE_SETTINGS,
) -> LiveReplan:
    """Replan only the UAVs whose remaining flight `new_object` touches (eq. 9, live).

    `positions` (grid coordinates) are where UAVs start a new path from at `now`; by
    default where their trajectory says (the ground station gives where a vehicle under
    way comes to rest once stopped). Only the replanned UAVs start from them: the others
    keep their trajectories. `progress` is where each UAV is on its own trajectory (its plan time)
    at `now`, by default `now`: a fleet flown by its passing order keeps the plan's order,
    not its clock, so each UAV's remaining flight starts where it is. `known_objects` are
    objects reported before, which every path avoids.
    Searches use the `qos` objective whatever `settings.objective` says (a UAV in flight
    must still reach its goal); every random draw comes from `settings.seed`.
    Raises ValueError on input the service should refuse (an object outside the grid).
    """
    get_algorithm(settings.algorithm)
    specs = {u.id: u for u in scenario.uavs}
    _validate(scenario, plan, [new_object, *known_objects], now, positions or {})
    own = _validated_progress(scenario, progress or {})
    new_object, *known_objects = (_plain(o) for o in (new_object, *known_objects))
    fleet = _remaining(plan, now, own)
    blocking = Blocking.build(
        scenario.blocked(),
        [(c[0], c[1]) for c in plan.non_uav_objects],
        [*known_objects, new_object],
        now,
    )
    window = window_from(new_object, now)
    touched = _touched(fleet, specs, new_object.cell, window, scenario)
    where = {
        u: np.asarray((positions or {}).get(u, t.xy[0]), dtype=float) for u, t in fleet.items()
    }
    blocked_now = {
        u: _why_not(specs[u], where[u], new_object.cell, window, blocking) for u in touched
    }
    failed = {u: why for u, why in blocked_now.items() if why is not None}
    order = [u for u in touched if u not in failed]
    replanner = _Replanner(where, specs, blocking, scenario, settings)
    changed = _replan_in_turn(order, fleet, replanner, now, failed)
    if changed:  # then every rest restarts now (gcs.mission.flight_plan.continued)
        _resolve_kept(fleet, replanner, changed, failed)
    conflicts = [_in_plan_time(c, now) for c in fleet_conflicts(fleet, specs, blocking)]
    return LiveReplan(
        now=now,
        touched=touched,
        changed={u: _shifted(t, now) for u, t in changed.items()},
        unresolved=[u for u in touched if u in failed],
        feasible=not conflicts,
        conflicts=[c.to_json() for c in conflicts],
        explanation=_explain(
            new_object, now, window, touched, list(changed), failed, conflicts, len(fleet)
        ),
    )


@dataclass(frozen=True)
class _Replanner:
    """What every UAV's replan is searched in: where each UAV is now, the fleet's specs,
    what blocks, the scenario and the settings."""

    where: Mapping[str, Array]
    specs: Mapping[str, UAVSpec]
    blocking: Blocking
    scenario: Scenario
    settings: PlannerSettings

    def replan(
        self, uav: str, fixed: Mapping[str, Trajectory], rng: np.random.Generator
    ) -> tuple[Trajectory | None, list[Conflict]]:
        return replan_one(
            self.specs[uav], self.where[uav], fixed, self.specs, self.blocking,
            self.scenario, self.settings, rng,
        )  # fmt: skip


def _resolve_kept(
    fleet: dict[str, Trajectory],
    replanner: _Replanner,
    changed: dict[str, Trajectory],
    failed: Mapping[str, str],
) -> None:
    """Kept UAVs in conflict with another after a replan that changed a path are
    replanned too, one at a time against everyone else, each at most once: the flight
    then restarts every rest now, wherever its UAV is, so two its order held apart in
    time may meet (fuzzed flight 3294: uav1 and uav5 0.198 cells apart, and the order
    then kept no more than that). Kept only if every pair is then apart; a replan that
    changes nothing leaves the flight and its order as they are. Updates `fleet` and
    `changed`."""
    rng = np.random.default_rng(replanner.settings.seed + 1)
    trial, extra = dict(fleet), dict[str, Trajectory]()
    tried: set[str] = set()
    while True:
        conflicts = fleet_conflicts(trial, replanner.specs, replanner.blocking)
        pairs = [c.uavs for c in conflicts if c.kind == "uav"]
        kept = [u for pair in pairs for u in reversed(pair) if u not in changed | extra]
        uav = next((u for u in kept if u not in failed and u not in tried), None)
        if uav is None:
            break
        tried.add(uav)
        path, _ = replanner.replan(uav, {u: t for u, t in trial.items() if u != uav}, rng)
        if path is not None:
            trial[uav] = extra[uav] = path
    if not pairs:  # every pair apart: else the kept ones stay as they were
        fleet.update(extra)
        changed.update(extra)


def _replan_in_turn(
    order: list[str],
    fleet: dict[str, Trajectory],
    replanner: _Replanner,
    now: float,
    failed: dict[str, str],
) -> dict[str, Trajectory]:
    """Prioritized replanning: each UAV in `order` searches against everyone but those
    still to come, whose old paths are about to change. Updates `fleet` and `failed`."""
    rng = np.random.default_rng(replanner.settings.seed)
    changed = {}
    for k, uav in enumerate(order):
        fixed = {u: t for u, t in fleet.items() if u != uav and u not in order[k + 1 :]}
        path, found = replanner.replan(uav, fixed, rng)
        if path is not None:
            fleet[uav] = changed[uav] = path
        elif found:
            failed[uav] = f"found no safe path ({_in_plan_time(found[0], now).describe()})"
        else:
            x, y = replanner.where[uav]
            failed[uav] = f"has no way from ({x:.2f}, {y:.2f}) to its goal"
    return changed


def _validate(
    scenario: Scenario,
    plan: Plan,
    objects: Sequence[NewObject],
    now: float,
    positions: Mapping[str, tuple[float, float]],
) -> None:
    """Refuse what cannot be planned with a message that says what is wrong."""
    grid = scenario.grid
    if {u.id for u in plan.uavs} != {u.id for u in scenario.uavs}:
        raise ValueError("the plan's UAVs are not the scenario's UAVs")
    if not (math.isfinite(now) and now >= 0):
        raise ValueError(f"now = {now} must be a finite time >= 0 s")
    for obj in objects:
        cell = obj.cell
        if len(cell) != 2 or not all(isinstance(c, int | np.integer) for c in cell):
            raise ValueError(f"object cell {cell} must be two integers (x, y)")
        if not grid.contains(cell):
            raise ValueError(f"object cell {cell} is outside the {grid.width}x{grid.height} grid")
        if obj.window is not None:
            t0, t1 = obj.window
            if math.isnan(t0) or math.isnan(t1) or math.isinf(t0) or t1 < t0:
                raise ValueError(f"object window {obj.window} must be [t0, t1] with t0 <= t1")
    ids = {u.id for u in scenario.uavs}
    for uav, (x, y) in positions.items():
        if uav not in ids:
            raise ValueError(f"position given for unknown UAV {uav!r}")
        inside = -0.5 <= x <= grid.width - 0.5 and -0.5 <= y <= grid.height - 0.5
        if not inside:  # also refuses NaN
            raise ValueError(f"position ({x}, {y}) of {uav!r} is outside the grid")


def _plain(obj: NewObject) -> NewObject:
    """The same object with Python numbers (numpy ones print badly in messages)."""
    x, y = obj.cell
    window = None if obj.window is None else (float(obj.window[0]), float(obj.window[1]))
    return NewObject((int(x), int(y)), window)


def _validated_progress(scenario: Scenario, progress: Mapping[str, float]) -> dict[str, float]:
    ids = {u.id for u in scenario.uavs}
    for uav, t in progress.items():
        if uav not in ids:
            raise ValueError(f"progress given for unknown UAV {uav!r}")
        if not (math.isfinite(t) and t >= 0):
            raise ValueError(f"progress {t} of {uav!r} must be a finite plan time >= 0 s")
    return dict(progress)


def _remaining(plan: Plan, now: float, own: Mapping[str, float]) -> dict[str, Trajectory]:
    """What is left of every flight still airborne, from where each UAV is on its own
    trajectory (`own`, else `now`), shifted to start at 0 (= `now`)."""
    out = {}
    for u in plan.uavs:
        track = Trajectory(np.array(u.trajectory, dtype=float))
        at = own.get(u.id, now)
        if track.end_time > at:
            rest = track.between(at, track.end_time)
            assert rest is not None
            out[u.id] = _shifted(rest, -at)
    return out


def _shifted(trajectory: Trajectory, by: float) -> Trajectory:
    return Trajectory(trajectory.points + np.array([by, 0.0, 0.0]))


def _in_plan_time(conflict: Conflict, now: float) -> Conflict:
    return dataclasses.replace(conflict, time=conflict.time + now)


def _touched(
    fleet: Mapping[str, Trajectory],
    specs: Mapping[str, UAVSpec],
    cell: Cell,
    window: tuple[float, float],
    scenario: Scenario,
) -> list[str]:
    """The UAVs the object touches, highest eq. 7 priority first: 1 / (t_c x T) with the
    object as the one collision (ties keep the scenario's order)."""
    shape = (scenario.grid.width, scenario.grid.height)
    priority = {}
    for uav, track in fleet.items():
        hits = timed_conflicts(uav, track, specs[uav].radius, cell, window, shape)
        if hits:
            first = max(min(c.time for c in hits), 1e-3)
            priority[uav] = 1.0 / (first * max(track.end_time, 1e-3))
    return sorted(priority, key=lambda u: -priority[u])


def _why_not(
    spec: UAVSpec, position: Array, cell: Cell, window: tuple[float, float], blocking: Blocking
) -> str | None:
    """Why a touched UAV cannot be replanned at all, or None if it can try."""
    inside = np.hypot(*np.maximum(np.abs(position - np.array(cell)) - 0.5, 0.0)) < spec.radius
    if inside and window[0] <= 0 <= window[1]:
        return f"is in the object's cell {cell} now, or cannot stop before it"
    if blocking.obstacles[spec.goal] or blocking.objects[spec.goal]:
        return f"cannot land: its goal {spec.goal} is under an object with no end"
    return None


def _explain(
    obj: NewObject,
    now: float,
    window: tuple[float, float],
    touched: list[str],
    changed: list[str],
    failed: Mapping[str, str],
    conflicts: list[Conflict],
    airborne: int,
) -> str:
    """One sentence for the operator."""
    what = f"The object at {tuple(obj.cell)} reported at t = {now:.2f} s"
    if failed:
        reasons = "; ".join(f"{u} {why}" for u, why in failed.items())
        return f"{what} leaves no safe plan: {reasons}."
    if conflicts:
        return f"{what} leaves no safe plan: {conflicts[0].describe()}."
    if window[1] < 0:
        return f"{what} has already gone (its window ended); no trajectory changes."
    if not touched:
        return f"{what} touches no UAV's remaining path; no trajectory changes."
    kept = airborne - len(changed)
    return (
        f"{what}: {', '.join(changed)} replanned around it from their current positions; "
        f"the other {kept} airborne UAV(s) keep their trajectories."
    )
