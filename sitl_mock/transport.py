"""The vehicles' ports on the asyncio loop: a UDP endpoint that answers every recent peer,
a TCP server that accepts several clients, a UDP output that sends to a listening ground
station (shared by every vehicle that names it), and an in-memory server whose clients
are plugged straight into a ground station's in-memory transport (a flight on one
virtual clock, with no sockets). All hand raw bytes and a link key to callbacks.

The UDP peer list expires on the loop's clock: it is a socket matter, not vehicle
behaviour."""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import Callable, Hashable
from typing import Any, Protocol

from .clock import loop_time

PacketHandler = Callable[[bytes, Hashable], None]

UDP_PEER_TIMEOUT_S = 10.0
"""Seconds a UDP peer keeps receiving after its last packet (a socket-level matter)."""
TCP_MAX_BUFFER = 1 << 20
"""Bytes queued for a slow TCP client before its packets are dropped (as a radio would)."""


class Endpoint(Protocol):
    port: int

    def send(self, data: bytes) -> None: ...

    async def close(self) -> None: ...


class UdpEndpoint(asyncio.DatagramProtocol):
    """Bound to host:port; replies to every address heard from in the last 10 s."""

    def __init__(self, on_packet: PacketHandler) -> None:
        self._on_packet = on_packet
        self._peers: dict[tuple[Any, ...], float] = {}
        self._transport: asyncio.DatagramTransport | None = None
        self.port = 0

    @classmethod
    async def open(cls, host: str, port: int, on_packet: PacketHandler) -> UdpEndpoint:
        loop = asyncio.get_running_loop()
        _, endpoint = await loop.create_datagram_endpoint(
            lambda: cls(on_packet), local_addr=(host, port)
        )
        return endpoint

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self._transport = transport  # type: ignore[assignment]
        self.port = transport.get_extra_info("sockname")[1]

    def datagram_received(self, data: bytes, addr: tuple[Any, ...]) -> None:
        self._peers[addr] = loop_time()
        self._on_packet(data, ("udp", addr))

    def error_received(self, exc: Exception) -> None:
        """ICMP port unreachable from a departed peer: nothing to do."""

    def send(self, data: bytes) -> None:
        if self._transport is None or not self._peers:
            return
        cutoff = loop_time() - UDP_PEER_TIMEOUT_S
        for addr, seen in list(self._peers.items()):
            if seen < cutoff:
                del self._peers[addr]
            else:
                self._transport.sendto(data, addr)

    async def close(self) -> None:
        if self._transport is not None:
            self._transport.close()


class TcpEndpoint:
    """A TCP server; every connected client receives everything the vehicle sends."""

    def __init__(self, on_packet: PacketHandler) -> None:
        self._on_packet = on_packet
        self._writers: dict[int, asyncio.StreamWriter] = {}
        self._server: asyncio.Server | None = None
        self._tasks: set[asyncio.Task[None]] = set()
        self.port = 0

    @classmethod
    async def open(cls, host: str, port: int, on_packet: PacketHandler) -> TcpEndpoint:
        endpoint = cls(on_packet)
        endpoint._server = await asyncio.start_server(endpoint._serve, host, port)
        endpoint.port = endpoint._server.sockets[0].getsockname()[1]
        return endpoint

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        key = id(writer)
        self._writers[key] = writer
        self._tasks.add(asyncio.current_task())  # type: ignore[arg-type]
        try:
            while data := await reader.read(65536):
                self._on_packet(data, ("tcp", key))
        except (ConnectionError, asyncio.CancelledError):
            pass
        finally:
            self._writers.pop(key, None)
            self._tasks.discard(asyncio.current_task())  # type: ignore[arg-type,unused-ignore]
            writer.close()

    def send(self, data: bytes) -> None:
        for writer in list(self._writers.values()):
            transport = writer.transport
            if transport.is_closing():
                continue
            if transport.get_write_buffer_size() < TCP_MAX_BUFFER:
                writer.write(data)

    async def close(self) -> None:
        if self._server is not None:
            self._server.close()
        for task in list(self._tasks):
            task.cancel()
        for writer in list(self._writers.values()):
            writer.close()
        if self._server is not None:
            await asyncio.wait_for(self._server.wait_closed(), timeout=2.0)


