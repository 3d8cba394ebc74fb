"""Byte transports under a MAVLink connection: UDP, TCP, and in memory.

A transport moves raw bytes; it knows nothing of MAVLink. The connection above it is
handed one (`MavConnection(transport)`), as httpx's client is handed a transport, so the
link, command and mission-protocol code runs unchanged over sockets or in memory. Who
opens transports for connection strings is injected too (`TransportOpener`): sockets in
production; in a simulated flight, in-memory ports of simulated vehicles, so that the
ground station and the vehicles run on one virtual clock.

Sockets bind where the connection string says and talk only to whom it names:
- `udpout:HOST:PORT` binds loopback when HOST is loopback (every interface otherwise,
  so the vehicle's answers can arrive) and accepts datagrams only from HOST:PORT;
  anything else is dropped and counted in `ignored`;
- `udpin:HOST:PORT` listens on HOST only; several vehicles may send to it, and the
  connection above decides which sender speaks for which system id;
- `tcp:HOST:PORT` connects to a vehicle's server and reconnects while it is away (a
  reboot drops the connection).
Everything runs on the caller's asyncio loop: no threads, no blocking sockets.
"""

from __future__ import annotations

import asyncio
import contextlib
from abc import ABC, abstractmethod
from collections.abc import Awaitable, Callable
from typing import Protocol

from gcs.mavlink.endpoint import Endpoint
from gcs.mavlink.errors import LinkError
from gcs.mavlink.recent import Recent

Peer = tuple[str, int] | None
"""Where bytes came from (UDP address); None for a stream (TCP, memory)."""
OnBytes = Callable[[bytes, Peer], None]

TCP_RECONNECT_S = 0.5


def _nowhere(data: bytes, peer: Peer) -> None:
    """The receiver of a transport nobody listens to yet."""


class ByteTransport(ABC):
    """Sends bytes to the vehicle side and hands what arrives to one receiver."""

    def __init__(self) -> None:
        self._receiver: OnBytes = _nowhere
        self.ignored = 0  # datagrams from an address this transport does not talk to

    def set_receiver(self, receiver: OnBytes) -> None:
        self._receiver = receiver

    def deliver(self, data: bytes, peer: Peer) -> None:
        self._receiver(data, peer)

    @abstractmethod
    def send(self, data: bytes, peer: Peer = None) -> None:
        """Send to `peer` (a UDP address), or to the one peer this transport talks to."""

    def peers(self) -> list[Peer]:
        """Every address worth sending a broadcast (a GCS heartbeat) to."""
        return [None]

    @abstractmethod
    def close(self) -> None: ...


class MemoryPort(Protocol):
    """The far end of an in-memory link: a simulated vehicle's port (sitl_mock's), or the
    other end of a `MemoryTransport.pair`. It delivers on a later loop iteration."""

    def send(self, data: bytes) -> None: ...

    def set_receiver(self, receiver: Callable[[bytes], None]) -> None: ...

    def close(self) -> None: ...


class MemoryTransport(ByteTransport):
    """Bytes to and from an in-memory port, arriving on a later loop iteration (as from a
    socket, so no handler runs inside its sender)."""

    def __init__(self, port: MemoryPort) -> None:
        super().__init__()
        self._port = port
        self.closed = False
        self.sent = 0
        port.set_receiver(self._arrive)

    @classmethod
    def pair(cls) -> tuple[MemoryTransport, MemoryTransport]:
        """Two transports wired to each other (a scripted peer on the far end)."""
        a, b = _WireEnd(), _WireEnd()
        a.other, b.other = b, a
        return cls(a), cls(b)

    def send(self, data: bytes, peer: Peer = None) -> None:
        if not self.closed:
            self.sent += 1
            self._port.send(bytes(data))

    def _arrive(self, data: bytes) -> None:
        if not self.closed:
            self.deliver(data, None)

    def close(self) -> None:
        self.closed = True
        self._port.close()


class _WireEnd:
    """One end of `MemoryTransport.pair`'s wire."""

    def __init__(self) -> None:
        self.other: _WireEnd | None = None
        self.receiver: Callable[[bytes], None] | None = None
        self.closed = False

    def set_receiver(self, receiver: Callable[[bytes], None]) -> None:
        self.receiver = receiver

    def send(self, data: bytes) -> None:
        other = self.other
        if other is not None and not other.closed and other.receiver is not None:
            asyncio.get_running_loop().call_soon(other.receiver, data)

    def close(self) -> None:
        self.closed = True


