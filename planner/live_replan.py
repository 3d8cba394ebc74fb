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
nearby until it has gone. Inside this module time runs from `now`, because the search
and the exact check both take every flight to start at t = 0; results are in plan time.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.black_hole import Search, search_path
from planner.clearance import ClearanceField
from planner.grid_search import GridGraph, cell_map, descend
from planner.objectives import QosObjective
from planner.optimizers import get_algorithm
from planner.path_cost import Traffic
from planner.path_encoding import DetourEncoding
from planner.pipeline import ATTEMPTS, MAX_HOVER, PlannerSettings
from planner.plan import Plan
from planner.safety import Conflict, cell_conflicts, check_plan, uav_conflicts
from planner.scenario import Scenario, UAVSpec
from planner.trajectory import Trajectory, merge_collinear

Array = NDArray[np.float64]
Cell = tuple[int, int]
LIVE_SETTINGS = PlannerSettings(population=20, iterations=150)
# The search keeps UAVs apart as discs: a disc round each quarter of a cell covers the
# cell's square, and it reaches at most 0.1 cell beyond it, so neighbours stay usable.
QUARTERS = np.array([(-0.25, -0.25), (-0.25, 0.25), (0.25, -0.25), (0.25, 0.25)])
QUARTER_RADIUS = math.sqrt(2.0) / 4.0


@dataclass(frozen=True)
class NewObject:
    """A non-UAV object on `cell`, there during `window` (plan seconds, the end may be
    math.inf) or, without a window, from now on."""

    cell: tuple[int, int]
    window: tuple[float, float] | None = None


@dataclass(frozen=True)
class LiveReplan:
    """What a reported object changes; trajectories are `[t, x, y]` in plan time."""

    now: float
    touched: list[str]  # UAVs whose remaining path the object touches, in replanning order
    changed: dict[str, Trajectory]  # new trajectories, from the position at `now`
    unresolved: list[str]  # touched UAVs that keep their old trajectory: no safe path
    feasible: bool  # the exact check finds nothing on the whole remaining fleet
    conflicts: list[dict]  # what it found (Conflict.to_json(), times in plan seconds)
    explanation: str  # one sentence for the operator

    def to_json(self) -> dict:
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        return fields | {"changed": {u: t.to_json() for u, t in self.changed.items()}}


