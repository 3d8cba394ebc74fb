"""A plan made flyable at a real speed: missions, the passing order, the timing, a verdict.

The plan's speeds are scaled by one factor so that its fastest UAV cruises at the flight
speed (5 m/s unless the operator asks otherwise), which keeps every relative speed and
every passing order of the plan. Each UAV's mission flies its path at those speeds with
no waits: where the plan makes a UAV wait for another, the passing order does
(`passing_order`), at whatever moment the other actually passes. The flight is timed as
copters fly it (`flight_timing`), and it is refused before anything is armed when the
ground station cannot keep it safe at that speed (`UnsafeSpeed`, naming the highest
speed it can).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from gcs.mavlink.mission_item import Autopilot, Command, Mission
from gcs.mission.build import DEFAULT_ALTITUDE_M, Finish, Visit, build_missions, takeoff_index
from gcs.mission.flight_timing import FlightStuck, TimedPath, fly
from gcs.mission.geodesy import Floats, GridFrame
from gcs.mission.landing_clearance import clear_landings
from gcs.mission.motion import (
    DEFAULT_SPEED_M_S,
    CopterLimits,
    highest_speed_for_stray,
    stray_m,
)
from gcs.mission.passing_order import PassingOrder, PlannedPath
from planner.check.safety import uav_conflicts
from planner.model.plan import Plan
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory

TURN_RADIUS_M = 0.5
"""A vehicle passing a waypoint cuts the corner by up to its acceptance radius (ArduCopter's
default is 2 m): close, so that the path flown is the path the order was derived for."""
MAX_SPEED_M_S = 20.0
"""ArduCopter's WPNAV_SPEED range ends at 20 m/s."""
DEFAULT_CLEARANCE_M = 1.3
"""What a plan made for flying keeps beyond 2R: twice what a vehicle may stray at 10 m/s
(`stray_m`), so that the passing order can keep every pair 2R apart up to that speed."""
STOPPING_NEXT = frozenset({Command.NAV_LAND, Command.NAV_RETURN_TO_LAUNCH, Command.NAV_TAKEOFF})
"""What ArduCopter will not fly into without stopping at the waypoint before."""
PLACED = frozenset({Command.NAV_WAYPOINT, Command.NAV_LOITER_TIME, Command.NAV_LAND})
"""The NAV items after take-off that are places on the path."""
SAME_PLACE_M = 0.01
"""Two points of a path this close to a waypoint are equally its place: the first counts."""


class UnsafeSpeed(ValueError):
    """The flight cannot be kept safe at the speed asked for; answered 422."""

    def __init__(self, message: str, highest_safe_m_s: float | None) -> None:
        super().__init__(message)
        self.highest_safe_m_s = highest_safe_m_s


