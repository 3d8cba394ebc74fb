"""Flight modes and their wire encoding: ArduCopter custom mode numbers, PX4's main/sub modes."""

from __future__ import annotations

import enum

from .codec import mavlink


class FlightMode(enum.Enum):
    """What the vehicle is doing, independent of how an autopilot numbers it."""

    STABILIZE = "STABILIZE"
    POSCTL = "POSCTL"
    AUTO = "AUTO"
    GUIDED = "GUIDED"
    LOITER = "LOITER"
    RTL = "RTL"
    LAND = "LAND"
    BRAKE = "BRAKE"
    TAKEOFF = "TAKEOFF"
    OFFBOARD = "OFFBOARD"


REQUIRES_POSITION = frozenset(
    {
        FlightMode.AUTO,
        FlightMode.GUIDED,
        FlightMode.LOITER,
        FlightMode.RTL,
        FlightMode.BRAKE,
        FlightMode.POSCTL,
        FlightMode.TAKEOFF,
        FlightMode.OFFBOARD,
    }
)
"""Modes a real autopilot refuses before it has a position estimate."""


class ModeTable:
    """Two-way map between FlightMode and a custom_mode number, plus base_mode flags."""

    def __init__(
        self,
        numbers: dict[FlightMode, int],
        guided_modes: frozenset[FlightMode],
        base_flags: dict[FlightMode, int],
    ) -> None:
        self._numbers = numbers
        self._modes = {number: mode for mode, number in numbers.items()}
        self._guided = guided_modes
        self._base_flags = base_flags

    def custom_mode(self, mode: FlightMode) -> int:
        return self._numbers[mode]

    def mode(self, custom_mode: int) -> FlightMode | None:
        return self._modes.get(custom_mode)

    def supports(self, mode: FlightMode) -> bool:
        return mode in self._numbers

    def base_mode(self, mode: FlightMode, armed: bool) -> int:
        flags: int = self._base_flags.get(mode, 0) | mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if mode in self._guided:
            flags |= mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
        if armed:
            flags |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        return flags


_AP_BASE = mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED

ARDUCOPTER_MODES = ModeTable(
    numbers={
        FlightMode.STABILIZE: 0,
        FlightMode.AUTO: 3,
        FlightMode.GUIDED: 4,
        FlightMode.LOITER: 5,
        FlightMode.RTL: 6,
        FlightMode.LAND: 9,
        FlightMode.BRAKE: 17,
    },
    guided_modes=frozenset({FlightMode.AUTO, FlightMode.GUIDED, FlightMode.RTL, FlightMode.LAND}),
    base_flags={mode: _AP_BASE for mode in FlightMode},
)
"""ArduCopter: base_mode 0x51 (0x59 in autopilot-driven modes), 0xD9 armed, as SITL sends."""

ARDUCOPTER_NAMES = {
    FlightMode.STABILIZE: "Stabilize",
    FlightMode.AUTO: "Auto",
    FlightMode.GUIDED: "Guided",
    FlightMode.LOITER: "Loiter",
    FlightMode.RTL: "RTL",
    FlightMode.LAND: "Land",
    FlightMode.BRAKE: "Brake",
}
"""What ArduCopter's `Mode::name()` calls each mode in its STATUSTEXTs."""


def _px4(main: int, sub: int = 0) -> int:
    return (main << 16) | (sub << 24)


PX4_MAIN_POSCTL, PX4_MAIN_AUTO, PX4_MAIN_OFFBOARD, PX4_MAIN_STABILIZED = 3, 4, 6, 7
PX4_SUB_TAKEOFF, PX4_SUB_LOITER, PX4_SUB_MISSION, PX4_SUB_RTL, PX4_SUB_LAND = 2, 3, 4, 5, 6

_PX4_AUTO_FLAGS = (
    mavlink.MAV_MODE_FLAG_AUTO_ENABLED
    | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
    | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
)
_PX4_MANUAL_FLAGS = (
    mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
)

PX4_MODES = ModeTable(
    numbers={
        FlightMode.STABILIZE: _px4(PX4_MAIN_STABILIZED),
        FlightMode.POSCTL: _px4(PX4_MAIN_POSCTL),
        FlightMode.AUTO: _px4(PX4_MAIN_AUTO, PX4_SUB_MISSION),
        FlightMode.LOITER: _px4(PX4_MAIN_AUTO, PX4_SUB_LOITER),
        FlightMode.RTL: _px4(PX4_MAIN_AUTO, PX4_SUB_RTL),
        FlightMode.LAND: _px4(PX4_MAIN_AUTO, PX4_SUB_LAND),
        FlightMode.TAKEOFF: _px4(PX4_MAIN_AUTO, PX4_SUB_TAKEOFF),
        FlightMode.OFFBOARD: _px4(PX4_MAIN_OFFBOARD),
    },
    guided_modes=frozenset({FlightMode.POSCTL}),
    base_flags={
        FlightMode.STABILIZE: _PX4_MANUAL_FLAGS,
        FlightMode.POSCTL: _PX4_MANUAL_FLAGS,
        **{
            mode: _PX4_AUTO_FLAGS
            for mode in (
                FlightMode.AUTO,
                FlightMode.LOITER,
                FlightMode.RTL,
                FlightMode.LAND,
                FlightMode.TAKEOFF,
                FlightMode.OFFBOARD,
            )
        },
    },
)
"""PX4: custom_mode = main << 16 | sub << 24."""
