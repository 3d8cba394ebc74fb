"""A vehicle's navigation limits, as its own parameters state them.

A flight is timed and kept apart with each vehicle's real limits, not assumed ones: how
fast it accelerates (and how hard that acceleration ramps) decides how far ahead it
must be told to stop. ArduCopter renamed these parameters in 4.7/4.8 (WP_* in SI units;
before: WPNAV_* in centimetres); each is looked up under its names, newest first. A
vehicle that answers none (PX4, or a link too lossy to ask) flies with ArduCopter's
defaults, which the flight says.
"""

from __future__ import annotations

import asyncio
import dataclasses

from gcs.mavlink.errors import GcsError
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Autopilot
from gcs.mavlink.parameters import find_parameter
from gcs.mission.motion import CopterLimits

NAMES: dict[str, tuple[tuple[str, float], ...]] = {
    "accel_m_s2": (("WP_ACC", 1.0), ("WPNAV_ACCEL", 100.0)),
    "jerk_m_s3": (("WP_JERK", 1.0), ("WPNAV_JERK", 1.0)),
    "corner_accel_m_s2": (("WP_ACC_CNR", 1.0), ("WPNAV_ACCEL_C", 100.0)),
    "stop_jerk_m_s3": (("PSC_JERK_NE", 1.0), ("PSC_JERK_XY", 1.0)),
    "jerk_ramp_s": (("ATC_INPUT_TC", 0.5),),  # the S-curves' jerk builds over 2 x this
    "descent_m_s": (("WP_SPD_DN", 1.0), ("WPNAV_SPEED_DN", 100.0)),
    "land_m_s": (("LAND_SPD_MS", 1.0), ("LAND_SPEED", 100.0)),
    "vertical_accel_m_s2": (("WP_ACC_Z", 1.0), ("WPNAV_ACCEL_Z", 100.0)),
}
"""CopterLimits field: (parameter, units per SI unit), newest name first."""


async def read_limits(link: VehicleLink) -> CopterLimits:
    """The vehicle's limits; ArduCopter's defaults for what it does not say."""
    defaults = CopterLimits()
    if link.autopilot != Autopilot.ARDUPILOT:
        return defaults
    found = await asyncio.gather(*(_read(link, names) for names in NAMES.values()))
    values = {field: value for field, value in zip(NAMES, found, strict=True) if value is not None}
    if values.get("corner_accel_m_s2", 1.0) <= 0:  # 0: twice the acceleration
        values["corner_accel_m_s2"] = 2 * values.get("accel_m_s2", defaults.accel_m_s2)
    return dataclasses.replace(defaults, **{k: v for k, v in values.items() if v > 0})


async def _read(link: VehicleLink, names: tuple[tuple[str, float], ...]) -> float | None:
    try:
        found = await find_parameter(link, [name for name, _ in names])
    except GcsError:
        return None
    if found is None:
        return None
    name, value = found
    return value / dict(names)[name]