@dataclass(frozen=True)
class FlightPlan:
    """What the vehicles fly, and what the ground station keeps while they do."""

    speed_m_s: float  # the fastest UAV's cruise
    factor: float  # seconds of the flight per second of the plan
    plan: Plan  # times multiplied by `factor`
    scenario: Scenario  # speeds divided by `factor`
    missions: dict[str, Mission]
    paths: dict[str, PlannedPath]  # metres from the grid's origin, on the flight's clock
    leg_speeds: dict[str, Floats]  # m/s of each leg of each path
    limits: dict[str, CopterLimits]  # each vehicle's, at its cruise speed
    order: PassingOrder
    altitude_m: float

    @property
    def frame(self) -> GridFrame:
        return GridFrame.of(self.scenario)

    @cached_property
    def timed(self) -> dict[str, TimedPath]:
        """The flight when nothing goes wrong (computed when first asked: it is a
        simulation of every vehicle, a second or so for ten)."""
        return fly(
            self.paths, self.leg_speeds, self.limits, self.order,
            altitude_m=self.altitude_m, stops=self.stops,
        )  # fmt: skip

    @cached_property
    def stops(self) -> dict[str, Floats]:
        """Where each vehicle comes to rest on the way (metres along its path)."""
        return {
            uav: stopping_points(self.missions[uav], path, self.frame)
            for uav, path in self.paths.items()
        }

    @property
    def duration_s(self) -> float:
        """From the common start to the last arrival over a goal."""
        return max(t.arrival_s for t in self.timed.values())

    def min_separation_m(self) -> float:
        """The closest two UAVs come on the timed flight (until they are down)."""
        cell = self.scenario.grid.cell_size_m
        trajectories = {uav: t.trajectory(cell) for uav, t in self.timed.items()}
        radii = {u.id: u.radius for u in self.scenario.uavs}
        return uav_conflicts(trajectories, radii)[1] * cell

    def cruise_at(self, uav_id: str, along_m: float) -> float:
        """The speed the UAV's mission flies it at `along_m` metres along its path."""
        path, legs = self.paths[uav_id], self.leg_speeds[uav_id]
        if len(legs) == 0:
            return self.limits[uav_id].speed_m_s
        k = int(np.searchsorted(path.s, along_m, side="right")) - 1
        return float(legs[min(max(k, 0), len(legs) - 1)])

    def leaders(self, uav_id: str) -> list[str]:
        """The UAVs the passing order makes this one let pass first, each once (it may
        meet one of them twice)."""
        return sorted({w.leader for w in self.order.waits.get(uav_id, [])})

    def notes(self, uav_id: str) -> str:
        """What the UAV's mission file cannot say by itself: the passing order it keeps
        only when the ground station flies it with the others."""
        leaders = self.leaders(uav_id)
        others = len(self.missions) - 1
        timing = (
            f"mvo-gcs: {uav_id}'s mission, timed for {self.speed_m_s:g} m/s with its "
            f"vehicle's limits, for a start together with {others} other UAV(s)."
        )
        if not leaders:
            return f"{timing} It waits for nobody on the way."
        return (
            f"{timing} On the way it must let {', '.join(leaders)} pass first; only the "
            "ground station keeps that order (it pauses this vehicle until they have "
            "passed). Flown alone from this file, nothing keeps it: fly it with mvo-gcs, "
            "or keep the others clear of its path."
        )

    def places(self, uav_id: str) -> dict[int, float]:
        """Metres along the UAV's path of its mission's NAV items, by seq."""
        return item_places(self.missions[uav_id], self.paths[uav_id], self.frame)

    def visits(self, uav_id: str) -> list[Visit]:
        """The NAV items after take-off, when the timed flight reaches each."""
        return timed_visits(self.missions[uav_id], self.timed[uav_id], self.frame)


def flight_plan(
    plan: Plan,
    scenario: Scenario,
    autopilots: Mapping[str, Autopilot],
    *,
    altitude_m: float = DEFAULT_ALTITUDE_M,
    finish: Finish = "land",
    max_speed_m_s: float = DEFAULT_SPEED_M_S,
    turn_radius_m: float = TURN_RADIUS_M,
    limits: Mapping[str, CopterLimits] | None = None,
    landings_cleared: bool = True,
) -> FlightPlan:
    """The plan flown with its fastest UAV at `max_speed_m_s`; `limits` are each
    vehicle's (ArduCopter's defaults where not given). UnsafeSpeed if it cannot be kept.
    The missions and the order come at once; the timing when first asked for. Without
    `landings_cleared` nobody is held short of a landing (`_with_landings_cleared`): the
    verdict and the missions are the same, for a second less work on twelve UAVs."""
    if not 0 < max_speed_m_s <= MAX_SPEED_M_S:
        raise UnsafeSpeed(
            f"max_speed_m_s must be above 0 and at most {MAX_SPEED_M_S:g} m/s (ArduCopter's "
            f"WPNAV_SPEED range), got {max_speed_m_s:g}",
            min(MAX_SPEED_M_S, max(max_speed_m_s, 0.0)) or None,
        )
    cell = scenario.grid.cell_size_m
    radius = {u.id: u.radius * cell for u in scenario.uavs}
    raw = {u.id: PlannedPath.of(u.id, u.trajectory, cell, radius[u.id]) for u in plan.uavs}
    legs = {uav: _leg_speeds(p) for uav, p in raw.items()}
    fastest = max((float(s.max()) for s in legs.values() if len(s)), default=0.0)
    factor = fastest / max_speed_m_s if fastest > 0 else 1.0
    paths = {uav: _stretched_path(p, factor) for uav, p in raw.items()}
    leg_speeds = {uav: s / factor for uav, s in legs.items()}
    given = dict(limits or {})
    vehicle_limits = {
        uav: _at_cruise(given.get(uav, CopterLimits()), leg_speeds[uav], turn_radius_m)
        for uav in paths
    }
    margin = 2 * stray_m(max_speed_m_s)
    order = PassingOrder.derive(paths.values(), margin_m=margin)
    _refuse_if_unsafe(order, radius, max_speed_m_s)
    slow_plan, slow_scenario = stretched(plan, scenario, factor)
    missions = _missions(slow_plan, slow_scenario, autopilots, altitude_m, finish, turn_radius_m)
    flight = FlightPlan(
        max_speed_m_s, factor, slow_plan, slow_scenario, missions, paths, leg_speeds,
        vehicle_limits, order, altitude_m,
    )  # fmt: skip
    return _with_landings_cleared(flight, margin) if landings_cleared else flight


