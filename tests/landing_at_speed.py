"""LAND from cruise speed: where a vehicle told to land mid-leg comes down. Shared by the
mock's test (tests/integration/test_land_at_speed.py) and real ArduCopter's
(tests/sitl/test_real_land.py), which hold both to the same figure.

ArduCopter's LAND shapes the horizontal velocity to zero in a straight line at WP_ACC
with the position controller's jerk (PSC_JERK_NE, 5 m/s^3; `Mode::
land_run_horizontal_control`). The mock once stopped with the waypoints' jerk (WP_JERK,
1 m/s^3) and came down 40 % further on: past path ends and corners, into the way of
vehicles the passing order had waiting (fuzzed flights 11531 and 11767, 5.82 m and
5.63 m apart with 2R 6 m), which real ArduCopter does not do.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymap3d
import pytest

from gcs.mavlink.actions import FlightActions
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Autopilot, Command, Frame, Mission, MissionItem
from gcs.mavlink.mission_protocol import MissionClient

ALT_M = 10.0
SPEED_M_S = 10.0
LEG_M = 300.0
LAND_AT_M = 150.0  # east of home: at cruise speed by then
CAME_DOWN_M = 23.0
"""How far on from where it was told to land real ArduCopter came down from 10 m/s
(4.8.0-dev SITL, 2026-12-06: 23.01 m from 9.97 m/s). The mock once came down 32.7 m on."""


@dataclass(frozen=True)
class Landing:
    speed_m_s: float  # when told to land
    came_down_m: float  # from there to where it touched down
    aside_m: float  # the furthest it strayed sideways from its leg


def mission_east(home: tuple[float, float, float]) -> Mission:
    """Take off at `home`, fly LEG_M east at SPEED_M_S and land there."""

    def at(east: float) -> tuple[int, int]:
        lat, lon, _ = pymap3d.enu2geodetic(east, 0.0, 0.0, home[0], home[1], 0.0)
        return round(float(lat) * 1e7), round(float(lon) * 1e7)

    (x0, y0), (x1, y1) = at(0.0), at(LEG_M)
    items = (
        MissionItem(Command.NAV_WAYPOINT, Frame.GLOBAL, x=x0, y=y0, z=home[2]),
        MissionItem(Command.NAV_TAKEOFF, z=ALT_M, x=x0, y=y0),
        MissionItem(Command.DO_CHANGE_SPEED, Frame.MISSION, params=(1, SPEED_M_S, -1, 0)),
        MissionItem(Command.NAV_WAYPOINT, x=x1, y=y1, z=ALT_M),
        MissionItem(Command.NAV_LAND, x=x1, y=y1),
    )
    return Mission(items, Autopilot.ARDUPILOT, home)


async def land_mid_leg(
    link: VehicleLink, actions: FlightActions, home: tuple[float, float, float], bound_s: float
) -> Landing:
    """Fly `mission_east` and switch to LAND LAND_AT_M east of home; where the vehicle
    says it was (east, north of `home`) from then until it disarmed."""

    def here() -> np.ndarray:
        position = link.state.position
        assert position is not None
        east, north, _ = pymap3d.geodetic2enu(position.lat, position.lon, 0.0, *home[:2], 0.0)
        return np.array([float(east), float(north)])

    await MissionClient(link).upload(mission_east(home))
    await actions.arm_and_take_off(ALT_M)
    await actions.wait_altitude(ALT_M)
    await actions.start_mission()
    await link.wait_for("GLOBAL_POSITION_INT", lambda _: here()[0] > LAND_AT_M, bound_s)
    speed, told = float(np.hypot(*link.state.velocity_n_e_m_s)), here()
    await actions.land()
    aside = 0.0
    while link.state.armed:
        await link.wait_for("GLOBAL_POSITION_INT", None, bound_s)
        aside = max(aside, abs(float(here()[1])))
    return Landing(speed, float(np.hypot(*(here() - told))), aside)


def assert_came_down_as_arducopter(landed: Landing) -> None:
    """Landed from cruise, it came down straight on, CAME_DOWN_M on (within a tenth)."""
    assert landed.speed_m_s == pytest.approx(SPEED_M_S, abs=0.3), landed
    assert landed.came_down_m == pytest.approx(CAME_DOWN_M, rel=0.1), landed
    assert landed.aside_m < 0.5, landed
