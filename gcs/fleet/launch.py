"""Lining the fleet up and starting it together: the plan's t = 0.

Nobody arms unless every vehicle is at its planned start (a plan is only safe from the
start it was planned for). Then each vehicle takes off in GUIDED and holds at its
altitude over its start; only when all of them hold are they switched to AUTO within
one loop iteration. If one fails before that, none starts and the others do the
fallback.
"""

from __future__ import annotations

import asyncio

from gcs.fleet.crew import Crew
from gcs.fleet.events import MissionsStarted, StartCancelled, VehicleReady
from gcs.fleet.interventions import abort, fall_back
from gcs.fleet.member import Member
from gcs.fleet.outcome import VehicleOutcome
from gcs.mavlink.errors import FlightError
from gcs.mission.geodesy import distance_m


async def prepare(crew: Crew) -> dict[str, VehicleOutcome[None]]:
    """Arm, take off and hold every vehicle at its altitude over its start."""
    outcomes = await crew.each(lambda m: check_at_start(crew, m), "prepare")
    failed = tuple(uav for uav, o in outcomes.items() if not o.ok)
    if failed:
        crew.bus.publish(StartCancelled(failed, "none armed"))
        return outcomes
    outcomes = await crew.each(lambda m: _take_off(crew, m), "prepare")
    failed = tuple(uav for uav, o in outcomes.items() if not o.ok)
    crew.ready = not failed
    if failed:
        fallback = crew.settings.fallback
        crew.bus.publish(StartCancelled(failed, fallback.value))
        healthy = [uav for uav in crew.members if uav not in failed]
        await fall_back(crew, healthy, fallback)
    return outcomes


async def check_at_start(crew: Crew, member: Member) -> None:
    """The plan is safe only if every UAV starts where the plan starts it."""
    loop = asyncio.get_running_loop()
    settings = crew.settings
    deadline = loop.time() + settings.readiness.arm_timeout_s
    while (position := member.link.state.position) is None:  # no estimate yet
        if loop.time() > deadline:
            raise FlightError(f"{member.uav_id}: the vehicle reports no position")
        await asyncio.sleep(settings.tick_s)
    off = distance_m(position.lat, position.lon, *member.tracker.origin)
    if off > settings.start_tolerance_m:
        raise FlightError(
            f"{member.uav_id} is {off:.1f} m from its start "
            f"(limit {settings.start_tolerance_m} m): the plan is only safe "
            "from the start it was planned for"
        )


async def _take_off(crew: Crew, member: Member) -> None:
    await member.client.set_current(member.takeoff_seq)
    await member.actions.arm_and_take_off(member.altitude_m)
    await member.actions.wait_altitude(member.altitude_m)
    crew.bus.publish(VehicleReady(member.uav_id, member.altitude_m))


async def start(crew: Crew) -> dict[str, VehicleOutcome[None]]:
    """AUTO + MISSION_START to every vehicle within one loop iteration (plan t = 0)."""
    if not crew.ready:
        raise FlightError("the fleet is not ready: prepare() did not succeed for every vehicle")
    sent: list[float] = []
    loop = asyncio.get_running_loop()

    async def start_one(member: Member) -> None:
        member.tracker.start(member.link.state.time_boot_ms)
        sent.append(loop.time())
        await member.actions.start_mission()

    outcomes = await crew.each(start_one, "start")
    crew.started = True
    spread = (max(sent) - min(sent)) * 1000 if sent else 0.0
    crew.bus.publish(MissionsStarted(tuple(crew.members), spread, crew.flight.duration_s))
    failed = [uav for uav, o in outcomes.items() if not o.ok]
    if failed:
        await abort(crew, crew.settings.fallback.value, f"{', '.join(failed)} did not start")
    return outcomes