def continued(
    flight: FlightPlan,
    along: Mapping[str, float],
    changed: Mapping[str, Trajectory],
    missions: Mapping[str, Mission],
    now_s: float,
    committed_m: Mapping[str, float] | None = None,
) -> FlightPlan:
    """The rest of a flight after a live replan at `now_s` (the flight's clock): each UAV
    from where it is (`along`, metres along its path), on its new trajectory (`changed`:
    cells, the flight's clock) or the rest of its old path, and the passing order of
    those rests. A rest starts at `now_s` wherever its UAV is on its own plan, as the
    replan took it (`planner.live.replan`): a vehicle the order held back is not where the
    old clock would have it (on that clock, two vehicles of fuzzed flight 3034 seemed to
    pass 1.6 m apart at once, and the order kept no more than that). Pairs that still
    seem closer than their radii at once are ordered all the same (`order_together`;
    fuzzed flight 3499 kept only 1.66 m otherwise); a vehicle leads what its rest begins
    inside, a kept one what it would meet before it could stop (`committed_m`: metres
    from where it is), and a replanned one what it meets on its way to its new path
    (`begun_where_it_is`: it comes to rest somewhere on it, not knowing where); and its
    timing (`timed`) proves the order has no cycle."""
    cell = flight.scenario.grid.cell_size_m
    new = {
        uav: PlannedPath.of(uav, trajectory.points, cell, flight.paths[uav].radius_m)
        for uav, trajectory in changed.items()
    }
    paths = {
        uav: begun_where_it_is(path, along.get(uav, 0.0), new[uav])
        if uav in changed
        else path.after(along.get(uav, 0.0)).starting_at(now_s)
        for uav, path in flight.paths.items()
    }
    committed = {u: m for u, m in (committed_m or {}).items() if u not in changed}
    committed |= {uav: paths[uav].length - path.length for uav, path in new.items()}
    order = PassingOrder.derive(
        paths.values(),
        margin_m=2 * stray_m(flight.speed_m_s),
        order_together=True,
        committed_m=committed,
    )
    return dataclasses.replace(
        flight,
        missions={**flight.missions, **missions},
        paths=paths,
        leg_speeds=_legs(paths),
        order=order,
    )


def begun_where_it_is(old: PlannedPath, along_m: float, new: PlannedPath) -> PlannedPath:
    """A replanned vehicle's `new` path, begun where it is (`along_m` along its `old`
    one): stopped for the replan, it comes to rest somewhere on its way to where `new`
    begins, which was only foreseen (`Fleet.stopping_places`), and then flies there
    (`build_mission(airborne=True)`). Out of the order's sight on the way, it stopped 12 m
    short of it, and another vehicle was let by 5.65 m from it (fuzzed flight 7648).
    The way there is timed as flown just before `new`; `continued` has the vehicle lead
    what it meets on it."""
    here, start = np.asarray(old.position(along_m)), new.xy[0]
    s_start = along_path(old, start, after_m=along_m)
    ahead = np.hypot(*(np.asarray(old.position(s_start)) - start)) < SAME_PLACE_M
    between = (old.s > along_m) & (old.s < s_start) & ahead  # the old path's corners on it
    way = np.vstack([here, old.xy[between], start])
    legs = np.hypot(*np.diff(way, axis=0).T)
    if legs.sum() < SAME_PLACE_M:
        return new
    to_go = legs.sum() - np.concatenate([[0.0], np.cumsum(legs)])
    speed = max(float(_leg_speeds(new).max(initial=0.0)), 1e-3)
    t = new.arrive[0] - to_go / speed
    return dataclasses.replace(
        new,
        xy=np.vstack([way[:-1], new.xy]),
        arrive=np.concatenate([t[:-1], new.arrive]),
        leave=np.concatenate([t[:-1], new.leave]),
    )


