"""Builders for the messages a vehicle sends, from a `VehicleState`."""

from __future__ import annotations

import math
from collections.abc import Callable

from .codec import Message, mavlink
from .flavour import Flavour
from .snapshot import VehicleState

S = mavlink

CAPABILITIES = (
    S.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
    | S.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | S.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | S.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | S.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
    | S.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | S.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
    | S.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
)
EKF_READY = (
    S.EKF_ATTITUDE
    | S.EKF_VELOCITY_HORIZ
    | S.EKF_VELOCITY_VERT
    | S.EKF_POS_HORIZ_REL
    | S.EKF_POS_HORIZ_ABS
    | S.EKF_POS_VERT_ABS
    | S.EKF_PRED_POS_HORIZ_REL
    | S.EKF_PRED_POS_HORIZ_ABS
)
EKF_NO_POSITION = (
    S.EKF_ATTITUDE
    | S.EKF_VELOCITY_HORIZ
    | S.EKF_VELOCITY_VERT
    | S.EKF_POS_VERT_ABS
    | S.EKF_CONST_POS_MODE
)
"""0xa7: what ArduCopter SITL reports from its EKF start until it uses GPS (then 0x33f)."""
SATELLITES = 10
BATTERY_MV = 12600


def heartbeat(state: VehicleState, flavour: Flavour) -> Message:
    return S.MAVLink_heartbeat_message(
        S.MAV_TYPE_QUADROTOR,
        flavour.autopilot,
        state.base_mode,
        state.custom_mode,
        state.system_status,
        3,
    )


def sys_status(state: VehicleState, flavour: Flavour) -> Message:
    present, enabled, health = state.sensors
    return S.MAVLink_sys_status_message(
        present,
        enabled,
        health,
        250,
        BATTERY_MV,
        1200 if state.armed else 0,
        95,
        0,
        0,
        0,
        0,
        0,
        0,
    )


def gps_raw_int(state: VehicleState, flavour: Flavour) -> Message:
    north, east, _ = state.velocity_ned
    return S.MAVLink_gps_raw_int_message(
        _usec(state),
        S.GPS_FIX_TYPE_RTK_FIXED,
        _e7(state.lat),
        _e7(state.lon),
        round(state.alt_amsl * 1000),
        121,
        65535,
        round(state.ground_speed * 100),
        _cdeg(math.degrees(math.atan2(east, north))),
        SATELLITES,
    )


def global_position_int(state: VehicleState, flavour: Flavour) -> Message:
    north, east, down = state.velocity_ned
    known = state.position_known
    return S.MAVLink_global_position_int_message(
        _msec(state),
        _e7(state.lat) if known else 0,
        _e7(state.lon) if known else 0,
        round(state.alt_amsl * 1000) if known else 0,
        round(state.alt * 1000),
        round(north * 100),
        round(east * 100),
        round(down * 100),
        _cdeg(state.heading_deg),
    )


def attitude(state: VehicleState, flavour: Flavour) -> Message:
    return S.MAVLink_attitude_message(
        _msec(state), 0.0, 0.0, math.radians(_wrap180(state.heading_deg)), 0.0, 0.0, 0.0
    )


def vfr_hud(state: VehicleState, flavour: Flavour) -> Message:
    return S.MAVLink_vfr_hud_message(
        state.ground_speed,
        state.ground_speed,
        round(state.heading_deg) % 360,
        50 if state.armed else 0,
        state.alt_amsl,
        -state.velocity_ned[2],
    )


def home_position(state: VehicleState, flavour: Flavour) -> Message:
    lat, lon, alt = state.home
    return S.MAVLink_home_position_message(
        _e7(lat),
        _e7(lon),
        round(alt * 1000),
        0.0,
        0.0,
        0.0,
        [1.0, 0.0, 0.0, 0.0],
        0.0,
        0.0,
        0.0,
        _usec(state),
    )


def gps_global_origin(state: VehicleState, flavour: Flavour) -> Message:
    """The EKF origin: where home was first set (ArduPilot sends it when that happens)."""
    lat, lon, alt = state.home
    return S.MAVLink_gps_global_origin_message(_e7(lat), _e7(lon), round(alt * 1000), _usec(state))


def timesync(state: VehicleState, flavour: Flavour) -> Message:
    """ArduPilot's own TIMESYNC request (tc1 0, ts1 its clock), every 10 s unasked."""
    return S.MAVLink_timesync_message(0, nanoseconds(state))


def extended_sys_state(state: VehicleState, flavour: Flavour) -> Message:
    return S.MAVLink_extended_sys_state_message(S.MAV_VTOL_STATE_UNDEFINED, state.landed_state)


