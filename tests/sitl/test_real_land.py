"""Real ArduCopter's LAND from cruise speed (tests/landing_at_speed.py): the figure the
mock is held to. Run with `ARDUPILOT_SITL=/path/to/arducopter`; skipped otherwise."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs.mavlink import client
from gcs.mavlink.actions import FlightActions, ReadinessPolicy
from gcs.mavlink.commands import CommandPolicy
from gcs.mavlink.link import LinkSettings
from tests.landing_at_speed import assert_came_down_as_arducopter, land_mid_leg
from tests.sitl.ardupilot_sitl import instances

pytestmark = [pytest.mark.sitl, pytest.mark.slow, pytest.mark.timeout(900)]

HOME = (-35.363262, 149.165237, 584.0)
SPEEDUP = 5.0


async def test_real_arducopter_landed_at_cruise_speed_comes_down_where_the_mock_does(
    tmp_path: Path,
) -> None:
    with instances([HOME], tmp_path, speedup=SPEEDUP) as (instance,):
        link = await client.connect(
            instance.connection, settings=LinkSettings(connect_timeout_s=60.0)
        )
        try:
            readiness = ReadinessPolicy(arm_timeout_s=300.0, climb_timeout_s=120.0)
            actions = FlightActions(link, CommandPolicy(), readiness)
            landed = await land_mid_leg(link, actions, HOME, bound_s=300.0)
        finally:
            await link.close()
    print(f"\nLAND from cruise on real ArduCopter: {landed}")
    assert_came_down_as_arducopter(landed)
