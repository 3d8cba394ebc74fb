"""A plan's trajectories as MAVLink missions, and the schedule each mission implies.

The plan (docs/planner.md) gives each UAV `[t, x, y]` points, piecewise linear in grid
cells and seconds, starting at its start cell at t = 0; two points at one place are a
hover and legs may differ in speed. A mission reproduces that timing with three things
every autopilot honours: the ground speed (DO_CHANGE_SPEED, before the first leg and
again before any leg at another speed), the waypoints (turns, speed changes and hovers
only: collinear steps at one speed are merged) and each waypoint's hold time.

t = 0 of the plan is the moment the mission leaves NAV_TAKEOFF, every vehicle hovering
at its altitude over its start cell (the fleet lines them up there). `fly_ideally`
flies a mission with instant speed changes and exact holds; `mission_schedule` is the
time it reaches each item, which the fleet compares with the vehicle's progress.

Waits are the waypoint's hold time (NAV_WAYPOINT param1), not NAV_LOITER_TIME: one item
per turning point, so MISSION_ITEM_REACHED for a waypoint means "arrived here", and
both autopilots read param1 as seconds to hover. PX4 takes a float; ArduCopter keeps
whole seconds, so for it each hold is rounded and the leg after it flown in the time
left (`Route.whole_second_holds`): arrivals stay as planned, and only that leg is flown
up to half a second (at most one) early or late.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from gcs.mavlink.mission_item import Autopilot, Command, Frame, Mission, MissionItem
from gcs.mission.geodesy import Floats, GridFrame, local_metres, to_e7
from planner.model.plan import Plan
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory, merge_collinear

DEFAULT_ALTITUDE_M = 20.0
"""Flight altitude above home: clear of trees and roofs, low enough for 10 m cells to matter."""
SPEED_RTOL = 1e-4
"""Leg speeds closer than this (relative) are one speed: plan times carry 6 decimals."""
MOVE_EPS_CELLS = 1e-9
"""Consecutive plan points closer than this are one place (a hover)."""

Finish = Literal["land", "rtl"]
_NAN = float("nan")
_STOPS = {Command.NAV_WAYPOINT, Command.NAV_LOITER_TIME, Command.NAV_LAND}


@dataclass(frozen=True)
class Route:
    """The places a mission visits: start, turns, speed changes, hovers and the end.

    The UAV leaves place k at `arrive[k] + hold[k]` and flies straight to place k + 1
    at a constant speed, reaching it at `arrive[k + 1]`; the plan's times are kept.
    """

    xy: Floats  # (k, 2) cells
    arrive: Floats  # (k,) plan seconds
    hold: Floats  # (k,) seconds hovering on arrival

    def __len__(self) -> int:
        return len(self.xy)

    @property
    def speeds(self) -> Floats:
        """Cells per second of each leg, shape (k - 1,)."""
        length: Floats = np.hypot(*np.diff(self.xy, axis=0).T)
        return length / (self.arrive[1:] - self.arrive[:-1] - self.hold[:-1])

    def without_holds(self) -> Route:
        """The same path, every leg at its own speed and no hover on the way: for a
        flight that keeps the plan's passing order rather than its clock, where a plan's
        wait is the passing order's to make, not a slower leg's. Places where it hovered
        on a straight line go too: ArduCopter plans only the leg after the next waypoint,
        so waypoints 1 m apart held it to about 1.7 m/s on real SITL."""
        moving = np.diff(self.arrive) - self.hold[:-1]
        arrive = np.concatenate([[self.arrive[0]], moving]).cumsum()
        return Route(self.xy, arrive, 0 * self.hold)._merged()

    def whole_second_holds(self) -> Route:
        """The route for an autopilot that holds for whole seconds only (ArduCopter keeps
        NAV_WAYPOINT's hold as an integer): each hold rounded to the nearest second, the
        leg after it flown in the time left, so every later arrival stays as planned.
        A hold is rounded down instead where rounding up would make its leg faster than
        the fastest leg of the route (the pace the flight was slowed to); the error is then
        at most one second of the leg's speed, on that leg only."""
        if len(self) == 1:
            return Route(self.xy, self.arrive, np.rint(self.hold))
        nearest, down = np.rint(self.hold), np.floor(self.hold + 1e-9)
        legs = np.hypot(*np.diff(self.xy, axis=0).T)
        left = self.arrive[1:] - self.arrive[:-1] - nearest[:-1]
        fastest = float(np.max(self.speeds))
        too_fast = (left <= 0) | (legs > fastest * (1 + SPEED_RTOL) * np.maximum(left, 1e-12))
        hold = nearest.copy()
        hold[:-1] = np.where(too_fast, down[:-1], nearest[:-1])
        return Route(self.xy, self.arrive, hold)

    @classmethod
    def of(cls, trajectory: ArrayLike) -> Route:
        """The route of a plan trajectory, `[t, x, y]` rows."""
        return cls._stops(np.asarray(trajectory, dtype=float).reshape(-1, 3))._merged()

    def _merged(self) -> Route:
        """Collinear places flown at one speed without a hover between them are one leg."""
        if len(self) == 1:
            return self
        speed = self.speeds
        hover_or_new_speed = (self.hold[1:-1] > 0) | ~np.isclose(
            speed[:-1], speed[1:], rtol=SPEED_RTOL, atol=0.0
        )
        breaks = np.concatenate([[0], np.flatnonzero(hover_or_new_speed) + 1, [len(self) - 1]])
        runs = [self._merged_run(a, b) for a, b in itertools.pairwise(breaks)]
        return Route(
            np.concatenate([self.xy[:1], *(r.xy[1:] for r in runs)]),
            np.concatenate([self.arrive[:1], *(r.arrive[1:] for r in runs)]),
            np.concatenate([self.hold[:1], *(r.hold[1:] for r in runs)]),
        )

    @classmethod
    def _stops(cls, points: Floats) -> Route:
        """Every place of the trajectory once, repeated points folded into a hold."""
        if len(points) == 0:
            raise ValueError("a trajectory needs at least one [t, x, y] point")
        t, xy = points[:, 0], points[:, 1:]
        if np.any(np.diff(t) < 0):
            raise ValueError("trajectory times must not decrease")
        moved = np.hypot(*np.diff(xy, axis=0).T) > MOVE_EPS_CELLS
        first = np.flatnonzero(np.concatenate([[True], moved]))
        last = np.concatenate([first[1:] - 1, [len(points) - 1]])
        stops = cls(xy[first], t[first], t[last] - t[first])
        if len(stops) > 1 and np.any(stops.arrive[1:] - stops.arrive[:-1] - stops.hold[:-1] <= 0):
            raise ValueError("trajectory moves in zero time: no speed can fly it")
        return stops

    def _merged_run(self, a: int, b: int) -> Route:
        """Places a..b flown at one speed: collinear places dropped, times by distance."""
        xy = merge_collinear(self.xy[a : b + 1])
        along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
        leave = self.arrive[a] + self.hold[a]
        arrive = leave + (self.arrive[b] - leave) * along / along[-1]
        arrive[0] = self.arrive[a]
        hold = np.zeros(len(xy))
        hold[0], hold[-1] = self.hold[a], self.hold[b]
        return Route(xy, arrive, hold)


def build_missions(
    plan: Plan,
    scenario: Scenario,
    autopilot: Autopilot = Autopilot.ARDUPILOT,
    *,
    altitude_m: float | Mapping[str, float] = DEFAULT_ALTITUDE_M,
    finish: Finish = "land",
    acceptance_radius_m: float | None = None,
    allow_infeasible: bool = False,
    holds: bool = True,
) -> dict[str, Mission]:
    """One mission per UAV of the plan, keyed by UAV id.

    `altitude_m` is metres above home, one for all or one per UAV id. An infeasible plan
    is refused unless `allow_infeasible` (e.g. to export it for inspection). Without
    `holds`, the plan's waits are left out and every leg is flown at its own speed (the
    ground station's passing order makes the vehicle wait where, and as long as, another
    is in its way).
    """
    if not plan.feasible and not allow_infeasible:
        raise ValueError(f"plan of {plan.scenario!r} is infeasible: it is not safe to fly")
    frame = GridFrame.of(scenario)
    specs = {u.id: u for u in scenario.uavs}
    unknown = [u.id for u in plan.uavs if u.id not in specs]
    if unknown:
        raise ValueError(f"plan UAVs {unknown} are not in scenario {scenario.name!r}")
    return {
        u.id: build_mission(
            u.trajectory,
            specs[u.id].speed,
            frame,
            autopilot,
            altitude_m=altitude_m if isinstance(altitude_m, int | float) else altitude_m[u.id],
            finish=finish,
            acceptance_radius_m=acceptance_radius_m,
            holds=holds,
        )
        for u in plan.uavs
    }


def build_mission(
    trajectory: ArrayLike,
    speed: float,
    frame: GridFrame,
    autopilot: Autopilot = Autopilot.ARDUPILOT,
    *,
    altitude_m: float = DEFAULT_ALTITUDE_M,
    finish: Finish = "land",
    acceptance_radius_m: float | None = None,
    holds: bool = True,
    airborne: bool = False,
) -> Mission:
    """The mission flying one plan trajectory; `speed` is the UAV's cruise speed in cells/s.

    Items: [home (ArduPilot only)], NAV_TAKEOFF, DO_CHANGE_SPEED, then a NAV_WAYPOINT per
    route place (a DO_CHANGE_SPEED before any leg at another speed), then NAV_LAND at the
    last place or, with `finish="rtl"`, NAV_RETURN_TO_LAUNCH after it. `airborne`: for a
    vehicle already flying (a live replan), the first place is a waypoint too, flown to
    from wherever the vehicle is (a NAV_TAKEOFF in the air is done at once, and the
    vehicle went straight for the next place: fuzzed flight 7648, from 12 m short of
    where the new path began, into another's way).
    """
    if altitude_m <= 0:
        raise ValueError(f"altitude_m must be positive, got {altitude_m}")
    if acceptance_radius_m is not None and acceptance_radius_m < 0:
        raise ValueError(f"acceptance_radius_m must not be negative, got {acceptance_radius_m}")
    route = Route.of(trajectory)
    if not holds:
        route = route.without_holds()
    elif autopilot == Autopilot.ARDUPILOT:
        route = route.whole_second_holds()
    lat, lon = frame.to_geodetic(route.xy[:, 0], route.xy[:, 1])
    x, y = to_e7(lat), to_e7(lon)
    radius = acceptance_radius_m or 0.0  # 0: the autopilot's default radius
    cruise = speed * frame.cell_size_m
    items = [_takeoff(x[0], y[0], altitude_m), _change_speed(cruise)]
    if route.hold[0] > 0 or airborne:
        items.append(_waypoint(x[0], y[0], altitude_m, route.hold[0], radius))
    for k, leg_speed in enumerate(route.speeds * frame.cell_size_m, start=1):
        if not math.isclose(leg_speed, cruise, rel_tol=SPEED_RTOL):
            items.append(_change_speed(leg_speed))
            cruise = leg_speed
        items.append(_waypoint(x[k], y[k], altitude_m, route.hold[k], radius))
    items = _finished(items, x[-1], y[-1], finish)
    home = (float(lat[0]), float(lon[0]), frame.alt0)
    if autopilot == Autopilot.ARDUPILOT:
        items.insert(0, _home(x[0], y[0], frame.alt0))
    return Mission(tuple(items), autopilot, home)


def _finished(items: list[MissionItem], x: int, y: int, finish: Finish) -> list[MissionItem]:
    """End with a landing at the last place (instead of its waypoint when there is no hold)."""
    if finish == "rtl":
        return [*items, MissionItem(Command.NAV_RETURN_TO_LAUNCH, Frame.MISSION)]
    if finish != "land":
        raise ValueError(f"finish must be 'land' or 'rtl', got {finish!r}")
    last = items[-1]
    if last.command == Command.NAV_WAYPOINT and last.params[0] == 0 and (last.x, last.y) == (x, y):
        items = items[:-1]
    return [*items, MissionItem(Command.NAV_LAND, params=(0.0, 0.0, 0.0, _NAN), x=x, y=y)]


def _home(x: int, y: int, amsl: float) -> MissionItem:
    """ArduPilot's item 0, as QGC writes it: frame GLOBAL, altitude AMSL."""
    return MissionItem(Command.NAV_WAYPOINT, Frame.GLOBAL, x=int(x), y=int(y), z=float(amsl))


def _takeoff(x: int, y: int, altitude_m: float) -> MissionItem:
    return MissionItem(
        Command.NAV_TAKEOFF, params=(0.0, 0.0, 0.0, _NAN), x=int(x), y=int(y), z=altitude_m
    )


def _change_speed(metres_per_second: float) -> MissionItem:
    """Ground speed (param1 = 1); throttle -1 = unchanged."""
    return MissionItem(
        Command.DO_CHANGE_SPEED, Frame.MISSION, params=(1.0, float(metres_per_second), -1.0, 0.0)
    )


def _waypoint(x: int, y: int, altitude_m: float, hold_s: float, radius_m: float) -> MissionItem:
    """Yaw NaN: keep the autopilot's yaw behaviour (0 would point PX4 north)."""
    return MissionItem(
        Command.NAV_WAYPOINT,
        params=(float(hold_s), radius_m, 0.0, _NAN),
        x=int(x),
        y=int(y),
        z=altitude_m,
    )


@dataclass(frozen=True, slots=True)
class Visit:
    """One NAV item reached on an ideal flight; times in plan seconds."""

    seq: int  # the item's index in the mission, as MISSION_ITEM_REACHED reports it
    arrive: float
    leave: float  # arrive + hold
    lat: float
    lon: float
    lands: bool = False  # NAV_LAND: the flight ends here, on the ground

    def shifted(self, seconds: float) -> Visit:
        """The same visit `seconds` later on the plan's clock."""
        return replace(self, arrive=self.arrive + seconds, leave=self.leave + seconds)


def fly_ideally(mission: Mission) -> list[Visit]:
    """The NAV items after take-off as a vehicle with instant speed changes would reach them.

    t = 0 when it leaves NAV_TAKEOFF over the take-off point. Legs are straight lines in
    the east-north plane at home's altitude, flown at the last DO_CHANGE_SPEED's param2;
    a waypoint or NAV_LOITER_TIME holds param1 seconds. The flight ends at NAV_LAND
    (reached when over its position, before descending) or before NAV_RETURN_TO_LAUNCH,
    whose timing is the autopilot's, not the plan's.
    """
    items = mission.items
    start = takeoff_index(items)
    lat = np.array([item.lat for item in items])
    lon = np.array([item.lon for item in items])
    ground = mission.home[2] if mission.home else 0.0
    metres = local_metres(lat, lon, lat[start], lon[start], ground)
    here, t, speed = metres[start], 0.0, None
    visits: list[Visit] = []
    for seq in range(start + 1, len(items)):
        item = items[seq]
        if item.command == Command.DO_CHANGE_SPEED and item.params[1] > 0:
            speed = item.params[1]
        if item.command == Command.NAV_RETURN_TO_LAUNCH:
            break
        if item.command not in _STOPS:
            continue
        distance = float(np.hypot(*(metres[seq] - here)))
        if distance > 0:
            if speed is None:
                raise ValueError(f"item {seq} moves before any DO_CHANGE_SPEED sets a speed")
            t += distance / speed
        hold = item.params[0] if item.command != Command.NAV_LAND else 0.0
        lands = item.command == Command.NAV_LAND
        visits.append(Visit(seq, t, t + hold, item.lat, item.lon, lands))
        here, t = metres[seq], t + hold
        if item.command == Command.NAV_LAND:
            break
    return visits


def mission_schedule(mission: Mission) -> dict[int, float]:
    """Item seq → plan time at which the vehicle should reach it (NAV items after take-off)."""
    return {visit.seq: visit.arrive for visit in fly_ideally(mission)}


def flown_trajectory(mission: Mission, frame: GridFrame) -> Trajectory:
    """The ideal flight back in the plan's terms: `[t, x, y]` in cells from t = 0."""
    takeoff = mission.items[takeoff_index(mission.items)]
    visits = fly_ideally(mission)
    rows = [(0.0, takeoff.lat, takeoff.lon)]
    for v in visits:
        rows.append((v.arrive, v.lat, v.lon))
        if v.leave > v.arrive:
            rows.append((v.leave, v.lat, v.lon))
    t, lat, lon = np.array(rows).T
    x, y = frame.to_cells(lat, lon)
    return Trajectory(np.column_stack([t, x, y]))


def takeoff_index(items: tuple[MissionItem, ...]) -> int:
    for seq, item in enumerate(items):
        if item.command == Command.NAV_TAKEOFF:
            return seq
    raise ValueError("the mission has no NAV_TAKEOFF: plan time 0 is undefined")


def first_leg_index(items: tuple[MissionItem, ...]) -> int:
    """The item the first leg flies to: the first after NAV_TAKEOFF but DO_CHANGE_SPEED."""
    after = takeoff_index(items) + 1
    return next(
        (seq for seq in range(after, len(items)) if items[seq].command != Command.DO_CHANGE_SPEED),
        after,
    )
