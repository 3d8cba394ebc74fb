"""Asking a vehicle for the telemetry the ground station follows.

A real ArduPilot streams nothing but HEARTBEAT until asked. SET_MESSAGE_INTERVAL
(MAVLink 2 era) is tried first, one message at a time; a vehicle that does not
acknowledge it gets the older REQUEST_DATA_STREAM for everything instead.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.commands import Cmd, CommandPolicy, send_command
from gcs.mavlink.errors import CommandError

if TYPE_CHECKING:
    from gcs.mavlink.link import VehicleLink

INTERVAL_POLICY = CommandPolicy(timeout_s=0.5, retries=2)
FALLBACK_STREAMS = (
    mavlink2.MAV_DATA_STREAM_EXTENDED_STATUS,  # SYS_STATUS, GPS_RAW_INT, MISSION_CURRENT
    mavlink2.MAV_DATA_STREAM_POSITION,  # GLOBAL_POSITION_INT
    mavlink2.MAV_DATA_STREAM_EXTRA2,  # VFR_HUD
)
FALLBACK_RATE_HZ = 4


def message_id(name: str) -> int:
    return getattr(mavlink2, f"MAVLINK_MSG_ID_{name}")


async def request_telemetry(link: VehicleLink, rates_hz: dict[str, float]) -> bool:
    """Ask for each message at its rate; True if SET_MESSAGE_INTERVAL was accepted."""
    try:
        for name, rate in rates_hz.items():
            await set_message_interval(link, name, rate)
    except CommandError:
        request_data_streams(link)
        return False
    return True


async def set_message_interval(link: VehicleLink, name: str, rate_hz: float) -> None:
    interval_us = int(1e6 / rate_hz) if rate_hz > 0 else -1
    await send_command(
        link, Cmd.SET_MESSAGE_INTERVAL, message_id(name), interval_us, policy=INTERVAL_POLICY
    )


def request_data_streams(link: VehicleLink, rate_hz: int = FALLBACK_RATE_HZ) -> None:
    """The pre-MAVLink-2 way: no acknowledgement, so sent once per stream group."""
    for stream in FALLBACK_STREAMS:
        link.send(
            link.codec.request_data_stream_encode(link.sysid, link.compid, stream, rate_hz, 1)
        )
