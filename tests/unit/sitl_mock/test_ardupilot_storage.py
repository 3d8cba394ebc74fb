"""ArduPilot's stored form of mission items, as ArduCopter SITL returned ours on download."""

from __future__ import annotations

import math

import pytest

from sitl_mock.ardupilot_storage import refusal, stored
from sitl_mock.codec import mavlink
from sitl_mock.mission_item import MissionItem

NAN = math.nan
LAT, LON = -353632620, 1491652370


def item(
    command: int, frame: int, *params: float, z: float = 0.0, x: int = LAT, y: int = LON
) -> MissionItem:
    p1, p2, p3, p4 = (*params, *[0.0] * (4 - len(params)))
    return MissionItem(0, frame, command, p1, p2, p3, p4, x=x, y=y, z=z)


def fields(i: MissionItem) -> tuple:
    return (i.frame, i.param1, i.param2, i.param3, i.param4, i.x, i.y, i.z)


def test_our_mission_comes_back_as_sitl_returned_it():
    """The mission uploaded to ArduCopter SITL V4.8.0-dev and what its download gave."""
    takeoff = item(22, 6, 0, 0, 0, NAN, z=10.0)
    speed = item(178, 2, 1, 1.0, -1, 0, x=0, y=0)
    waypoint = item(16, 6, 1.5, 0.5, 0, NAN, z=10.123, x=-353630823)
    land = item(21, 6, 0, 0, 0, NAN, x=0, y=0)
    assert fields(stored(takeoff)) == (3, 0.0, 0.0, 0.0, 0.0, LAT, LON, 10.0)
    assert fields(stored(speed)) == (0, 1.0, 1.0, -1.0, 0.0, 0, 0, 0.0)
    assert fields(stored(waypoint)) == (3, 1.0, 0.0, 0.0, 0.0, -353630823, LON, 10.119999885559082)
    assert fields(stored(land)) == (3, 0.0, 0.0, 0.0, 1.0, 0, 0, 0.0)


def test_absolute_frames_come_back_as_global_and_do_items_lose_their_position():
    assert stored(item(16, mavlink.MAV_FRAME_GLOBAL_INT, z=500.0)).frame == 0
    assert stored(item(16, mavlink.MAV_FRAME_MISSION, z=500.0)).frame == 0
    assert stored(item(16, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=5.0)).frame == 3
    moved = stored(item(178, 6, 1, 3.0, z=7.0))
    assert (moved.frame, moved.x, moved.y, moved.z) == (0, 0, 0, 0.0)


@pytest.mark.parametrize(
    ("bad", "result"),
    [
        (item(178, 2, 1, 1.0, NAN, 0), mavlink.MAV_MISSION_INVALID_PARAM3),  # seen on SITL
        (item(16, 6, -1, 0.5, 0, NAN, z=10.0), mavlink.MAV_MISSION_INVALID_PARAM1),  # seen on SITL
        (item(16, 6, NAN, z=10.0), mavlink.MAV_MISSION_INVALID_PARAM1),
        (item(16, 6, 0, math.inf, z=10.0), mavlink.MAV_MISSION_INVALID_PARAM2),
        (item(16, 6, z=NAN), mavlink.MAV_MISSION_INVALID_PARAM7),
        (item(16, 6, z=10.0, x=91 * 10**7), mavlink.MAV_MISSION_INVALID_PARAM5_X),
        (item(16, mavlink.MAV_FRAME_LOCAL_NED, z=10.0), mavlink.MAV_MISSION_UNSUPPORTED_FRAME),
    ],
)
def test_items_ardupilot_refuses(bad: MissionItem, result: int):
    assert refusal(bad) == result


@pytest.mark.parametrize(
    "good",
    [
        item(16, 6, 0, 0, 0, NAN, z=10.0),
        item(21, 6, 0, 0, 0, NAN),
        item(22, 6, 0, 0, 0, NAN),
        item(178, 2, 1, 5.0, -1, 0),
    ],
)
def test_nan_param4_is_allowed_on_the_commands_that_may_leave_it_unset(good: MissionItem):
    assert refusal(good) is None
