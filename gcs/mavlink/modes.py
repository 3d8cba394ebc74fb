"""Flight modes of both autopilot flavours: names to custom_mode values and back.

ArduCopter numbers its modes; PX4 packs a main mode and a sub mode into the
custom_mode word (main << 16 | sub << 24). Callers use the names only.
"""

from __future__ import annotations

from gcs.mavlink.mission_item import Autopilot

ARDUCOPTER_MODES: dict[str, int] = {
    "STABILIZE": 0,
    "ACRO": 1,
    "ALT_HOLD": 2,
    "AUTO": 3,
    "GUIDED": 4,
    "LOITER": 5,
    "RTL": 6,
    "CIRCLE": 7,
    "LAND": 9,
    "POSHOLD": 16,
    "BRAKE": 17,
}

PX4_MAIN_MODES: dict[str, int] = {
    "MANUAL": 1,
    "ALTCTL": 2,
    "POSCTL": 3,
    "AUTO": 4,
    "ACRO": 5,
    "OFFBOARD": 6,
    "STABILIZED": 7,
}
PX4_AUTO_SUB_MODES: dict[str, int] = {
    "READY": 1,
    "TAKEOFF": 2,
    "LOITER": 3,
    "MISSION": 4,
    "RTL": 5,
    "LAND": 6,
}
# The names the ground station uses, as (main, sub) in PX4.
PX4_MODES: dict[str, tuple[int, int]] = {
    **{name: (main, 0) for name, main in PX4_MAIN_MODES.items() if name != "AUTO"},
    "AUTO": (4, 4),  # AUTO means "fly the mission", as in ArduCopter
    **{name: (4, sub) for name, sub in PX4_AUTO_SUB_MODES.items() if name != "MISSION"},
    "GUIDED": (4, 3),  # PX4 holds position in AUTO.LOITER, the nearest to GUIDED
}


class UnknownModeError(ValueError):
    """The mode name does not exist for this autopilot."""


def px4_custom_mode(main: int, sub: int = 0) -> int:
    return (main << 16) | (sub << 24)


def custom_mode(autopilot: Autopilot, name: str) -> int:
    """The HEARTBEAT/DO_SET_MODE custom_mode value of a mode name."""
    key = name.upper()
    if autopilot == Autopilot.PX4:
        if key not in PX4_MODES:
            raise UnknownModeError(f"PX4 has no mode {name!r}; known: {', '.join(PX4_MODES)}")
        return px4_custom_mode(*PX4_MODES[key])
    if key not in ARDUCOPTER_MODES:
        known = ", ".join(ARDUCOPTER_MODES)
        raise UnknownModeError(f"ArduCopter has no mode {name!r}; known: {known}")
    return ARDUCOPTER_MODES[key]


def mode_name(autopilot: int, custom: int) -> str:
    """The name of a custom_mode as the HEARTBEAT reports it ("MODE(n)" if unknown)."""
    if autopilot == Autopilot.PX4:
        main, sub = (custom >> 16) & 0xFF, (custom >> 24) & 0xFF
        if main == PX4_MAIN_MODES["AUTO"]:
            if sub == PX4_AUTO_SUB_MODES["MISSION"]:
                return "AUTO"
            names = {v: k for k, v in PX4_AUTO_SUB_MODES.items()}
            return names.get(sub, f"AUTO({sub})")
        names = {v: k for k, v in PX4_MAIN_MODES.items()}
        return names.get(main, f"MODE({custom})")
    names = {v: k for k, v in ARDUCOPTER_MODES.items()}
    return names.get(custom, f"MODE({custom})")
