"""What a local program posing as a vehicle sends: well-formed, unsigned MAVLink that
claims the vehicle's system id, in GUIDED, in London (so that a taken-over link shows)."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

LONDON = (515074000, -1278000)
"""lat, lon in degE7."""


def forged(sysid: int) -> bytes:
    """An unsigned HEARTBEAT in GUIDED and a position in London, as vehicle `sysid`."""
    codec = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=1)
    beat = codec.heartbeat_encode(
        mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0x59, 4, 4
    )
    where = codec.global_position_int_encode(10**6, *LONDON, 20_000, 20_000, 0, 0, 0, 0)
    return bytes(beat.pack(codec)) + bytes(where.pack(codec))
