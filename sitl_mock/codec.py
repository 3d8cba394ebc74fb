"""pymavlink's MAVLink 2 codec (ardupilotmega dialect), wrapped for a vehicle's two needs:
encoding with its own sequence numbers and parsing each peer's byte stream separately."""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink

Message = mavlink.MAVLink_message

VEHICLE_COMPONENT = mavlink.MAV_COMP_ID_AUTOPILOT1


class Encoder:
    """Packs messages as one vehicle (its sysid, component 1), numbering them like an autopilot."""

    def __init__(self, sysid: int, compid: int = VEHICLE_COMPONENT) -> None:
        self._mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)

    def encode(self, msg: Message) -> bytes:
        buf = msg.pack(self._mav)
        self._mav.seq = (self._mav.seq + 1) % 256
        return buf


class Decoder:
    """Parses one peer's bytes; a stream may split or join packets, so state is kept per peer."""

    def __init__(self) -> None:
        self._mav = mavlink.MAVLink(None)
        self._mav.robust_parsing = True

    def decode(self, data: bytes) -> list[Message]:
        messages = self._mav.parse_buffer(data) or []
        return [m for m in messages if m.get_type() != "BAD_DATA"]


@dataclass(frozen=True)
class Sender:
    """Who sent a packet: its MAVLink identity and the link (address or connection) it came on."""

    sysid: int
    compid: int
    link: Hashable
