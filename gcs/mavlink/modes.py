"""Flight modes of both autopilot flavours, from pymavlink's own tables.

ArduCopter numbers its modes (`mavutil.mode_mapping_acm`); PX4 packs a main mode and a
sub mode into the custom_mode word (main << 16 | sub << 24, `mavutil.px4_map`). The
ground station speaks of modes by ArduCopter's names: `AUTO` is "fly the mission"
(PX4's AUTO.MISSION) and `GUIDED` is "hold where commanded" (PX4's AUTO.LOITER, the
nearest it has); every other PX4 name is PX4's own.
"""

from __future__ import annotations

from pymavlink import mavutil

from gcs.mavlink.mission_item import Autopilot

ARDUCOPTER_MODES: dict[str, int] = {
    name: number for number, name in mavutil.mode_mapping_acm.items()
}
PX4_ALIASES = {"AUTO": "MISSION", "GUIDED": "LOITER"}
PX4_MODES: dict[str, tuple[int, int]] = {
    name: (main, sub) for name, (_, main, sub) in mavutil.px4_map.items()
}


class UnknownModeError(ValueError):
    """The mode name does not exist for this autopilot."""


def px4_custom_mode(main: int, sub: int = 0) -> int:
    return (main << 16) | (sub << 24)


def px4_main_sub(name: str) -> tuple[int, int]:
    """PX4's (main, sub) mode of one of our mode names."""
    key = PX4_ALIASES.get(name.upper(), name.upper())
    if key not in PX4_MODES:
        known = ", ".join(sorted({*PX4_MODES, *PX4_ALIASES}))
        raise UnknownModeError(f"PX4 has no mode {name!r}; known: {known}")
    return PX4_MODES[key]


def custom_mode(autopilot: Autopilot, name: str) -> int:
    """The HEARTBEAT/DO_SET_MODE custom_mode value of a mode name."""
    if autopilot == Autopilot.PX4:
        return px4_custom_mode(*px4_main_sub(name))
    key = name.upper()
    if key not in ARDUCOPTER_MODES:
        known = ", ".join(ARDUCOPTER_MODES)
        raise UnknownModeError(f"ArduCopter has no mode {name!r}; known: {known}")
    return ARDUCOPTER_MODES[key]


def mode_name(autopilot: int, custom: int) -> str:
    """The name of a custom_mode as the HEARTBEAT reports it ("MODE(n)" if unknown)."""
    if autopilot == Autopilot.PX4:
        name = str(mavutil.interpret_px4_mode(0, custom))
        if name == "MISSION":
            return "AUTO"
        return name if name != "UNKNOWN" else f"MODE({custom})"
    return str(mavutil.mode_mapping_acm.get(custom, f"MODE({custom})"))
