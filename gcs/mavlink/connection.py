"""One MAVLink 2 endpoint: the codec, our GCS identity and heartbeat, and demultiplexing.

Several vehicles may speak through one connection (a udpin port many vehicles send
to); each message goes to the handler registered for its sender's system id, so two
vehicles sharing a port never see each other's traffic. Sending remembers which
address a system id spoke from and answers it there.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.transport import ByteTransport, Peer, open_transport

GCS_SYSID = 255
GCS_COMPID = 190  # MAV_COMP_ID_MISSIONPLANNER, as QGroundControl
HEARTBEAT_PERIOD_S = 1.0

Message = mavlink2.MAVLink_message
Handler = Callable[[Message], None]


class MavConnection:
    """A connection string opened as MAVLink 2, shared by the vehicle links on it."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.codec = mavlink2.MAVLink(None, srcSystem=GCS_SYSID, srcComponent=GCS_COMPID)
        self._transport: ByteTransport | None = None
        self._parsers: dict[Peer, mavlink2.MAVLink] = {}
        self._handlers: dict[int, Handler] = {}
        self._any_handlers: list[Handler] = []
        self._peer_of: dict[int, Peer] = {}
        self._heartbeat: asyncio.Task[None] | None = None

    @classmethod
    async def open(cls, url: str) -> MavConnection:
        connection = cls(url)
        connection._transport = await open_transport(url, connection._received)
        connection._heartbeat = asyncio.create_task(connection._send_heartbeats())
        return connection

    # --- receiving ---------------------------------------------------------------------

    def _received(self, data: bytes, peer: Peer) -> None:
        parser = self._parsers.get(peer)
        if parser is None:
            parser = self._parsers[peer] = mavlink2.MAVLink(None)
            parser.robust_parsing = True
        for msg in parser.parse_buffer(data) or ():
            if msg.get_type() == "BAD_DATA":
                continue
            sysid = msg.get_srcSystem()
            self._peer_of[sysid] = peer
            handler = self._handlers.get(sysid)
            if handler is not None:
                handler(msg)
            for listener in list(self._any_handlers):
                listener(msg)

    def attach(self, sysid: int, handler: Handler) -> None:
        """Send every message from `sysid` to `handler` (one handler per system id)."""
        self._handlers[sysid] = handler

    def detach(self, sysid: int) -> None:
        self._handlers.pop(sysid, None)

    def listen(self, handler: Handler) -> Callable[[], None]:
        """Also see every message from every system (discovery); returns the remover."""
        self._any_handlers.append(handler)
        return lambda: self._any_handlers.remove(handler)

    # --- sending -----------------------------------------------------------------------

    def send(self, msg: Message, sysid: int | None = None) -> None:
        """Pack with our identity and send to the vehicle `sysid` (or to every peer)."""
        if self._transport is None:
            return
        data = msg.pack(self.codec)
        peer = self._peer_of.get(sysid) if sysid is not None else None
        if peer is None and sysid is not None and sysid in self._peer_of:
            self._transport.send(data)  # a TCP stream: no address
        elif peer is None:
            for target in self._transport.peers():
                self._transport.send(data, target)
        else:
            self._transport.send(data, peer)

    async def _send_heartbeats(self) -> None:
        beat = self.codec.heartbeat_encode(
            mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, mavlink2.MAV_STATE_ACTIVE
        )
        while True:
            self.send(beat)
            await asyncio.sleep(HEARTBEAT_PERIOD_S)

    async def close(self) -> None:
        if self._heartbeat is not None:
            self._heartbeat.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._heartbeat
        if self._transport is not None:
            self._transport.close()
            self._transport = None
