"""pymavlink's MAVLink 2 codec (ardupilotmega dialect), wrapped for a vehicle's two needs:
encoding with its own sequence numbers and parsing each peer's byte stream separately,
both optionally signed (`signing.py`)."""

from __future__ import annotations

import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any, TypeAlias

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import signing

__all__ = ["VEHICLE_COMPONENT", "Decoder", "Encoder", "Message", "Sender", "mavlink"]

Message: TypeAlias = Any
"""A pymavlink message (`mavlink.MAVLink_message`): its fields are attributes made at run time,
so a static type cannot name them."""

VEHICLE_COMPONENT: int = mavlink.MAV_COMP_ID_AUTOPILOT1


class Encoder:
    """Packs messages as one vehicle (its sysid, component 1), numbering them like an autopilot
    and signing them when the vehicle has a key."""

    def __init__(
        self,
        sysid: int,
        compid: int = VEHICLE_COMPONENT,
        key: bytes | None = None,
        wall: Callable[[], float] = time.time,
    ) -> None:
        self._mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self._signs = key is not None
        self._wall = wall
        if key is not None:
            signing.sign_outgoing(self._mav, key, wall())

    def encode(self, msg: Message) -> bytes:
        if self._signs:  # ArduPilot keeps its signing clock current; pymavlink only counts
            signing.keep_current(self._mav, self._wall())
        buf: bytes = msg.pack(self._mav)
        self._mav.seq = (self._mav.seq + 1) % 256
        return buf


class Decoder:
    """Parses one peer's bytes; a stream may split or join packets, so state is kept per peer.
    With a key, packets not signed with it are dropped and counted in `rejected`."""

    def __init__(self, key: bytes | None = None) -> None:
        self._mav = mavlink.MAVLink(None)
        self._mav.robust_parsing = True
        if key is not None:
            signing.require_signed(self._mav, key)

    @property
    def rejected(self) -> int:
        return signing.rejected(self._mav)

    def decode(self, data: bytes) -> list[Message]:
        messages = self._mav.parse_buffer(data) or []
        return [m for m in messages if m.get_type() != "BAD_DATA"]


@dataclass(frozen=True)
class Sender:
    """Who sent a packet: its MAVLink identity and the link (address or connection) it came on."""

    sysid: int
    compid: int
    link: Hashable