def _with_landings_cleared(flight: FlightPlan, margin_m: float) -> FlightPlan:
    """The flight with its landers held short where nobody then waits out a landing
    (`landing_clearance`), timed with the same simulation the flight is timed with.
    Only before take-off: after a live replan a hold could fall right in front of a
    vehicle at speed, where it cannot stop."""

    radius = {uav: path.radius_m for uav, path in flight.paths.items()}

    def derive(paths: Mapping[str, PlannedPath]) -> PassingOrder | None:
        order = PassingOrder.derive(
            paths.values(), margin_m=margin_m, like=(flight.order, flight.paths)
        )
        return order if order.narrowest_margin_m(radius) >= margin_m - 1e-9 else None

    timed: list[FlightPlan] = []  # each one scored, its timing kept (a whole simulation)

    def score(paths: dict[str, PlannedPath], order: PassingOrder) -> tuple[float, float]:
        """A candidate whose order cannot be kept to the end scores worst (a hold may
        still free it: fuzzed flight 13783 was refused with a 500 instead)."""
        candidate = dataclasses.replace(flight, paths=paths, leg_speeds=_legs(paths), order=order)
        timed.append(candidate)
        try:
            arrivals = [t.arrival_s for t in candidate.timed.values()]
        except FlightStuck:
            return math.inf, math.inf
        return max(arrivals, default=0.0), sum(arrivals)

    paths, _ = clear_landings(flight.paths, flight.order, derive, score)
    return next((c for c in timed if c.paths is paths), flight)


def _legs(paths: Mapping[str, PlannedPath]) -> dict[str, Floats]:
    return {uav: _leg_speeds(path) for uav, path in paths.items()}


def stretched(plan: Plan, scenario: Scenario, factor: float) -> tuple[Plan, Scenario]:
    """The plan with every time multiplied by `factor`, and the scenario with speeds divided."""
    uavs = [
        u.model_copy(update={"trajectory": [[t * factor, x, y] for t, x, y in u.trajectory]})
        for u in plan.uavs
    ]
    specs = [u.model_copy(update={"speed": u.speed / factor}) for u in scenario.uavs]
    return plan.model_copy(update={"uavs": uavs}), scenario.model_copy(update={"uavs": specs})


def stopping_points(mission: Mission, path: PlannedPath, frame: GridFrame) -> Floats:
    """Where ArduCopter stops on the way: at a waypoint followed by a landing (or by a
    return home, a take-off, loiter turns), which it will not fly through (ModeAuto::
    set_next_wp), whatever the corner; in metres along `path`."""
    items = mission.items
    seqs = [
        seq
        for seq in range(takeoff_index(items) + 1, len(items))
        if items[seq].command != Command.DO_CHANGE_SPEED
    ]
    places = item_places(mission, path, frame)
    return np.array(
        [
            places[seq]
            for seq, following in itertools.pairwise(seqs)
            if items[seq].command == Command.NAV_WAYPOINT
            and items[following].command in STOPPING_NEXT
        ]
    )


def item_places(mission: Mission, path: PlannedPath, frame: GridFrame) -> dict[int, float]:
    """Metres along `path` of each NAV item after take-off that has a place, by seq. Each
    is looked for at or after the one before: a path that comes back over itself (a
    vehicle stepping aside and back) has a later item on its later pass (fuzzed flight
    3983: a resumed vehicle found on the first pass was lost there while it flew on)."""
    items = mission.items
    places: dict[int, float] = {}
    after = 0.0
    for seq in range(takeoff_index(items) + 1, len(items)):
        item = items[seq]
        if item.command == Command.NAV_RETURN_TO_LAUNCH:
            break
        if item.command in PLACED:
            after = along_path(path, frame.to_metres(item.lat, item.lon), after)
            places[seq] = after
    return places


