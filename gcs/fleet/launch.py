"""Lining the fleet up and starting it together: the plan's t = 0.

Nobody arms unless every vehicle is at its planned start (a plan is only safe from the
start it was planned for). Then each vehicle takes off in GUIDED and holds at its
altitude over its start; only when all of them hold are they switched to AUTO within
one loop iteration. If one fails before that, none starts and the others do the
fallback.

"At its start" is the rule:

- within `start_tolerance_m` (3 m) of the planned start point: it takes off where it
  stands, as always;
- further, but inside its start cell (the grid cell whose centre the plan starts it
  at: a geographic scenario snaps a start, "where vehicle X is now" included, to its
  cell's centre, up to half a diagonal away, 7.1 m with 10 m cells): an ArduCopter
  takes off where it stands, then is sent to the start at its take-off altitude
  (SET_POSITION_TARGET_GLOBAL_INT in GUIDED, repeated each second: the message has no
  answer) and is ready only once within `start_hold_m` of it and holding (slower than
  `HOLDING_M_S`); a vehicle not there within `start_move_timeout_s` fails, clearly, and
  the fleet does not start;
- outside its start cell (the wrong vehicle, or a vehicle somewhere else), or off by
  more than the tolerance on PX4 (which is not flown to its start here): refused before
  anything arms.

Why the moves are safe. The plan is safe from the cell centres, and it does not begin
until every vehicle holds over its own (the synchronised start). Before that each
vehicle climbs straight up from where it stands and flies a straight line to its own
cell's centre: the whole move lies inside its own start cell (a square holds the segment
between two of its points), and the plan gives every UAV a different start cell. Cells
keep the moves apart but not by the UAVs' radii (two vehicles may stand either side of
a shared edge), so before anything arms the moves are also checked pairwise: the two
segments (a vehicle that does not move is a point) must stay at least the two radii
apart, whenever each vehicle is anywhere on its own; otherwise both are refused.
"""

from __future__ import annotations

import asyncio
import itertools
import math

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.fleet.crew import Crew
from gcs.fleet.events import (
    MissionsStarted,
    StartCancelled,
    VehicleFailed,
    VehicleReady,
    Waiting,
)
from gcs.fleet.interventions import abort, fall_back
from gcs.fleet.member import Member
from gcs.fleet.outcome import VehicleOutcome
from gcs.mavlink.errors import FlightError
from gcs.mavlink.mission_item import Autopilot
from gcs.mission.geodesy import distance_m, to_e7

HOLDING_M_S = 0.3  # "holding" over the start: ground speed below this
TARGET_EVERY_S = 1.0  # the position target again (it has no answer to wait for)
POSITION_ONLY = (
    mavlink2.POSITION_TARGET_TYPEMASK_VX_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_VY_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_VZ_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AX_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AY_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AZ_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
)


async def prepare(crew: Crew) -> dict[str, VehicleOutcome[None]]:
    """Arm, take off and hold every vehicle at its altitude over its start."""
    checked = await crew.each(lambda m: check_at_start(crew, m), "prepare")
    outcomes: dict[str, VehicleOutcome[None]] = {
        uav: VehicleOutcome(uav, o.ok, o.detail, None, o.error, o.seconds)
        for uav, o in checked.items()
    }
    failed = tuple(uav for uav, o in outcomes.items() if not o.ok)
    if not failed:
        for uav, why in crossing_moves(crew).items():
            crew.bus.publish(VehicleFailed(uav, "prepare", why))
            outcomes[uav] = VehicleOutcome(uav, False, why, None, FlightError(why))
        failed = tuple(uav for uav, o in outcomes.items() if not o.ok)
    if failed:
        crew.bus.publish(StartCancelled(failed, "none armed"))
        return outcomes
    moving = {uav for uav, o in checked.items() if o.value}
    outcomes = await crew.each(lambda m: _take_off(crew, m, m.uav_id in moving), "prepare")
    failed = tuple(uav for uav, o in outcomes.items() if not o.ok)
    crew.ready = not failed
    if failed:
        fallback = crew.settings.fallback
        crew.bus.publish(StartCancelled(failed, fallback.value))
        healthy = [uav for uav in crew.members if uav not in failed]
        await fall_back(crew, healthy, fallback)
    return outcomes