class MemoryPort:
    """One client's in-memory connection to a vehicle, as a TCP connection would be: what
    the client sends reaches the vehicle, and what the vehicle sends reaches the client,
    each on a later loop iteration (never inside its sender)."""

    def __init__(self, server: MemoryServer, key: Hashable) -> None:
        self._server = server
        self._key = key
        self._receiver: Callable[[bytes], None] | None = None
        self.closed = False

    def set_receiver(self, receiver: Callable[[bytes], None]) -> None:
        self._receiver = receiver

    def send(self, data: bytes) -> None:
        """From the client to the vehicle."""
        if not self.closed and not self._server.closed:
            asyncio.get_running_loop().call_soon(self._server.arrive, bytes(data), self._key)

    def deliver(self, data: bytes) -> None:
        """From the vehicle to the client."""
        if not self.closed and self._receiver is not None:
            asyncio.get_running_loop().call_soon(self._receive, data)

    def _receive(self, data: bytes) -> None:
        if not self.closed and self._receiver is not None:
            self._receiver(data)

    def close(self) -> None:
        self.closed = True
        self._server.forget(self._key)


class MemoryServer:
    """A vehicle's in-memory server: any number of clients connect (`connect`), each gets
    everything the vehicle sends, as from its TCP server. `port` is nominal (the one the
    vehicle would serve on), so a ground station can name it in a connection string."""

    _ids = itertools.count(1)

    def __init__(self, port: int, on_packet: PacketHandler) -> None:
        self.port = port
        self._on_packet = on_packet
        self._clients: dict[Hashable, MemoryPort] = {}
        self.closed = False

    def connect(self) -> MemoryPort:
        if self.closed:
            raise ConnectionRefusedError(f"the vehicle's port {self.port} is closed")
        key = ("memory", next(self._ids))
        port = self._clients[key] = MemoryPort(self, key)
        return port

    def arrive(self, data: bytes, key: Hashable) -> None:
        if not self.closed and key in self._clients:
            self._on_packet(data, key)

    def forget(self, key: Hashable) -> None:
        self._clients.pop(key, None)

    def send(self, data: bytes) -> None:
        for client in list(self._clients.values()):
            client.deliver(data)

    async def close(self) -> None:
        self.closed = True
        for client in list(self._clients.values()):
            client.closed = True
        self._clients.clear()


class UdpOutput(asyncio.DatagramProtocol):
    """`--out udp:HOST:PORT`: one socket that sends to a ground station listening there.

    Several vehicles share it, as they share a MAVProxy output: the ground station sees
    every system id arrive from one address and answers to it; what it sends back goes to
    every vehicle on the output, and each keeps what is addressed to it (target_system).
    """

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self._listeners: list[PacketHandler] = []
        self._transport: asyncio.DatagramTransport | None = None

    @classmethod
    async def open(cls, host: str, port: int) -> UdpOutput:
        loop = asyncio.get_running_loop()
        _, output = await loop.create_datagram_endpoint(
            lambda: cls(host, port), remote_addr=(host, port)
        )
        return output

    def subscribe(self, on_packet: PacketHandler) -> None:
        self._listeners.append(on_packet)

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self._transport = transport  # type: ignore[assignment]

    def datagram_received(self, data: bytes, addr: tuple[Any, ...]) -> None:
        for on_packet in self._listeners:
            on_packet(data, ("out", self.host, self.port))

    def error_received(self, exc: Exception) -> None:
        """Nobody listening there yet (ICMP port unreachable): keep sending, as SITL does."""

    def send(self, data: bytes) -> None:
        if self._transport is not None:
            self._transport.sendto(data)

    async def close(self) -> None:
        if self._transport is not None:
            self._transport.close()


def parse_output(text: str) -> tuple[str, int]:
    """`udp:HOST:PORT` (MAVProxy's --out form; `udpout:` is accepted too) to (host, port)."""
    kind, _, address = text.partition(":")
    host, _, port = address.rpartition(":")
    if kind not in ("udp", "udpout") or not host or not port.isdigit():
        raise ValueError(f"expected udp:HOST:PORT, got {text!r}")
    number = int(port)
    if not 1 <= number <= 65535:
        raise ValueError(f"port must be in 1..65535, got {number}")
    return host, number


async def open_endpoint(kind: str, host: str, port: int, on_packet: PacketHandler) -> Endpoint:
    if kind == "udp":
        return await UdpEndpoint.open(host, port, on_packet)
    if kind == "tcp":
        return await TcpEndpoint.open(host, port, on_packet)
    if kind == "memory":
        return MemoryServer(port, on_packet)
    raise ValueError(f"transport must be 'udp', 'tcp' or 'memory', got {kind!r}")


def connection_string(kind: str, host: str, port: int) -> str:
    """How a pymavlink client reaches the endpoint (a memory server stands in for TCP)."""
    return f"udpout:{host}:{port}" if kind == "udp" else f"tcp:{host}:{port}"
