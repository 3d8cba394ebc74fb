"""Simulated vehicles at a scenario's starts, with ArduCopter's whole boot, for `mvo-gcs fly`
(which opens its own connections to them). Fleet flights are in tests/inprocess/fleet.py."""

from __future__ import annotations

from gcs.mission.geodesy import GridFrame
from planner.model.scenario import Scenario
from sitl_mock import VehicleConfig


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