def ekf_status_report(state: VehicleState, flavour: Flavour) -> Message:
    """ArduPilot's estimator summary; MAVSDK asks for it along with SYS_STATUS (health)."""
    flags = EKF_READY if state.estimate_ready else EKF_NO_POSITION  # MAVSDK's health
    return S.MAVLink_ekf_status_report_message(flags, 0.02, 0.02, 0.02, 0.02, 0.0, 0.0)


def mission_current(state: VehicleState, flavour: Flavour) -> Message:
    mission_mode = 1 if state.mode == "AUTO" else 0  # "current mode requires a mission"
    return S.MAVLink_mission_current_message(
        state.mission_seq, state.mission_total, state.mission_state, mission_mode
    )


def battery_status(state: VehicleState, flavour: Flavour) -> Message:
    cells = [4200, 4200, 4200] + [65535] * 7
    return S.MAVLink_battery_status_message(
        0,
        S.MAV_BATTERY_FUNCTION_ALL,
        S.MAV_BATTERY_TYPE_LIPO,
        2500,
        cells,
        1200 if state.armed else 0,
        -1,
        -1,
        95,
    )


def system_time(state: VehicleState, flavour: Flavour) -> Message:
    return S.MAVLink_system_time_message(0, _msec(state))


BUILDERS: dict[int, Callable[[VehicleState, Flavour], Message]] = {
    S.MAVLINK_MSG_ID_HEARTBEAT: heartbeat,
    S.MAVLINK_MSG_ID_SYS_STATUS: sys_status,
    S.MAVLINK_MSG_ID_GPS_RAW_INT: gps_raw_int,
    S.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: global_position_int,
    S.MAVLINK_MSG_ID_ATTITUDE: attitude,
    S.MAVLINK_MSG_ID_VFR_HUD: vfr_hud,
    S.MAVLINK_MSG_ID_HOME_POSITION: home_position,
    S.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: extended_sys_state,
    S.MAVLINK_MSG_ID_MISSION_CURRENT: mission_current,
    S.MAVLINK_MSG_ID_BATTERY_STATUS: battery_status,
    S.MAVLINK_MSG_ID_SYSTEM_TIME: system_time,
    S.MAVLINK_MSG_ID_EKF_STATUS_REPORT: ekf_status_report,
    S.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: gps_global_origin,
    S.MAVLINK_MSG_ID_TIMESYNC: timesync,
}
NEEDS_HOME = frozenset({S.MAVLINK_MSG_ID_HOME_POSITION, S.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN})
"""Messages that exist only once home (the EKF origin) is set."""
ARDUPILOT_ONLY = frozenset({S.MAVLINK_MSG_ID_EKF_STATUS_REPORT, S.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN})


def streamable(flavour: Flavour) -> frozenset[int]:
    """The messages a vehicle of this flavour can stream or send on request."""
    if flavour.name == "ardupilot":
        return frozenset(BUILDERS)
    return frozenset(BUILDERS) - ARDUPILOT_ONLY


def autopilot_version(sysid: int, flavour: Flavour, board_id: bytes) -> Message:
    """ArduPilot reports its board in `uid2` (SITL: the machine id plus the instance) and
    leaves `uid` zero; PX4 reports it in `uid`."""
    if flavour.name == "px4":
        version = (1 << 24) | (15 << 16) | (0 << 8) | S.FIRMWARE_VERSION_TYPE_OFFICIAL
        capabilities = CAPABILITIES | S.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
        uid, uid2 = int.from_bytes(board_id, "big"), [0] * 18
    else:
        version = (4 << 24) | (8 << 16) | (0 << 8) | S.FIRMWARE_VERSION_TYPE_DEV
        capabilities = CAPABILITIES
        uid, uid2 = 0, list(board_id.ljust(18, b"\0"))
    return S.MAVLink_autopilot_version_message(
        capabilities,
        version,
        0,
        0,
        0,
        [0] * 8,
        [0] * 8,
        [0] * 8,
        0x1209,
        0x5741,
        uid,
        uid2,
    )


def statustext(severity: int, text: str) -> Message:
    return S.MAVLink_statustext_message(severity, text.encode()[:50], 0, 0)


def command_ack(command: int, result: int, target_system: int, target_component: int) -> Message:
    return S.MAVLink_command_ack_message(command, result, 0, 0, target_system, target_component)


def _e7(degrees: float) -> int:
    return round(degrees * 1e7)


def _cdeg(degrees: float) -> int:
    return round(degrees % 360 * 100) % 36000


def _wrap180(degrees: float) -> float:
    return (degrees + 180.0) % 360.0 - 180.0


def _msec(state: VehicleState) -> int:
    return round(state.uptime * 1000) & 0xFFFFFFFF


def _usec(state: VehicleState) -> int:
    return round(state.t * 1e6)


def nanoseconds(state: VehicleState) -> int:
    """The vehicle's clock for TIMESYNC: nanoseconds since boot."""
    return round(state.uptime * 1e9)
