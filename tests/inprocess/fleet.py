"""Flying a planned scenario with the ground station's `Fleet` on simulated vehicles in
memory, on the test's virtual clock (tests marked `virtual_clock`): the vehicles and the
ground station share one clock, so a flight takes seconds and a seed replays exactly."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass

from gcs.fleet.events import FleetEvent
from gcs.fleet.fleet import Fleet, FleetSettings, FlightReport
from gcs.mavlink import client
from gcs.mavlink.link import LinkSettings, VehicleLink
from gcs.mavlink.mission_item import Autopilot
from gcs.mission.flight_plan import flight_plan
from gcs.mission.geodesy import GridFrame, distance_m
from gcs.mission.motion import DEFAULT_SPEED_M_S
from planner.model.plan import Plan
from planner.model.scenario import Scenario
from sitl_mock import Simulator
from tests.inprocess.vehicles import SimulatedVehicles

ALTITUDE_M = 10.0
GOAL_RADIUS_M = 2.0  # ArduCopter's default WP_RADIUS_M


@dataclass(frozen=True)
class FlownCase:
    report: FlightReport
    sim_min_separation_m: float
    two_r_m: float
    plan_min_separation_m: float
    goal_misses_m: dict[str, float]


async def connect_all(
    vehicles: SimulatedVehicles, sim: Simulator, settings: LinkSettings | None = None
) -> list[VehicleLink]:
    """A link to each of `sim`'s vehicles, in sysid order, over in-memory ports."""
    return list(
        await asyncio.gather(
            *(
                client.connect(
                    sim.connection_string(k),
                    settings=settings or LinkSettings(connect_timeout_s=5),
                    opener=vehicles.open,
                )
                for k in sim.sysids
            )
        )
    )


async def fly_plan(
    vehicles: SimulatedVehicles,
    sim: Simulator,
    scenario: Scenario,
    plan: Plan,
    autopilot: Autopilot = Autopilot.ARDUPILOT,
    settings: FleetSettings | None = None,
    max_speed_m_s: float = DEFAULT_SPEED_M_S,
    altitude_m: float = ALTITUDE_M,
    record: Callable[[FleetEvent], None] | None = None,
) -> FlownCase:
    """Upload, start and follow the plan on `sim` (vehicle k flies UAV k); `record` is
    handed every event of the flight."""
    autopilots = {u.id: autopilot for u in scenario.uavs}
    flight = flight_plan(
        plan, scenario, autopilots, altitude_m=altitude_m, max_speed_m_s=max_speed_m_s
    )
    links = await connect_all(vehicles, sim)
    try:
        by_uav = {uav.id: link for uav, link in zip(scenario.uavs, links, strict=True)}
        fleet = Fleet(by_uav, flight, settings=settings)
        if record is not None:
            fleet.record(record)
        report = await fleet.fly()
    finally:
        await asyncio.gather(*(link.close() for link in links))
    separation = sim.min_separation()
    cell = scenario.grid.cell_size_m
    return FlownCase(
        report,
        separation.distance_m if separation else float("inf"),
        2 * max(u.radius for u in scenario.uavs) * cell,
        (plan.metrics.min_separation or float("inf")) * cell,
        goal_misses(sim, scenario),
    )


def goal_misses(sim: Simulator, scenario: Scenario) -> dict[str, float]:
    """How far each vehicle came down from its UAV's goal, in metres."""
    frame = GridFrame.of(scenario)
    misses = {}
    for k, uav in enumerate(scenario.uavs, start=1):
        final = sim.final_position(k)
        assert final is not None, f"vehicle {k} has no track"
        lat, lon = frame.to_geodetic(*uav.goal)
        misses[uav.id] = distance_m(final.lat, final.lon, float(lat), float(lon))
    return misses
