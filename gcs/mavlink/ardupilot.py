"""What ArduPilot (Copter) does to a mission it stores, and what must then be set aside.

ArduPilot does not keep the MISSION_ITEM_INT it was sent: it packs each item into a
small command and rebuilds an item from that on download (`AP_Mission::
mavlink_int_to_mission_cmd` and `mission_cmd_to_mavlink_int`). Seen on ArduCopter SITL
(4.8.0-dev): frame 6 comes back 3 and DO items come back in frame 0 with no position;
a NaN parameter comes back 0 (NAV_LAND's param4: 1); NAV_WAYPOINT keeps only its hold
time, in whole seconds (the acceptance radius is Copter's WPNAV_RADIUS parameter);
altitudes are kept in whole centimetres; the rest travels as float32.

`expected(item)` is the item as ArduPilot will give it back; the read-back check
compares that with what was downloaded, so it accepts what the autopilot legitimately
rebuilds and still catches a wrong waypoint, a missing item or a changed command.
`mission_parameters` says which parameters must carry what the items cannot.
"""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.mission_item import Mission, MissionItem

UINT16_MAX = 0xFFFF
ALTITUDE_RESOLUTION_M = 0.011  # whole centimetres, cut rather than rounded, then float32
RELATIVE = frozenset(
    {mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT}
)
ABSOLUTE = frozenset({mavlink2.MAV_FRAME_GLOBAL, mavlink2.MAV_FRAME_GLOBAL_INT})
POSITIONED = frozenset(
    {
        mavlink2.MAV_CMD_NAV_WAYPOINT,
        mavlink2.MAV_CMD_NAV_LOITER_UNLIM,
        mavlink2.MAV_CMD_NAV_LOITER_TIME,
        mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH,
        mavlink2.MAV_CMD_NAV_LAND,
        mavlink2.MAV_CMD_NAV_TAKEOFF,
    }
)
KEPT_PARAMS: dict[int, tuple[bool, bool, bool, bool]] = {
    mavlink2.MAV_CMD_NAV_WAYPOINT: (True, False, False, False),
    mavlink2.MAV_CMD_NAV_TAKEOFF: (True, False, False, False),
    mavlink2.MAV_CMD_NAV_LAND: (True, False, False, True),
    mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH: (False, False, False, False),
    mavlink2.MAV_CMD_DO_CHANGE_SPEED: (True, True, True, False),
}
"""Which of param1..4 ArduPilot keeps, per command (the others come back 0)."""
WHOLE_SECONDS = frozenset({mavlink2.MAV_CMD_NAV_WAYPOINT, mavlink2.MAV_CMD_NAV_LOITER_TIME})


def expected(item: MissionItem) -> MissionItem:
    """The item as a download from ArduPilot returns it (position aside: `same_stored`)."""
    kept = KEPT_PARAMS.get(item.command, (True, True, True, True))
    params = tuple(
        _stored_param(item.command, k, value) if keep else 0.0
        for k, (value, keep) in enumerate(zip(item.params, kept, strict=True))
    )
    return MissionItem(
        item.command,
        item.frame,
        (params[0], params[1], params[2], params[3]),
        item.x,
        item.y,
        item.z,
        item.autocontinue,
    )


def same_stored(sent: MissionItem, read: MissionItem) -> bool:
    """Whether `read` is what ArduPilot returns for having stored `sent`."""
    want = expected(sent)
    if int(want.command) != int(read.command):
        return False
    if not all(_same_f32(a, b) for a, b in zip(want.params, read.params, strict=True)):
        return False
    if sent.command not in POSITIONED:
        return True  # DO items come back in frame 0 with no position
    return (
        _frame_class(sent.frame) == _frame_class(read.frame)
        and (sent.x, sent.y) == (read.x, read.y)
        and abs(float(sent.z) - float(read.z)) < ALTITUDE_RESOLUTION_M
    )


RADIUS_PARAMETERS = (("WP_RADIUS_M", 1.0), ("WPNAV_RADIUS", 100.0))
"""Where ArduCopter keeps the waypoint radius, newest first, with its unit per metre:
4.8 (as its SITL lists it) has WP_RADIUS_M in metres, 4.6 and older WPNAV_RADIUS in cm."""
MIN_RADIUS_M = 0.05  # Copter's WP_RADIUS_M_MIN


def acceptance_radius_m(mission: Mission) -> float | None:
    """The waypoints' acceptance radius (their param2, which ArduCopter does not store
    but takes from a parameter), if the mission asks for one."""
    radii = {
        item.params[1]
        for item in mission.items
        if item.command == mavlink2.MAV_CMD_NAV_WAYPOINT and item.params[1] > 0
    }
    return max(MIN_RADIUS_M, min(radii)) if radii else None


def _stored_param(command: int, index: int, value: float) -> float:
    if (command, index) == (mavlink2.MAV_CMD_NAV_LAND, 3):
        return -1.0 if value < 0 else 1.0  # only its sign is kept (NaN: 1)
    if math.isnan(value):
        return 0.0  # "unset" comes back 0
    if index == 0 and command in WHOLE_SECONDS:
        return float(min(max(int(value), 0), UINT16_MAX))
    return float(np.float32(value))


def _frame_class(frame: int) -> str:
    if frame in RELATIVE:
        return "relative"
    if frame in ABSOLUTE:
        return "absolute"
    return f"frame {frame}"


def _same_f32(a: float, b: float) -> bool:
    fa, fb = np.float32(a), np.float32(b)
    return bool((math.isnan(fa) and math.isnan(fb)) or fa == fb)
