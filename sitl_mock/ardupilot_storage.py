"""How ArduPilot stores a mission item and what a download then returns.

ArduPilot does not keep the MISSION_ITEM_INT it was sent: `AP_Mission::
mavlink_int_to_mission_cmd` packs it into a 15-byte command (after
`sanity_check_params`) and `mission_cmd_to_mavlink_int` rebuilds an item from that on
download. A ground station that compares its upload with a download sees the
difference, so the mock stores items the same way (verified on ArduCopter SITL, see
docs/sitl_mock.md). Only the commands the mock flies are modelled.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .codec import mavlink
from .mission_item import NAV_COMMANDS, MissionItem

NAN_PARAM4_ALLOWED = frozenset(
    {
        mavlink.MAV_CMD_NAV_WAYPOINT,
        mavlink.MAV_CMD_NAV_LOITER_UNLIM,
        mavlink.MAV_CMD_NAV_LAND,
        mavlink.MAV_CMD_NAV_TAKEOFF,
    }
)
"""Commands for which `sanity_check_params` lets param4 be NaN; any other NaN is refused."""
RELATIVE_FRAMES = frozenset(
    {mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT}
)
ABSOLUTE_FRAMES = frozenset(
    {mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_INT, mavlink.MAV_FRAME_MISSION}
)
LOCATION_ALT_MAX_M = 83000.0
UINT16_MAX = 0xFFFF
INVALID_PARAM: tuple[int, ...] = (
    mavlink.MAV_MISSION_INVALID_PARAM1,
    mavlink.MAV_MISSION_INVALID_PARAM2,
    mavlink.MAV_MISSION_INVALID_PARAM3,
    mavlink.MAV_MISSION_INVALID_PARAM4,
)


def refusal(item: MissionItem) -> int | None:
    """The MAV_MISSION_RESULT ArduPilot answers this item with, or None if it stores it."""
    params = (item.param1, item.param2, item.param3, item.param4)
    for index, value in enumerate(params):
        nan_ok = index == 3 and item.command in NAN_PARAM4_ALLOWED
        if math.isinf(value) or (math.isnan(value) and not nan_ok):
            return INVALID_PARAM[index]
    if item.command == mavlink.MAV_CMD_NAV_WAYPOINT and not 0 <= item.param1 <= UINT16_MAX:
        return int(mavlink.MAV_MISSION_INVALID_PARAM1)
    if item.command not in NAV_COMMANDS:  # no position kept (`AP_Mission::stored_in_location`)
        return None
    if not -90e7 <= item.x <= 90e7:
        return int(mavlink.MAV_MISSION_INVALID_PARAM5_X)
    if not -180e7 <= item.y <= 180e7:
        return int(mavlink.MAV_MISSION_INVALID_PARAM6_Y)
    if math.isnan(item.z) or abs(item.z) >= LOCATION_ALT_MAX_M:
        return int(mavlink.MAV_MISSION_INVALID_PARAM7)
    if item.frame not in RELATIVE_FRAMES | ABSOLUTE_FRAMES:
        return int(mavlink.MAV_MISSION_UNSUPPORTED_FRAME)
    return None


def stored(item: MissionItem) -> MissionItem:
    """The item as a download returns it once ArduPilot has stored it."""
    params = _stored_params(item)
    if item.command in NAV_COMMANDS:
        frame = (
            mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
            if item.frame in RELATIVE_FRAMES
            else mavlink.MAV_FRAME_GLOBAL
        )
        x, y, z = item.x, item.y, _stored_alt(item.z)
    else:
        frame, x, y, z = 0, 0, 0, 0.0
    return replace(
        item,
        frame=frame,
        param1=params[0],
        param2=params[1],
        param3=params[2],
        param4=params[3],
        x=x,
        y=y,
        z=z,
        autocontinue=1,
        current=0,
    )


def _stored_params(item: MissionItem) -> tuple[float, float, float, float]:
    """param1..4 after the round trip through the packed command (float32, whole seconds)."""
    command = item.command
    if command == mavlink.MAV_CMD_NAV_WAYPOINT:
        return (float(_uint16(item.param1)), 0.0, 0.0, 0.0)
    if command == mavlink.MAV_CMD_NAV_LOITER_TIME:
        return (
            float(_uint16(item.param1)),
            0.0,
            -1.0 if item.param3 < 0 else 1.0,
            1.0 if item.param4 > 0 else 0.0,
        )
    if command == mavlink.MAV_CMD_NAV_LOITER_UNLIM:
        radius = float(_uint16(abs(item.param3)))
        return (0.0, 0.0, -radius if item.param3 < 0 else radius, 0.0)
    if command == mavlink.MAV_CMD_NAV_LAND:
        ccw = not math.isnan(item.param4) and item.param4 < 0
        return (float(_uint16(item.param1)), 0.0, 0.0, -1.0 if ccw else 1.0)
    if command == mavlink.MAV_CMD_NAV_TAKEOFF:
        return (float(_uint16(item.param1)), 0.0, 0.0, 0.0)
    if command == mavlink.MAV_CMD_DO_CHANGE_SPEED:
        return (float(_uint8(item.param1)), _float32(item.param2), _float32(item.param3), 0.0)
    return (0.0, 0.0, 0.0, 0.0)


def _stored_alt(z: float) -> float:
    """Metres kept as whole centimetres (`alt = z * 100.0f`, cut) and read back as float32."""
    centimetres = int(np.float32(z) * np.float32(100.0))
    return float(np.float32(centimetres) * np.float32(0.01))


def _float32(value: float) -> float:
    return float(np.float32(value))


def _uint16(value: float) -> int:
    """C's float-to-uint16 conversion as SITL does it: NaN is 0, fractions are cut."""
    return 0 if math.isnan(value) else int(value) & UINT16_MAX


def _uint8(value: float) -> int:
    return 0 if math.isnan(value) else int(value) & 0xFF
