"""Which vehicle is at the other end of a link: its system id and its board's unique id.

One vehicle can be reached several ways at once (its own TCP port, and the ground
station's listening port through MAVProxy or a router, as SITL serves it), and a
connection string says nothing about which vehicle answers on it. The autopilot's
AUTOPILOT_VERSION does: ArduPilot fills `uid2` (the MCU's id; SITL the machine id plus
its instance) and PX4 `uid`. Two links whose vehicles report the same system id and the
same UID reach one vehicle. A vehicle that reports no UID (zeros) cannot be told apart
from another with its system id, and is never taken for one. A link asks once
(`gcs.mavlink.client.identify`) and keeps the answer.
"""

from __future__ import annotations

from dataclasses import dataclass


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
