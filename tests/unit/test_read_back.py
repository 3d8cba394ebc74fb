"""The read-back check accepts what ArduPilot rebuilds and still catches a real change.

The stored forms are the ones ArduCopter SITL 4.8.0-dev returned for these very items
(docs/sitl_mock.md, "Seen on the real vehicle").
"""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink import ardupilot
from gcs.mavlink.mission_item import Autopilot, Command, Frame, Mission, MissionItem
from gcs.mavlink.mission_protocol import first_mismatch

NAN = math.nan
LAT, LON = -353632620, 1491652370
HOME = MissionItem(Command.NAV_WAYPOINT, Frame.GLOBAL, x=LAT, y=LON, z=584.0)
SENT = (
    HOME,
    MissionItem(Command.NAV_TAKEOFF, params=(0, 0, 0, NAN), x=LAT, y=LON, z=20.0),
    MissionItem(Command.DO_CHANGE_SPEED, Frame.MISSION, params=(1, 1.0, -1, 0)),
    MissionItem(Command.NAV_WAYPOINT, params=(2.0, 0.5, 0, NAN), x=LAT + 900, y=LON, z=20.0),
    MissionItem(Command.NAV_LAND, params=(0, 0, 0, NAN), x=LAT + 900, y=LON + 900, z=0.0),
)
STORED = (  # what the download returned
    replace(HOME, z=584.03),
    MissionItem(Command.NAV_TAKEOFF, Frame.GLOBAL_RELATIVE_ALT, (0, 0, 0, 0), LAT, LON, 20.0),
    MissionItem(Command.DO_CHANGE_SPEED, Frame.GLOBAL, (1, 1.0, -1, 0), 0, 0, 0.0),
    MissionItem(
        Command.NAV_WAYPOINT, Frame.GLOBAL_RELATIVE_ALT, (2, 0, 0, 0), LAT + 900, LON, 20.0
    ),
    MissionItem(Command.NAV_LAND, Frame.GLOBAL_RELATIVE_ALT, (0, 0, 0, 1), LAT + 900, LON + 900),
)


def mission(items: tuple[MissionItem, ...]) -> Mission:
    return Mission(items, Autopilot.ARDUPILOT)


def test_what_arducopter_rebuilds_is_the_mission_we_sent() -> None:
    assert first_mismatch(mission(SENT), STORED) is None


def test_a_literal_comparison_would_have_refused_it() -> None:
    """The bug this check fixes: every upload to real ArduCopter 'failed' verification."""
    assert mission(SENT).first_differing(STORED) == 1


@pytest.mark.parametrize(
    ("seq", "change"),
    [
        (3, {"x": LAT + 901}),  # a waypoint 1.1 cm north
        (3, {"z": 20.5}),  # another altitude
        (3, {"params": (3, 0, 0, 0)}),  # another hold time
        (2, {"params": (1, 2.0, -1, 0)}),  # another speed
        (4, {"command": Command.NAV_RETURN_TO_LAUNCH}),  # another command
        (1, {"frame": Frame.GLOBAL}),  # an absolute altitude where we meant relative
    ],
)
def test_a_real_difference_is_still_caught(seq: int, change: dict) -> None:
    stored = list(STORED)
    stored[seq] = replace(stored[seq], **change)
    assert first_mismatch(mission(SENT), tuple(stored)) == seq


def test_a_missing_item_is_caught() -> None:
    assert first_mismatch(mission(SENT), STORED[:-1]) == len(STORED) - 1


def test_altitudes_are_compared_at_the_centimetre_arducopter_keeps() -> None:
    assert ardupilot.same_stored(SENT[3], replace(STORED[3], z=20.0 - 0.0099))
    assert not ardupilot.same_stored(SENT[3], replace(STORED[3], z=20.0 - 0.02))


def test_the_acceptance_radius_goes_to_a_parameter() -> None:
    assert ardupilot.acceptance_radius_m(mission(SENT)) == pytest.approx(0.5)
    no_radius = replace(SENT[3], params=(2.0, 0.0, 0, NAN))
    assert ardupilot.acceptance_radius_m(mission((*SENT[:3], no_radius, SENT[4]))) is None
    names = [name for name, _ in ardupilot.RADIUS_PARAMETERS]
    assert names == ["WP_RADIUS_M", "WPNAV_RADIUS"]  # 4.8's metres first, then 4.6's cm


def test_px4_keeps_items_as_sent() -> None:
    px4 = Mission(SENT[1:], Autopilot.PX4)
    assert first_mismatch(px4, SENT[1:]) is None
    assert first_mismatch(px4, STORED[1:]) == 0  # PX4 would not rebuild them: a change
    assert mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT == Frame.GLOBAL_RELATIVE_ALT_INT
