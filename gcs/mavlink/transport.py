"""Byte transports for the connection strings pymavlink's mavutil understands.

`udpout:host:port` sends to a vehicle listening there (it answers our source port),
`udpin:host:port` listens for vehicles (several may share the port, each answered at
the address it last spoke from) and `tcp:host:port` connects to a vehicle's TCP
server, reconnecting if the vehicle drops the connection (e.g. on reboot). All run on
the caller's asyncio loop: no threads, no blocking sockets.
"""

from __future__ import annotations

import asyncio
import contextlib
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

from gcs.mavlink.errors import LinkError

Peer = tuple[str, int] | None
"""Where bytes came from (UDP address); None for a TCP stream."""
OnBytes = Callable[[bytes, Peer], None]

TCP_RECONNECT_S = 0.5


@dataclass(frozen=True)
class Endpoint:
    kind: Literal["udpout", "udpin", "tcp"]
    host: str
    port: int

    @classmethod
    def parse(cls, url: str) -> Endpoint:
        """`udpout:127.0.0.1:14550` etc.; `udp:` is mavutil's alias of `udpin:`."""
        kind, _, rest = url.partition(":")
        host, _, port = rest.rpartition(":")
        kind = {"udp": "udpin"}.get(kind, kind)
        if kind not in ("udpout", "udpin", "tcp") or not host or not port.isdigit():
            raise LinkError(
                f"bad connection string {url!r}: expected udpout:HOST:PORT, "
                "udpin:HOST:PORT or tcp:HOST:PORT"
            )
        return cls(kind, host, int(port))  # type: ignore[arg-type]


class ByteTransport(ABC):
    """Sends and receives raw MAVLink bytes; subclasses own the socket."""

    @abstractmethod
    def send(self, data: bytes, peer: Peer = None) -> None: ...

    def peers(self) -> list[Peer]:
        """Every address worth sending a broadcast (a GCS heartbeat) to."""
        return [None]

    @abstractmethod
    def close(self) -> None: ...


class _Datagrams(asyncio.DatagramProtocol):
    def __init__(self, on_bytes: OnBytes) -> None:
        self.on_bytes = on_bytes

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        self.on_bytes(data, (addr[0], addr[1]))

    def error_received(self, exc: Exception) -> None:  # ICMP port unreachable etc.
        pass


class UdpTransport(ByteTransport):
    def __init__(self, transport: asyncio.DatagramTransport, remote: Peer) -> None:
        self._transport = transport
        self._remote = remote
        self._seen: dict[tuple[str, int], None] = {}

    def note_peer(self, peer: Peer) -> None:
        if peer is not None:
            self._seen[peer] = None

    def send(self, data: bytes, peer: Peer = None) -> None:
        target = peer or self._remote
        if target is None:
            for seen in self._seen:
                self._transport.sendto(data, seen)
        else:
            self._transport.sendto(data, target)

    def peers(self) -> list[Peer]:
        return [self._remote] if self._remote else list(self._seen)

    def close(self) -> None:
        self._transport.close()


async def _open_udp(endpoint: Endpoint, on_bytes: OnBytes) -> UdpTransport:
    loop = asyncio.get_running_loop()
    holder: list[UdpTransport] = []

    def received(data: bytes, peer: Peer) -> None:
        holder[0].note_peer(peer)
        on_bytes(data, peer)

    address = (endpoint.host, endpoint.port)
    try:
        if endpoint.kind == "udpout":
            transport, _ = await loop.create_datagram_endpoint(
                lambda: _Datagrams(received), local_addr=("0.0.0.0", 0)
            )
            holder.append(UdpTransport(transport, address))
        else:
            transport, _ = await loop.create_datagram_endpoint(
                lambda: _Datagrams(received), local_addr=address
            )
            holder.append(UdpTransport(transport, None))
    except OSError as exc:
        where = f"{endpoint.kind}:{endpoint.host}:{endpoint.port}"
        raise LinkError(f"cannot open {where}: {exc}") from exc
    return holder[0]


class _Stream(asyncio.Protocol):
    def __init__(self, on_bytes: OnBytes, lost: Callable[[], None]) -> None:
        self.on_bytes = on_bytes
        self.lost = lost

    def data_received(self, data: bytes) -> None:
        self.on_bytes(data, None)

    def connection_lost(self, exc: Exception | None) -> None:
        self.lost()


class TcpTransport(ByteTransport):
    """A TCP client that reconnects in the background while the vehicle is away."""

    def __init__(self, endpoint: Endpoint, on_bytes: OnBytes) -> None:
        self._endpoint = endpoint
        self._on_bytes = on_bytes
        self._transport: asyncio.Transport | None = None
        self._closed = False
        self._reconnecting: asyncio.Task[None] | None = None

    async def connect(self) -> None:
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_connection(
            lambda: _Stream(self._on_bytes, self._lost), self._endpoint.host, self._endpoint.port
        )
        self._transport = transport  # type: ignore[assignment]

    def _lost(self) -> None:
        self._transport = None
        if not self._closed:
            self._reconnecting = asyncio.ensure_future(self._reconnect())

    async def _reconnect(self) -> None:
        while not self._closed and self._transport is None:
            await asyncio.sleep(TCP_RECONNECT_S)
            with contextlib.suppress(OSError):
                await self.connect()

    def send(self, data: bytes, peer: Peer = None) -> None:
        if self._transport is not None:
            self._transport.write(data)

    def close(self) -> None:
        self._closed = True
        if self._reconnecting is not None:
            self._reconnecting.cancel()
        if self._transport is not None:
            self._transport.close()


async def open_transport(url: str, on_bytes: OnBytes) -> ByteTransport:
    """The transport a connection string names, already open."""
    endpoint = Endpoint.parse(url)
    if endpoint.kind != "tcp":
        return await _open_udp(endpoint, on_bytes)
    tcp = TcpTransport(endpoint, on_bytes)
    try:
        await tcp.connect()
    except OSError as exc:
        raise LinkError(f"cannot connect to {url}: {exc.strerror or exc}") from exc
    return tcp
