"""What a vehicle does on its own when it loses the ground station: it brakes.

The passing order is kept from the ground: a vehicle that can no longer hear it flies
its mission on, through the places where it was to wait for others (fuzzed flights with
a 10 s link drop at 10 m/s came 1.75 m close, 2R 6 m), and so does every vehicle of a
service killed in flight. So before a flight, each ArduCopter is given its own GCS
failsafe (`FS_GCS_ENABLE` 7: brake, or land where it cannot), after `brake_after_s` of
silence (`FS_GCS_TIMEOUT`), landings left to go on (`FS_OPTIONS` bit 3: "continue if
landing", the vehicle's other options kept). The follower takes a vehicle it finds so
braked for stopped, and sends it on by the passing order once it is heard again.

ArduCopter counts only the HEARTBEATs of `MAV_GCS_SYSID` (255, the service's), on its
own clock, which a simulator may run faster than the wall's: the timeout is given in the
vehicle's seconds, from how fast its clock (`time_boot_ms`) has run since we first heard
it (SITL at speed-up 2 showed HEARTBEATs ten times a second, so their rate says
nothing of its clock: taken for it, the timeout came to 19 s, not 4). The service
beats five times a second (`gcs.mavlink.connection`), ten beats to a timeout of 2 s: 20 %
packet loss drops them all once in ten million. Another ground station beating as 255
(a second console, a MAVProxy) keeps the failsafe from acting while it is heard.
PX4 keeps its own data-link-loss action (`NAV_DLL_ACT`): it is not set here.
"""

from __future__ import annotations

import asyncio
import logging

from gcs.mavlink.errors import GcsError
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Autopilot
from gcs.mavlink.parameters import find_parameter, set_parameter

log = logging.getLogger("mvo_gcs.fleet")

BRAKE_OR_LAND = 7
CONTINUE_IF_LANDING = 1 << 3
RATE_WITHIN_S = 3.0
TIMEOUT_RANGE_S = (2.0, 120.0)
"""FS_GCS_TIMEOUT's range (ArduCopter 4.3 on; before, the timeout was fixed at 5 s)."""
FIXED_TIMEOUT_S = 5.0


class FailsafeSetupError(GcsError):
    """The vehicle did not take its GCS failsafe: the flight must not start."""


async def brake_on_link_loss(link: VehicleLink, brake_after_s: float) -> float | None:
    """Give the vehicle its GCS failsafe (ArduPilot only; a `brake_after_s` of 0 leaves
    its parameters as they are); `FailsafeSetupError` if it does not take it. The
    seconds of its own it flies on without us before it brakes, None if not known."""
    if brake_after_s <= 0 or link.autopilot != Autopilot.ARDUPILOT:
        return None
    try:
        return await _set_failsafe(link, brake_after_s)
    except GcsError as exc:
        raise FailsafeSetupError(
            f"vehicle {link.sysid}: its brake on losing the ground station (GCS failsafe) "
            f"was not set, flight refused: {exc}"
        ) from exc


async def _set_failsafe(link: VehicleLink, brake_after_s: float) -> float:
    timeout_s = FIXED_TIMEOUT_S
    if await find_parameter(link, ["FS_GCS_TIMEOUT"]) is not None:
        timeout_s = timeout_on_vehicle_s(await _clock_rate(link), brake_after_s)
        await set_parameter(link, "FS_GCS_TIMEOUT", timeout_s)
        log.info("vehicle %d brakes after %.1f s of its own without us", link.sysid, timeout_s)
    found = await find_parameter(link, ["FS_OPTIONS"])
    if found is not None and int(found[1]) & CONTINUE_IF_LANDING == 0:
        await set_parameter(link, "FS_OPTIONS", int(found[1]) | CONTINUE_IF_LANDING)
    await set_parameter(link, "FS_GCS_ENABLE", BRAKE_OR_LAND)
    return timeout_s


async def _clock_rate(link: VehicleLink) -> float:
    """How fast the vehicle's clock runs, once a second of its reports tells (a link
    opened for the flight, its mission uploaded in under a second on SITL, knew nothing
    yet: the timeout came to 2 s of a vehicle at speed-up 2, one of ours); as ours if
    its reports do not say within RATE_WITHIN_S."""
    loop = asyncio.get_running_loop()
    until = loop.time() + RATE_WITHIN_S
    while (rate := link.clock_rate()) is None and loop.time() < until:
        await asyncio.sleep(0.1)
    if rate is None:
        log.warning("vehicle %d: its clock's rate is not known: taken for ours", link.sysid)
    return rate or 1.0


def timeout_on_vehicle_s(rate: float, brake_after_s: float) -> float:
    """`brake_after_s` of the ground station's time, in the seconds of a vehicle whose
    clock runs `rate` times as fast, within FS_GCS_TIMEOUT's range."""
    low, high = TIMEOUT_RANGE_S
    return min(high, max(low, round(brake_after_s * rate, 1)))
