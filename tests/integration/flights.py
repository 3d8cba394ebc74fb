"""Flying a planned scenario on simulated vehicles, for the fleet tests."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass

from gcs.fleet.fleet import Fleet, FleetSettings, FlightReport
from gcs.mavlink import client
from gcs.mavlink.link import LinkSettings
from gcs.mavlink.mission_item import Autopilot
from gcs.mission.geodesy import GridFrame, distance_m
from gcs.mission.pacing import DEFAULT_MAX_SPEED_M_S, paced_flight
from planner.plan import Plan
from planner.scenario import Scenario
from sitl_mock import Simulator, VehicleConfig

ALTITUDE_M = 10.0
GOAL_RADIUS_M = 2.0  # ArduCopter's default WP_RADIUS_M


@dataclass(frozen=True)
class FlownCase:
    report: FlightReport
    sim_min_separation_m: float
    two_r_m: float
    plan_min_separation_m: float
    goal_misses_m: dict[str, float]


def vehicles_at_starts(scenario: Scenario, autopilot: str = "ardupilot") -> list[VehicleConfig]:
    """One simulated vehicle per UAV, its home on the UAV's start cell."""
    frame = GridFrame.of(scenario)
    configs = []
    for k, uav in enumerate(scenario.uavs, start=1):
        lat, lon = frame.to_geodetic(*uav.start)
        configs.append(
            VehicleConfig(sysid=k, home=(float(lat), float(lon), frame.alt0), autopilot=autopilot)
        )
    return configs


async def fly_plan(
    sim: Simulator,
    scenario: Scenario,
    plan: Plan,
    autopilot: Autopilot = Autopilot.ARDUPILOT,
    settings: FleetSettings | None = None,
    max_speed_m_s: float = DEFAULT_MAX_SPEED_M_S,
) -> FlownCase:
    """Upload, start and follow the plan on `sim` (vehicle k flies UAV k)."""
    autopilots = {u.id: autopilot for u in scenario.uavs}
    missions = paced_flight(
        plan, scenario, autopilots, altitude_m=ALTITUDE_M, max_speed_m_s=max_speed_m_s
    ).missions
    links = await asyncio.gather(
        *(
            client.connect(sim.connection_string(k), settings=LinkSettings(connect_timeout_s=5))
            for k in range(1, len(scenario.uavs) + 1)
        )
    )
    try:
        by_uav = {uav.id: link for uav, link in zip(scenario.uavs, links, strict=True)}
        report = await Fleet(by_uav, missions, settings=settings).fly()
    finally:
        await asyncio.gather(*(link.close() for link in links))
    separation = sim.min_separation()
    cell = scenario.grid.cell_size_m
    return FlownCase(
        report,
        separation.distance_m if separation else float("inf"),
        2 * max(u.radius for u in scenario.uavs) * cell,
        (plan.metrics.min_separation or float("inf")) * cell,
        _goal_misses(sim, scenario),
    )


def _goal_misses(sim: Simulator, scenario: Scenario) -> dict[str, float]:
    frame = GridFrame.of(scenario)
    misses = {}
    for k, uav in enumerate(scenario.uavs, start=1):
        final = sim.final_position(k)
        lat, lon = frame.to_geodetic(*uav.goal)
        misses[uav.id] = distance_m(final.lat, final.lon, float(lat), float(lon))
    return misses