async def check_at_start(crew: Crew, member: Member) -> bool:
    """The plan is safe only if every UAV starts where the plan starts it: refused
    unless at its start by the rule above; says whether it must fly to its start."""
    loop = asyncio.get_running_loop()
    settings = crew.settings
    deadline = loop.time() + settings.readiness.arm_timeout_s
    while (position := member.link.state.position) is None:  # no estimate yet
        if loop.time() > deadline:
            raise FlightError(f"{member.uav_id}: the vehicle reports no position")
        await asyncio.sleep(settings.tick_s)
    off = distance_m(position.lat, position.lon, *member.tracker.origin)
    if off <= settings.start_tolerance_m:
        return False
    if member.link.autopilot == Autopilot.PX4:
        raise FlightError(
            f"{member.uav_id} is {off:.1f} m from its start "
            f"(limit {settings.start_tolerance_m} m on PX4): the plan is only safe "
            "from the start it was planned for"
        )
    if not in_start_cell(crew, member, position.lat, position.lon):
        cell = crew.flight.scenario.grid.cell_size_m
        raise FlightError(
            f"{member.uav_id} is {off:.1f} m from its start, outside its {cell:g} m start "
            f"cell (within {settings.start_tolerance_m} m it takes off as it stands, "
            "within its start cell it flies to its start first): the plan is only safe "
            "from the start it was planned for"
        )
    return True


def in_start_cell(crew: Crew, member: Member, lat: float, lon: float) -> bool:
    """Whether (lat, lon) lies in the grid cell of the member's planned start."""
    frame = crew.flight.frame
    sx, sy = frame.to_cells(*member.tracker.origin)
    x, y = frame.to_cells(lat, lon)
    return max(abs(float(x) - round(float(sx))), abs(float(y) - round(float(sy)))) <= 0.5


def crossing_moves(crew: Crew) -> dict[str, str]:
    """Vehicles whose moves to their starts (from where they stand; none if they do
    not move) could come closer than their two radii: uav -> why."""
    frame, cell = crew.flight.frame, crew.flight.scenario.grid.cell_size_m
    radius = {u.id: u.radius * cell for u in crew.flight.scenario.uavs}
    moves: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for uav, member in crew.members.items():
        position = member.link.state.position
        if position is None:
            continue
        here = np.array(frame.to_cells(position.lat, position.lon), dtype=float) * cell
        start = np.array(frame.to_cells(*member.tracker.origin), dtype=float) * cell
        off = float(np.hypot(*(here - start)))
        moves[uav] = (here, start if off > crew.settings.start_tolerance_m else here)
    refused: dict[str, str] = {}
    for a, b in itertools.combinations(sorted(moves), 2):
        if moves[a][0] is moves[a][1] and moves[b][0] is moves[b][1]:
            continue  # neither moves: as before, their plan's business
        gap = _segments_gap(*moves[a], *moves[b])
        need = radius.get(a, 0.0) + radius.get(b, 0.0)
        if gap < need:
            for uav, other in ((a, b), (b, a)):
                refused[uav] = (
                    f"{uav} and {other} would come {gap:.1f} m apart (less than their radii, "
                    f"{need:.1f} m) flying to their starts: move one nearer its start"
                )
    return refused