def timed_visits(mission: Mission, timed: TimedPath, frame: GridFrame) -> list[Visit]:
    """Each NAV item after take-off with the time the timed flight gets there (no holds:
    a flight waits where the passing order says, not at a waypoint)."""
    visits = []
    for seq, s in item_places(mission, timed.path, frame).items():
        item = mission.items[seq]
        if item.command == Command.NAV_LOITER_TIME:
            continue
        at = timed.time_at(s)
        lands = item.command == Command.NAV_LAND
        visits.append(Visit(seq, at, at, item.lat, item.lon, lands))
        if lands:
            break
    return visits


def along_path(path: PlannedPath, point: Floats, after_m: float = 0.0) -> float:
    """The distance along `path`, at or after `after_m`, of its point nearest `point` (a
    mission's waypoint, in metres from the grid's origin); of near-equal ones, the first."""
    a, d = path.xy[:-1], np.diff(path.xy, axis=0)
    ahead = path.s[1:] >= after_m  # the legs that reach `after_m`
    if not ahead.any():
        return path.length
    length = np.maximum(np.hypot(*d.T), 1e-6)
    earliest = np.clip((after_m - path.s[:-1]) / length, 0.0, 1.0)
    f = np.clip(np.einsum("ij,ij->i", point - a, d) / length**2, earliest, 1.0)
    miss = np.where(ahead, np.hypot(*(point - (a + f[:, None] * d)).T), np.inf)
    k = int(np.flatnonzero(miss <= miss.min() + SAME_PLACE_M)[0])
    return float(path.s[k] + f[k] * length[k])


def _leg_speeds(path: PlannedPath) -> Floats:
    """m/s of each leg of a path on the plan's clock."""
    length: Floats = np.hypot(*np.diff(path.xy, axis=0).T)
    return length / np.maximum(path.arrive[1:] - path.leave[:-1], 1e-9)


def _stretched_path(path: PlannedPath, factor: float) -> PlannedPath:
    return PlannedPath(
        path.uav_id, path.xy, path.arrive * factor, path.leave * factor, path.radius_m
    )


def _at_cruise(limits: CopterLimits, legs: Floats, radius_m: float) -> CopterLimits:
    """A vehicle's limits with its cruise set to its fastest leg and its waypoint radius."""
    cruise = float(legs.max()) if len(legs) else limits.speed_m_s
    return dataclasses.replace(limits, speed_m_s=cruise, radius_m=radius_m)


def _refuse_if_unsafe(order: PassingOrder, radius: Mapping[str, float], speed: float) -> None:
    """Where the plan flies two UAVs within reach of each other at once, the order keeps
    only what the plan keeps; that must leave room for both to stray off their paths
    (more, the faster they fly)."""
    margin, needed = order.narrowest_margin_m(radius), 2 * stray_m(speed) - 1e-9
    if margin >= needed:
        return
    safe = highest_speed_for_stray(margin / 2)
    highest = math.floor(safe * 10) / 10 if safe is not None else None  # what is offered
    if highest is not None and highest <= 0:
        highest = None
    pairs = ", ".join(
        f"{a} and {b} ({reach - radius[a] - radius[b]:+.2f} m beyond 2R)"
        for (a, b), reach in sorted(order.reach_m.items())
        if reach - radius[a] - radius[b] < needed
    )
    advice = (
        f"the highest speed it can keep safe is {highest:g} m/s"
        if highest is not None
        else "no speed is safe: plan again with larger radii"
    )
    raise UnsafeSpeed(
        f"at {speed:g} m/s a vehicle may stray {stray_m(speed):.2f} m off its path, but the "
        f"plan flies {pairs} side by side with less room than twice that; {advice}",
        highest,
    )


def _missions(
    plan: Plan,
    scenario: Scenario,
    autopilots: Mapping[str, Autopilot],
    altitude_m: float,
    finish: Finish,
    turn_radius_m: float,
) -> dict[str, Mission]:
    missions: dict[str, Mission] = {}
    for autopilot in set(autopilots.values()):
        built = build_missions(
            plan, scenario, autopilot, altitude_m=altitude_m, finish=finish,
            acceptance_radius_m=turn_radius_m, holds=False,
        )  # fmt: skip
        missions |= {uav: m for uav, m in built.items() if autopilots[uav] == autopilot}
    return missions


def plan_trajectories(flight: FlightPlan) -> dict[str, Trajectory]:
    """The timed flight in the plan's terms (cells), for the exact check."""
    cell = flight.scenario.grid.cell_size_m
    return {uav: t.trajectory(cell) for uav, t in flight.timed.items()}
