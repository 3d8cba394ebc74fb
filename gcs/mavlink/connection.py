"""One MAVLink 2 endpoint: the codec, our GCS identity and heartbeat, and demultiplexing.

A connection is handed a byte transport (sockets, or memory in tests). Several vehicles
may speak through one connection (a udpin port many vehicles send to); each message goes
to the handler registered for its sender's system id, so two vehicles sharing a port
never see each other's traffic. On a listening port the first address a system id's
HEARTBEAT comes from speaks for that system from then on: packets claiming that system
id from any other address are dropped and counted (`ignored`), and the latest such
claimant is kept (`contested`), so a local process cannot pose as a vehicle. A system
silent for RELOCK_AFTER_S may come back from a new address, unless it is `pinned` (a
registered vehicle): then only the operator moves it (`relock`), or, on a signed
connection, a validly signed packet. With a signing key, every packet we send is signed
and every packet that is unsigned or wrongly signed is dropped and counted the same way.
Per-sender parsers are bounded in count and time (`gcs.mavlink.recent`).
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.endpoint import Endpoint
from gcs.mavlink.recent import Recent
from gcs.mavlink.signature_check import TICKS_PER_S, why_refused
from gcs.mavlink.transport import ByteTransport, Peer, TransportOpener, open_transport

GCS_SYSID = 255
GCS_COMPID = mavlink2.MAV_COMP_ID_MISSIONPLANNER  # 190, as QGroundControl
HEARTBEAT_PERIOD_S = 0.2
"""Five a second, not MAVLink's customary one: ArduCopter's GCS failsafe, which the
service sets to brake after 2 s without one (`gcs.fleet.link_loss`), then sees ten beats
to a timeout, and packet loss alone does not set it off."""
SIGNING_EPOCH = 1420070400  # MAVLink signing timestamps count from 2015-01-01
RELOCK_AFTER_S = 10.0  # a system silent this long may speak from a new address

Message = Any
"""A decoded pymavlink message (`mavlink2.MAVLink_message`); untyped in pymavlink."""
Handler = Callable[[Message], None]


@dataclass(frozen=True)
class Signing:
    """MAVLink 2 message signing: a 32-byte secret shared with the vehicle."""

    key: bytes
    link_id: int = 0

    def __post_init__(self) -> None:
        if len(self.key) != 32:
            raise ValueError(f"a MAVLink signing key has 32 bytes, got {len(self.key)}")

    @classmethod
    def from_text(cls, text: str) -> Signing:
        """64 hex digits, or a passphrase hashed as MAVProxy's `signing setup` does."""
        try:
            key = bytes.fromhex(text)
        except ValueError:
            key = b""
        return cls(key if len(key) == 32 else hashlib.sha256(text.encode()).digest())

    def apply(self, codec: Any, *, outgoing: bool) -> None:
        codec.signing.secret_key = self.key
        codec.signing.link_id = self.link_id
        codec.signing.sign_outgoing = outgoing
        codec.signing.allow_unsigned_callback = None  # unsigned packets are refused
        codec.signing.timestamp = signing_now()


def signing_now() -> int:
    """Now in signing units: a protocol timestamp, so the wall clock, not the loop's."""
    return int((time.time() - SIGNING_EPOCH) * TICKS_PER_S)


@dataclass
class _Speaker:
    """The address a system id speaks from, and when it last did."""

    peer: Peer
    heard: float


@dataclass
class Contest:
    """Another address that claims a system id already speaking from elsewhere."""

    peer: Peer
    packets: int
    last: float

    @property
    def address(self) -> str:
        return format_peer(self.peer)


def format_peer(peer: Peer) -> str:
    if peer is None:
        return "the connection's one peer"
    host, port = peer[:2]
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


