"""The mock's LAND from cruise speed comes down where real ArduCopter's does
(tests/landing_at_speed.py)."""

from __future__ import annotations

import pytest

from gcs.mavlink.actions import FlightActions
from tests.landing_at_speed import assert_came_down_as_arducopter, land_mid_leg

from .conftest import CMAC, vehicle

pytestmark = [pytest.mark.virtual_clock]


async def test_landed_at_cruise_speed_the_mock_comes_down_where_arducopter_does(
    simulator, links
) -> None:
    sim = await simulator([vehicle(1)])
    link = await links(sim, 1)
    landed = await land_mid_leg(link, FlightActions(link), CMAC, bound_s=120.0)
    assert_came_down_as_arducopter(landed)