@dataclass(frozen=True)
class _Blocking:
    """What every UAV keeps clear of, with time counted from `now`."""

    obstacles: NDArray[np.bool_]
    objects: NDArray[np.bool_]  # known objects and reported ones there from now on
    timed: tuple[tuple[Cell, float, float], ...]  # reported objects there only in [a, b]
    field: ClearanceField  # obstacles and objects, for the search

    @classmethod
    def build(
        cls,
        obstacles: NDArray[np.bool_],
        known: Sequence[Cell],
        live: Sequence[NewObject],
        now: float,
    ) -> _Blocking:
        objects = cell_map(known, obstacles.shape)
        timed = []
        for obj in live:
            a, b = _window_from(obj, now)
            if b < 0:
                continue  # already gone
            if a <= 0 and math.isinf(b):
                objects[obj.cell] = True
            else:
                timed.append((obj.cell, max(a, 0.0), b))
        return cls(obstacles, objects, tuple(timed), ClearanceField.build(obstacles | objects))

    def cell_conflicts(self, uav: str, trajectory: Trajectory, radius: float) -> list[Conflict]:
        """The exact cell rule for one UAV, timed objects only during their window."""
        found = cell_conflicts(uav, trajectory, radius, self.obstacles, "obstacle")
        found += cell_conflicts(uav, trajectory, radius, self.objects, "non_uav_object")
        for cell, a, b in self.timed:
            found += _timed_conflicts(uav, trajectory, radius, cell, (a, b), self.obstacles.shape)
        return found

    def discs(self, until: float) -> list[tuple[Trajectory, float, float]]:
        """Timed objects as motionless discs for the search's traffic, up to `until`."""
        out = []
        for (x, y), a, b in self.timed:
            if a > until:
                continue
            for dx, dy in QUARTERS:
                hover = np.array([[a, x + dx, y + dy], [min(b, until), x + dx, y + dy]])
                out.append((Trajectory(hover), QUARTER_RADIUS, 0.0))
        return out

    def max_wait(self, horizon: float) -> float:
        """Hover long enough to let the others pass, or a timed object go."""
        ends = [b for _, _, b in self.timed if math.isfinite(b)]
        return max([min(horizon + 1.0, MAX_HOVER)] + [b + 1.0 for b in ends])


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

    `positions` (grid coordinates) are where UAVs are at `now`; by default where their
    trajectory says. Only the replanned UAVs start from them: the others keep their
    trajectories. `progress` is where each UAV is on its own trajectory (its plan time)
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
    blocking = _Blocking.build(
        scenario.blocked(),
        [(c[0], c[1]) for c in plan.non_uav_objects],
        [*known_objects, new_object],
        now,
    )
    window = _window_from(new_object, now)
    touched = _touched(fleet, specs, new_object.cell, window, scenario)
    where = {
        u: np.asarray((positions or {}).get(u, t.xy[0]), dtype=float) for u, t in fleet.items()
    }
    blocked_now = {
        u: _why_not(specs[u], where[u], new_object.cell, window, blocking) for u in touched
    }
    failed = {u: why for u, why in blocked_now.items() if why is not None}
    order = [u for u in touched if u not in failed]
    changed = _replan_in_turn(order, fleet, where, specs, blocking, scenario, settings, now, failed)
    conflicts = [_in_plan_time(c, now) for c in _fleet_conflicts(fleet, specs, blocking)]
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


def _replan_in_turn(
    order: list[str],
    fleet: dict[str, Trajectory],
    where: Mapping[str, Array],
    specs: Mapping[str, UAVSpec],
    blocking: _Blocking,
    scenario: Scenario,
    settings: PlannerSettings,
    now: float,
    failed: dict[str, str],
) -> dict[str, Trajectory]:
    """Prioritized replanning: each UAV in `order` searches against everyone but those
    still to come, whose old paths are about to change. Updates `fleet` and `failed`."""
    rng = np.random.default_rng(settings.seed)
    changed = {}
    for k, uav in enumerate(order):
        fixed = {u: t for u, t in fleet.items() if u != uav and u not in order[k + 1 :]}
        path, found = _replan_one(
            specs[uav], where[uav], fixed, specs, blocking, scenario, settings, rng
        )
        if path is not None:
            fleet[uav] = changed[uav] = path
        elif found:
            failed[uav] = f"found no safe path ({_in_plan_time(found[0], now).describe()})"
        else:
            x, y = where[uav]
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


def _window_from(obj: NewObject, now: float) -> tuple[float, float]:
    """The object's window with time counted from `now` (from now on if it has none)."""
    if obj.window is None:
        return 0.0, math.inf
    return obj.window[0] - now, obj.window[1] - now


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


def _timed_conflicts(
    uav: str,
    trajectory: Trajectory,
    radius: float,
    cell: Cell,
    window: tuple[float, float],
    shape: tuple[int, int],
) -> list[Conflict]:
    """The cell rule on the part of the flight during the window."""
    part = trajectory.between(*window)
    if part is None:
        return []
    return cell_conflicts(uav, part, radius, cell_map([cell], shape), "non_uav_object")


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
        hits = _timed_conflicts(uav, track, specs[uav].radius, cell, window, shape)
        if hits:
            first = max(min(c.time for c in hits), 1e-3)
            priority[uav] = 1.0 / (first * max(track.end_time, 1e-3))
    return sorted(priority, key=lambda u: -priority[u])