class MavConnection:
    """A byte transport spoken as MAVLink 2, shared by the vehicle links on it."""

    def __init__(
        self,
        transport: ByteTransport,
        *,
        name: str = "memory",
        signing: Signing | None = None,
        heartbeat: bool = True,
    ) -> None:
        self.name = name
        self.signing = signing
        self.codec = mavlink2.MAVLink(None, srcSystem=GCS_SYSID, srcComponent=GCS_COMPID)
        if signing is not None:
            signing.apply(self.codec, outgoing=True)
        self.ignored = 0  # packets dropped: a spoofed sender, a bad or missing signature
        self.signature_refusals = 0
        self.last_refusal = ""  # why the latest packet was refused for its signature
        self._transport: ByteTransport | None = transport
        self._loop = asyncio.get_running_loop()
        self._parsers: Recent[Peer, Any] = Recent(self._loop.time)
        self._handlers: dict[int, Handler] = {}
        self._listeners: list[Handler] = []
        self._speakers: dict[int, _Speaker] = {}
        self.pinned: set[int] = set()
        """System ids that keep their address through a silence (registered vehicles)."""
        self.contested: dict[int, Contest] = {}
        transport.set_receiver(self._received)
        self._heartbeat = asyncio.ensure_future(self._send_heartbeats()) if heartbeat else None

    @classmethod
    async def open(
        cls,
        url: str | Endpoint,
        *,
        signing: Signing | None = None,
        opener: TransportOpener = open_transport,
    ) -> MavConnection:
        """Open the transport a connection string names (a socket, unless `opener` says)."""
        endpoint = url if isinstance(url, Endpoint) else Endpoint.parse(url)
        transport = await opener(endpoint)
        return cls(transport, name=str(endpoint), signing=signing)

    @property
    def dropped(self) -> int:
        """Every packet not taken: by the transport (wrong address) or by us."""
        transport_ignored = self._transport.ignored if self._transport is not None else 0
        return self.ignored + transport_ignored

    # --- receiving ---------------------------------------------------------------------

    def _new_parser(self) -> Any:
        parser = mavlink2.MAVLink(None)
        parser.robust_parsing = True
        if self.signing is not None:
            self.signing.apply(parser, outgoing=False)
        return parser

    def _received(self, data: bytes, peer: Peer) -> None:
        parser = self._parsers.touch(peer, self._new_parser)
        for msg in parser.parse_buffer(data) or ():
            if msg.get_type() == "BAD_DATA":
                if self.signing is not None and _is_packet(msg):
                    self._refused(msg, parser)
                continue
            if self._admitted(msg, peer):
                self._dispatch(msg)

    def _refused(self, bad: Message, parser: Any) -> None:
        assert self.signing is not None
        self.ignored += 1
        self.signature_refusals += 1
        self.last_refusal = why_refused(
            bytes(bad.data), self.signing.key, int(parser.signing.timestamp)
        )

    def refusals(self) -> str:
        """What signature refusals there were, as a clause for an error ("" if none)."""
        if not self.signature_refusals:
            return ""
        return (
            f"; {self.signature_refusals} packets were refused for their signature, the "
            f"latest {self.last_refusal}"
        )

    def _admitted(self, msg: Message, peer: Peer) -> bool:
        """True unless the message claims a system that speaks from another address."""
        sysid, now = msg.get_srcSystem(), self._loop.time()
        speaker = self._speakers.get(sysid)
        if speaker is None or speaker.peer == peer:
            if speaker is not None:
                speaker.heard = now
            elif msg.get_type() == "HEARTBEAT":
                self._speakers[sysid] = _Speaker(peer, now)
            return True
        if msg.get_type() == "HEARTBEAT" and self._may_move(sysid, speaker, now):
            self._speakers[sysid] = _Speaker(peer, now)  # the vehicle came back elsewhere
            self.contested.pop(sysid, None)
            return True
        self.ignored += 1
        contest = self.contested.get(sysid)
        if contest is None or contest.peer != peer:
            contest = self.contested[sysid] = Contest(peer, 0, now)
        contest.packets += 1
        contest.last = now
        return False

    def _may_move(self, sysid: int, speaker: _Speaker, now: float) -> bool:
        """A silent system may speak from elsewhere: any, unless pinned; a pinned one
        only with a valid signature (every packet that reaches here on a signed
        connection has one)."""
        silent = now - speaker.heard > RELOCK_AFTER_S
        return silent and (sysid not in self.pinned or self.signing is not None)

    def relock(self, sysid: int, peer: Peer) -> None:
        """The operator's word: `sysid` speaks from `peer` from now on."""
        self._speakers[sysid] = _Speaker(peer, self._loop.time())
        self.contested.pop(sysid, None)

    def _dispatch(self, msg: Message) -> None:
        handler = self._handlers.get(msg.get_srcSystem())
        if handler is not None:
            handler(msg)
        for listener in list(self._listeners):
            listener(msg)

    def attach(self, sysid: int, handler: Handler) -> None:
        """Send every message from `sysid` to `handler` (one handler per system id)."""
        self._handlers[sysid] = handler

    def detach(self, sysid: int) -> None:
        self._handlers.pop(sysid, None)

    def listen(self, handler: Handler) -> Callable[[], None]:
        """Also see every message from every system (discovery); returns the remover."""
        self._listeners.append(handler)
        return lambda: self._listeners.remove(handler)

    def systems(self) -> list[int]:
        """Every system id that has sent a HEARTBEAT here."""
        return sorted(self._speakers)

    # --- sending -----------------------------------------------------------------------

    def send(self, msg: Message, sysid: int | None = None) -> None:
        """Pack with our identity and send to the vehicle `sysid` (or to every peer)."""
        if self._transport is None:
            return
        data = self._pack(msg)
        speaker = self._speakers.get(sysid) if sysid is not None else None
        if speaker is not None:
            self._transport.send(data, speaker.peer)
            return
        for target in self._transport.peers():
            self._transport.send(data, target)

    def _pack(self, msg: Message) -> bytes:
        """Packed with our identity; signed with a current timestamp, as ArduPilot keeps
        its own (pymavlink adds one tick a packet, which falls behind the clock: after a
        minute a receiver that starts listening refuses the stream)."""
        if self.signing is not None:
            self.codec.signing.timestamp = max(self.codec.signing.timestamp, signing_now())
        return bytes(msg.pack(self.codec))

    async def _send_heartbeats(self) -> None:
        beat = self.codec.heartbeat_encode(
            mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, mavlink2.MAV_STATE_ACTIVE
        )
        while True:
            if self._transport is not None:
                data = self._pack(beat)
                speakers = (speaker.peer for speaker in self._speakers.values())
                for target in dict.fromkeys([*self._transport.peers(), *speakers]):
                    self._transport.send(data, target)
            self._parsers.expire()
            await asyncio.sleep(HEARTBEAT_PERIOD_S)

    async def close(self) -> None:
        if self._heartbeat is not None:
            self._heartbeat.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._heartbeat
            self._heartbeat = None
        if self._transport is not None:
            self._transport.close()
            self._transport = None


def _is_packet(bad: Message) -> bool:
    """A BAD_DATA that held a whole packet (refused for its signature), not line noise."""
    return "signature" in str(getattr(bad, "reason", "")).lower()