class _Datagrams(asyncio.DatagramProtocol):
    def __init__(self, on_datagram: Callable[[bytes, tuple[str, int]], None]) -> None:
        self.on_datagram = on_datagram

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        self.on_datagram(data, (addr[0], addr[1]))

    def error_received(self, exc: Exception) -> None:  # ICMP port unreachable etc.
        pass


class UdpTransport(ByteTransport):
    """A UDP socket; with a `remote`, it talks to that address only (udpout)."""

    def __init__(self, remote: Peer) -> None:
        super().__init__()
        self._remote = remote
        self._transport: asyncio.DatagramTransport | None = None
        self._seen: Recent[tuple[str, int], None] = Recent(asyncio.get_running_loop().time)
        """Who sent lately: a listening port's broadcast goes to them (bounded: anyone
        can send to a listening port)."""

    @classmethod
    async def open(cls, endpoint: Endpoint) -> UdpTransport:
        loop = asyncio.get_running_loop()
        address = (endpoint.host, endpoint.port)
        if endpoint.kind == "udpout":
            udp = cls(address)
            local = (_loopback_of if endpoint.is_loopback else _wildcard_of)(endpoint.host), 0
        else:
            udp, local = cls(None), address
        try:
            transport, _ = await loop.create_datagram_endpoint(
                lambda: _Datagrams(udp._datagram), local_addr=local
            )
        except OSError as exc:
            raise LinkError(f"cannot open {endpoint}: {exc.strerror or exc}") from exc
        udp._transport = transport
        return udp

    def _datagram(self, data: bytes, peer: tuple[str, int]) -> None:
        if self._remote is not None and peer[:2] != self._remote:
            self.ignored += 1
            return
        self._seen.touch(peer, lambda: None)
        self.deliver(data, peer)

    def send(self, data: bytes, peer: Peer = None) -> None:
        if self._transport is None:
            return
        target = peer or self._remote
        if target is not None:
            self._transport.sendto(data, target)
            return
        for seen in self._seen:
            self._transport.sendto(data, seen)

    def peers(self) -> list[Peer]:
        if self._remote:
            return [self._remote]
        self._seen.expire()
        return list(self._seen)

    def close(self) -> None:
        if self._transport is not None:
            self._transport.close()
            self._transport = None


def _loopback_of(host: str) -> str:
    return "::1" if ":" in host else "127.0.0.1"


def _wildcard_of(host: str) -> str:
    return "::" if ":" in host else "0.0.0.0"


class _Stream(asyncio.Protocol):
    def __init__(self, owner: TcpTransport) -> None:
        self.owner = owner

    def data_received(self, data: bytes) -> None:
        self.owner.deliver(data, None)

    def connection_lost(self, exc: Exception | None) -> None:
        self.owner._lost()


class TcpTransport(ByteTransport):
    """A TCP client that reconnects in the background while the vehicle is away."""

    def __init__(self, endpoint: Endpoint) -> None:
        super().__init__()
        self._endpoint = endpoint
        self._transport: asyncio.Transport | None = None
        self._closed = False
        self._reconnecting: asyncio.Task[None] | None = None

    @classmethod
    async def open(cls, endpoint: Endpoint) -> TcpTransport:
        tcp = cls(endpoint)
        try:
            await tcp._connect()
        except OSError as exc:
            raise LinkError(f"cannot connect to {endpoint}: {exc.strerror or exc}") from exc
        return tcp

    async def _connect(self) -> None:
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_connection(
            lambda: _Stream(self), self._endpoint.host, self._endpoint.port
        )
        if self._closed:
            transport.close()
            return
        self._transport = transport

    def _lost(self) -> None:
        self._transport = None
        if not self._closed:
            self._reconnecting = asyncio.ensure_future(self._reconnect())

    async def _reconnect(self) -> None:
        while not self._closed and self._transport is None:
            await asyncio.sleep(TCP_RECONNECT_S)
            with contextlib.suppress(OSError):
                await self._connect()

    def send(self, data: bytes, peer: Peer = None) -> None:
        if self._transport is not None:
            self._transport.write(data)

    def close(self) -> None:
        self._closed = True
        if self._reconnecting is not None:
            self._reconnecting.cancel()
        if self._transport is not None:
            self._transport.close()
            self._transport = None


TransportOpener = Callable[[Endpoint], Awaitable[ByteTransport]]
"""Opens the transport a connection string names (`open_transport`: sockets)."""


async def open_transport(endpoint: Endpoint) -> ByteTransport:
    """The socket transport an endpoint names, already open."""
    resolved = await endpoint.resolved()
    if resolved.kind == "tcp":
        return await TcpTransport.open(resolved)
    return await UdpTransport.open(resolved)