def _why_not(
    spec: UAVSpec, position: Array, cell: Cell, window: tuple[float, float], blocking: _Blocking
) -> str | None:
    """Why a touched UAV cannot be replanned at all, or None if it can try."""
    inside = np.hypot(*np.maximum(np.abs(position - np.array(cell)) - 0.5, 0.0)) < spec.radius
    if inside and window[0] <= 0 <= window[1]:
        return f"is inside the object's cell {cell} now"
    if blocking.obstacles[spec.goal] or blocking.objects[spec.goal]:
        return f"cannot land: its goal {spec.goal} is under an object with no end"
    return None


def _replan_one(
    spec: UAVSpec,
    position: Array,
    fixed: Mapping[str, Trajectory],
    specs: Mapping[str, UAVSpec],
    blocking: _Blocking,
    scenario: Scenario,
    settings: PlannerSettings,
    rng: np.random.Generator,
) -> tuple[Trajectory | None, list[Conflict]]:
    """A new path that the exact check clears against everything held fixed (eq. 8), or
    None and what the last attempt ran into (nothing if there is no route at all).

    The searches alternate between two routes: the shortest way round the objects, and
    the shortest that also keeps off the cells the others will still fly through (the
    detour encoding bends a route by 1.5 cells at most). Each attempt continues the same
    generator. The last resort hovers where the UAV is until the others have landed and
    the timed objects have gone, then flies the first route."""
    routes = _routes(spec, position, fixed, specs, blocking)
    if not routes:
        return None, []
    horizon = max((t.end_time for t in fixed.values()), default=1.0)
    last: list[Conflict] = []
    for attempt in range(ATTEMPTS):
        encoding = DetourEncoding.around(
            routes[attempt % len(routes)], max_wait=blocking.max_wait(horizon)
        )
        outcome = search_path(
            encoding,
            _search(spec, position, encoding, fixed, specs, blocking, scenario),
            algorithm=settings.algorithm,
            population=settings.population,
            iterations=settings.iterations,
            rng=rng,
        )
        last = _own_conflicts(spec, outcome.trajectory, fixed, specs, blocking)
        if not last:
            return outcome.trajectory, []
    ends = [horizon] + [b for _, _, b in blocking.timed if math.isfinite(b)]
    corners = merge_collinear(routes[0])
    waits = np.zeros(len(corners))
    waits[0] = max(ends) + 0.1
    patient = Trajectory.from_waypoints(corners, spec.speed, waits)
    if not _own_conflicts(spec, patient, fixed, specs, blocking):
        return patient, []
    return None, last


def _routes(
    spec: UAVSpec,
    position: Array,
    fixed: Mapping[str, Trajectory],
    specs: Mapping[str, UAVSpec],
    blocking: _Blocking,
) -> list[Array]:
    """The routes to search around (see _replan_one), the shortest first."""
    static = blocking.obstacles | blocking.objects
    timed = cell_map([c for c, _, _ in blocking.timed], static.shape)
    everywhere = np.ones_like(static)
    swept = cell_map(
        [
            c.cell
            for u, t in fixed.items()
            for c in cell_conflicts(u, t, specs[u].radius, everywhere)
            if c.cell is not None  # always set for a cell conflict
        ],
        static.shape,
    )
    # Timed objects are walked round if possible; the search may still cross their cells
    # when they are not there, and a UAV may wait for one on its goal to go.
    timed[spec.goal] = swept[spec.goal] = False
    first = _route(position, spec.goal, spec.radius, static | timed)
    if first is None:
        first = _route(position, spec.goal, spec.radius, static)
    if first is None:
        return []
    clear = _route(position, spec.goal, spec.radius, static | timed | swept)
    if clear is None or (len(clear) == len(first) and np.allclose(clear, first)):
        return [first]
    return [first, clear]


def _route(position: Array, goal: Cell, radius: float, blocked: NDArray[np.bool_]) -> Array | None:
    """The exact position, then the shortest grid path to the goal from the neighbouring
    cell that makes the whole way shortest (None if no neighbour leads there)."""
    distance = GridGraph.build(blocked).distances_to(goal)
    start = _entry_cell(position, radius, distance, blocked)
    if start is None:
        return None
    path = np.array(descend(distance, start, blocked), dtype=float)
    if np.allclose(path[0], position):
        return path
    return np.vstack([position, path])