def _segments_gap(p: np.ndarray, q: np.ndarray, r: np.ndarray, s: np.ndarray) -> float:
    """The least distance between the segments pq and rs (in the plane)."""

    def point_to(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
        ab = b - a
        length = float(ab @ ab)
        t = 0.0 if length == 0 else min(max(float((x - a) @ ab) / length, 0.0), 1.0)
        return float(np.hypot(*(x - (a + t * ab))))

    def side(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
        return float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    d1, d2 = side(r, s, p), side(r, s, q)
    d3, d4 = side(p, q, r), side(p, q, s)
    if d1 * d2 < 0 and d3 * d4 < 0:
        return 0.0  # they cross
    return min(point_to(p, r, s), point_to(q, r, s), point_to(r, p, q), point_to(s, p, q))


async def _take_off(crew: Crew, member: Member, to_start: bool) -> None:
    await member.client.set_current(member.takeoff_seq)
    await member.actions.arm_and_take_off(member.altitude_m)
    await member.actions.wait_altitude(member.altitude_m)
    if to_start:
        await fly_to_start(crew, member)
    crew.bus.publish(VehicleReady(member.uav_id, member.altitude_m))


async def fly_to_start(crew: Crew, member: Member) -> None:
    """In GUIDED, to its planned start at its take-off altitude, until within
    `start_hold_m` of it and holding; a failure after `start_move_timeout_s`."""
    loop = asyncio.get_running_loop()
    settings, link = crew.settings, member.link
    lat, lon = member.tracker.origin
    lat_e7, lon_e7 = (int(v) for v in to_e7([lat, lon]))
    target = link.codec.set_position_target_global_int_encode(
        0, link.sysid, link.compid, mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, POSITION_ONLY,
        lat_e7, lon_e7, member.altitude_m, 0, 0, 0, 0, 0, 0, 0, 0,
    )  # fmt: skip
    deadline = loop.time() + settings.start_move_timeout_s
    sent = -math.inf
    while True:
        position = link.state.position
        off = math.inf if position is None else distance_m(position.lat, position.lon, lat, lon)
        if off <= settings.start_hold_m and link.state.groundspeed_m_s < HOLDING_M_S:
            return
        if loop.time() > deadline:
            raise FlightError(
                f"{member.uav_id} did not reach its start within "
                f"{settings.start_move_timeout_s:.0f} s ({off:.1f} m from it, "
                f"{settings.start_hold_m} m needed)"
            )
        if loop.time() - sent >= TARGET_EVERY_S:
            link.send(target)
            sent = loop.time()
        await asyncio.sleep(settings.tick_s)


async def start(crew: Crew) -> dict[str, VehicleOutcome[None]]:
    """AUTO + MISSION_START to every vehicle within one loop iteration (plan t = 0),
    but those the passing order stops at their start (`held_at_start`)."""
    if not crew.ready:
        raise FlightError("the fleet is not ready: prepare() did not succeed for every vehicle")
    sent: list[float] = []
    loop = asyncio.get_running_loop()
    held = held_at_start(crew)
    crew.starting = set(crew.members) - held
    crew.started = True  # the plan's t = 0: the order is kept from now (`Follower.starting`)

    async def start_one(member: Member) -> None:
        member.tracker.start(member.link.state.time_boot_ms)
        sent.append(loop.time())
        try:
            if member.uav_id not in held:
                await member.actions.start_mission()
        finally:
            crew.starting.discard(member.uav_id)

    outcomes = await crew.each(start_one, "start")
    spread = (max(sent) - min(sent)) * 1000 if sent else 0.0
    crew.bus.publish(MissionsStarted(tuple(crew.members), spread, crew.flight.duration_s))
    failed = [uav for uav, o in outcomes.items() if not o.ok]
    if failed:
        await abort(crew, crew.settings.fallback.value, f"{', '.join(failed)} did not start")
    return outcomes


def held_at_start(crew: Crew) -> set[str]:
    """The vehicles the passing order stops where they stand at the start (another must
    pass first, close ahead): they hover over their starts, out of AUTO, until the order
    lets them go (AUTO then). Sent on and paused at once, a mission speeding up from rest
    went on for metres (fuzzed flights 3522 and 3530: 2.9 m past a limit 0.8 m ahead,
    5.92 m from the vehicle it waited for)."""
    along = {uav: m.along for uav, m in crew.members.items()}
    changes = crew.gatekeeper.decide(along, list(crew.members), starting=True)
    for change in changes:
        crew.commander.held_out_of_mission(change.uav_id)
        waits = change.waits_for or ""
        crew.bus.publish(Waiting(change.uav_id, waits, change.gate.value, change.gap_m))
    return {change.uav_id for change in changes}
