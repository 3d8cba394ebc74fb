"""The parameter protocol over a small set of each autopilot's real parameters.

ArduPilot sends every value as a float with its true type in `param_type`; PX4 copies an
integer's bytes into the float field ("bytewise" encoding), so both are reproduced.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from .codec import Message, mavlink
from .kinematics import NavLimits

INT8, INT16, INT32, REAL32 = (
    mavlink.MAV_PARAM_TYPE_INT8,
    mavlink.MAV_PARAM_TYPE_INT16,
    mavlink.MAV_PARAM_TYPE_INT32,
    mavlink.MAV_PARAM_TYPE_REAL32,
)
_INTEGER_TYPES = frozenset(
    {
        mavlink.MAV_PARAM_TYPE_UINT8,
        INT8,
        mavlink.MAV_PARAM_TYPE_UINT16,
        INT16,
        mavlink.MAV_PARAM_TYPE_UINT32,
        INT32,
    }
)


@dataclass
class Param:
    name: str
    value: float
    type: int


ARDUCOPTER_DEFAULTS: tuple[tuple[str, float, int], ...] = (
    ("MAV_SYSID", 1, INT16),
    ("MAV_GCS_SYSID", 255, INT16),
    ("FRAME_CLASS", 1, INT8),
    ("FRAME_TYPE", 0, INT8),
    ("ARMING_SKIPCHK", 0, INT32),
    ("DISARM_DELAY", 10, INT8),
    ("WP_SPD", 10.0, REAL32),
    ("WP_RADIUS_M", 2.0, REAL32),
    ("WP_ACC", 2.5, REAL32),
    ("WP_SPD_UP", 2.5, REAL32),
    ("WP_SPD_DN", 1.5, REAL32),
    ("WP_ACC_Z", 1.0, REAL32),
    ("WP_JERK", 1.0, REAL32),
    ("PSC_JERK_NE", 5.0, REAL32),
    ("ATC_INPUT_TC", 0.15, REAL32),
    ("LAND_SPD_MS", 0.5, REAL32),
    ("RTL_ALT_M", 15.0, REAL32),
    ("FENCE_ENABLE", 0, INT8),
    ("FENCE_TYPE", 7, INT8),
    ("FENCE_ACTION", 1, INT8),
    ("FENCE_ALT_MAX", 100.0, REAL32),
    ("FENCE_RADIUS", 300.0, REAL32),
    ("FENCE_MARGIN", 2.0, REAL32),
    ("FS_GCS_ENABLE", 0, INT8),
    ("FS_GCS_TIMEOUT", 5.0, REAL32),
    ("FS_OPTIONS", 16, INT32),
    ("WP_YAW_BEHAVIOR", 2, INT8),
    ("BATT_CAPACITY", 3300, INT32),
)
"""ArduCopter 4.8 names, units (m, m/s) and defaults, as its SITL lists them (4.6 and
older call these WPNAV_SPEED, WPNAV_RADIUS, ... in cm and cm/s)."""

PX4_DEFAULTS: tuple[tuple[str, float, int], ...] = (
    ("MAV_SYS_ID", 1, INT32),
    ("MAV_TYPE", 2, INT32),
    ("SYS_AUTOSTART", 10016, INT32),
    ("COM_DISARM_PRFLT", 10.0, REAL32),
    ("COM_DISARM_LAND", 2.0, REAL32),
    ("MPC_XY_CRUISE", 5.0, REAL32),
    ("MPC_XY_VEL_MAX", 12.0, REAL32),
    ("MPC_ACC_HOR", 3.0, REAL32),
    ("MPC_Z_VEL_MAX_UP", 3.0, REAL32),
    ("MPC_Z_VEL_MAX_DN", 1.5, REAL32),
    ("MPC_ACC_UP_MAX", 4.0, REAL32),
    ("MPC_JERK_AUTO", 4.0, REAL32),
    ("MPC_LAND_SPEED", 0.7, REAL32),
    ("NAV_ACC_RAD", 2.0, REAL32),
    ("MIS_TAKEOFF_ALT", 2.5, REAL32),
    ("RTL_RETURN_ALT", 30.0, REAL32),
    ("NAV_DLL_ACT", 0, INT32),
)
"""PX4 names, SI units and defaults."""


def arducopter_s_curve_jerk(params: ParameterSet) -> float:
    """The constant jerk at which the mock's S-curves change speed as fast as ArduCopter's.

    ArduCopter's limit snap as well: their jerk builds up and dies away over twice
    ATC_INPUT_TC (SCurve, with AC_WPNav's snap of half WP_JERK·π / (2·ATC_INPUT_TC)), so
    each ramp of the acceleration takes WP_ACC / WP_JERK plus that, which the same ramp at
    this jerk takes too. With the defaults that is 0.89 of WP_JERK: a 22 m leg from rest
    to rest peaks at 4.77 m/s (ArduCopter SITL 4.65-4.73; the whole WP_JERK gave 4.95 and
    each such leg 0.1-0.4 s short) and a stop from 10 m/s takes 6.8 s (SITL 6.8;
    bench/results/short_legs_vs_sitl.md, kinematics_vs_sitl.txt)."""
    accel, jerk = params.get("WP_ACC"), params.get("WP_JERK")
    return accel / (accel / jerk + 2 * max(params.get("ATC_INPUT_TC"), 0.1))


ARDUCOPTER_BRAKE_DECEL = 7.5
"""BRAKE_MODE_DECEL_RATE_MSS, compiled into ArduCopter (BRAKE mode has no parameter):
with PSC_JERK_NE (5) its speed decays with a 1.5 s time constant (`brake_profile`)."""


def arducopter_limits(params: ParameterSet) -> NavLimits:
    return NavLimits(
        cruise_speed=params.get("WP_SPD"),
        accel=params.get("WP_ACC"),
        climb_rate=params.get("WP_SPD_UP"),
        descent_rate=params.get("WP_SPD_DN"),
        vertical_accel=params.get("WP_ACC_Z"),
        land_speed=params.get("LAND_SPD_MS"),
        accept_radius=params.get("WP_RADIUS_M"),
        jerk=arducopter_s_curve_jerk(params),
        stop_jerk=params.get("PSC_JERK_NE"),
        brake_decel=ARDUCOPTER_BRAKE_DECEL,
    )


def px4_limits(params: ParameterSet) -> NavLimits:
    return NavLimits(
        cruise_speed=params.get("MPC_XY_CRUISE"),
        accel=params.get("MPC_ACC_HOR"),
        climb_rate=params.get("MPC_Z_VEL_MAX_UP"),
        descent_rate=params.get("MPC_Z_VEL_MAX_DN"),
        vertical_accel=params.get("MPC_ACC_UP_MAX"),
        land_speed=params.get("MPC_LAND_SPEED"),
        accept_radius=params.get("NAV_ACC_RAD"),
        jerk=params.get("MPC_JERK_AUTO"),
        stop_jerk=params.get("MPC_JERK_AUTO"),
        brake_decel=params.get("MPC_ACC_HOR"),
    )


class ParameterSet:
    """Ordered parameters (the index is the protocol's param_index) and their wire encoding."""

    def __init__(self, defaults: tuple[tuple[str, float, int], ...], bytewise: bool) -> None:
        self._params = [Param(name, float(value), kind) for name, value, kind in defaults]
        self._index = {p.name: i for i, p in enumerate(self._params)}
        self._bytewise = bytewise

    def __len__(self) -> int:
        return len(self._params)

    def __contains__(self, name: str) -> bool:
        return name in self._index

    def get(self, name: str) -> float:
        return self._params[self._index[name]].value

    def set(self, name: str, value: float) -> None:
        param = self._params[self._index[name]]
        param.value = float(round(value)) if param.type in _INTEGER_TYPES else float(value)

    def value_message(self, name: str) -> Message:
        index = self._index[name]
        return self._message(index)

    def message_at(self, index: int) -> Message | None:
        return self._message(index) if 0 <= index < len(self._params) else None

    def all_messages(self) -> list[Message]:
        return [self._message(i) for i in range(len(self._params))]

    def decode(self, name: str, wire_value: float) -> float:
        """The value a PARAM_SET means, undoing PX4's bytewise encoding for integers."""
        param = self._params[self._index[name]]
        if self._bytewise and param.type in _INTEGER_TYPES:
            return float(struct.unpack("<i", struct.pack("<f", wire_value))[0])
        return wire_value

    def _message(self, index: int) -> Message:
        param = self._params[index]
        return mavlink.MAVLink_param_value_message(
            param.name.encode(), self._encode(param), param.type, len(self._params), index
        )

    def _encode(self, param: Param) -> float:
        if self._bytewise and param.type in _INTEGER_TYPES:
            return float(struct.unpack("<f", struct.pack("<i", int(param.value)))[0])
        return param.value
