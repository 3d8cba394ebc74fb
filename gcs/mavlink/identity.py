"""Which vehicle is at the other end of a link: its system id and its board's unique id.

One vehicle can be reached several ways at once (its own TCP port, and the ground
station's listening port through MAVProxy or a router, as SITL serves it), and a
connection string says nothing about which vehicle answers on it. The autopilot's
AUTOPILOT_VERSION does: ArduPilot fills `uid2` (the MCU's id; SITL the machine id plus
its instance) and PX4 `uid`. Two links whose vehicles report the same system id and the
same UID reach one vehicle. A vehicle that reports no UID (zeros) cannot be told apart
from another with its system id, and is never taken for one.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.commands import CommandPolicy, send_command
from gcs.mavlink.errors import GcsError, WaitTimeoutError
from gcs.mavlink.link import VehicleLink

ASK_POLICY = CommandPolicy(timeout_s=1.0, retries=2)
"""An old autopilot may not know REQUEST_MESSAGE; three tries are enough to ask."""
ANSWER_TIMEOUT_S = 1.0
"""How long AUTOPILOT_VERSION may trail the command's ACK."""


@dataclass(frozen=True)
class VehicleIdentity:
    sysid: int
    uid: str | None
    """The board's unique id in hex (`uid`, else `uid2`); None: the autopilot gives none."""

    def is_same_vehicle(self, other: VehicleIdentity) -> bool:
        return self.uid is not None and (self.sysid, self.uid) == (other.sysid, other.uid)

    def __str__(self) -> str:
        return f"sysid {self.sysid}, UID {self.uid or 'unknown'}"


def identity_of(msg: object, sysid: int) -> VehicleIdentity:
    """The identity an AUTOPILOT_VERSION message reports."""
    uid = int(getattr(msg, "uid", 0))
    uid2 = bytes(getattr(msg, "uid2", b"") or b"")
    if uid:
        return VehicleIdentity(sysid, f"{uid:016x}")
    if any(uid2):
        return VehicleIdentity(sysid, uid2.rstrip(b"\0").hex())
    return VehicleIdentity(sysid, None)


async def identify(link: VehicleLink) -> VehicleIdentity | None:
    """The vehicle's identity, asked for once per link and kept on it; None while the
    vehicle does not answer (asked again next time)."""
    if link.identity is not None:
        return link.identity
    with link.subscribe(["AUTOPILOT_VERSION"]) as sub:
        try:
            await _ask(link)
            msg = await sub.next_matching(None, ANSWER_TIMEOUT_S)
        except (GcsError, WaitTimeoutError):
            return None
    link.identity = identity_of(msg, link.sysid)
    return link.identity


async def _ask(link: VehicleLink) -> None:
    """REQUEST_MESSAGE, or the older REQUEST_AUTOPILOT_CAPABILITIES where it is refused."""
    with contextlib.suppress(GcsError):
        await send_command(
            link,
            mavlink2.MAV_CMD_REQUEST_MESSAGE,
            mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
            policy=ASK_POLICY,
        )
        return
    await send_command(link, mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1, policy=ASK_POLICY)