def _entry_cell(
    position: Array, radius: float, distance: Array, blocked: NDArray[np.bool_]
) -> Cell | None:
    """Of the free cells around `position`, the one with the shortest way to the goal,
    preferring those the UAV reaches in a straight line without touching a blocked cell
    (the first leg is the one leg the search cannot bend)."""
    centre = np.rint(position).astype(int)
    offsets = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)])
    cells = centre + offsets
    cells = cells[np.all((cells >= 0) & (cells < distance.shape), axis=1)]
    cells = cells[~blocked[cells[:, 0], cells[:, 1]]]
    total = np.hypot(*(cells - position).T) + distance[cells[:, 0], cells[:, 1]]
    if not np.isfinite(total).any():
        return None
    grazes = [
        bool(cell_conflicts("", Trajectory(np.array([[0, *position], [1, *c]])), radius, blocked))
        for c in cells
    ]
    x, y = cells[np.lexsort((total, grazes))[0]]
    return int(x), int(y)


def _search(
    spec: UAVSpec,
    position: Array,
    encoding: DetourEncoding,
    fixed: Mapping[str, Trajectory],
    specs: Mapping[str, UAVSpec],
    blocking: _Blocking,
    scenario: Scenario,
) -> Search:
    """The cost of `spec`'s candidates against the fixed flights and the timed objects."""
    others = [(t, specs[u].radius, specs[u].speed) for u, t in fixed.items()]
    others += blocking.discs(_longest_flight(encoding, spec.speed))
    lower, upper = encoding.region()
    traffic = Traffic.around(
        others, radius=spec.radius, speed=spec.speed, start=position, lower=lower, upper=upper
    )
    penalty = 100.0 * (scenario.grid.width + scenario.grid.height + 10)
    goal = np.array(spec.goal, dtype=float)
    return Search(
        spec.speed, spec.radius, goal, traffic, blocking.field, QosObjective(spec.speed, penalty)
    )


def _longest_flight(encoding: DetourEncoding, speed: float) -> float:
    """A bound on the flight time of any path the encoding can produce."""
    points = np.vstack([encoding.start, encoding.base, encoding.goal])
    legs = len(points) - 1
    length = (
        np.hypot(*np.diff(points, axis=0).T).sum() + legs * 2 * math.sqrt(2) * encoding.max_offset
    )
    return float(length / speed + legs * encoding.max_wait + 1.0)


def _own_conflicts(
    spec: UAVSpec,
    trajectory: Trajectory,
    fixed: Mapping[str, Trajectory],
    specs: Mapping[str, UAVSpec],
    blocking: _Blocking,
) -> list[Conflict]:
    """The exact check for one new flight against everything held fixed."""
    found = blocking.cell_conflicts(spec.id, trajectory, spec.radius)
    for other, track in fixed.items():
        radii = {spec.id: spec.radius, other: specs[other].radius}
        found += uav_conflicts({spec.id: trajectory, other: track}, radii)[0]
    return found


def _fleet_conflicts(
    fleet: Mapping[str, Trajectory], specs: Mapping[str, UAVSpec], blocking: _Blocking
) -> list[Conflict]:
    """planner.safety.check_plan on the remaining fleet, plus timed objects in their window."""
    radii = {u: specs[u].radius for u in fleet}
    objects = [(int(x), int(y)) for x, y in np.argwhere(blocking.objects)]
    found = check_plan(fleet, radii, blocking.obstacles, objects).conflicts
    for uav, track in fleet.items():
        for cell, a, b in blocking.timed:
            found += _timed_conflicts(
                uav, track, radii[uav], cell, (a, b), blocking.obstacles.shape
            )
    return found


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
