"""Sockets on the asyncio loop: a UDP endpoint that answers every recent peer, a TCP server
that accepts several clients, and a UDP output that sends to a listening ground station
(shared by every vehicle that names it). All hand raw bytes and a link key to callbacks.

The peer list expires on wall-clock time: it is a socket matter, not vehicle behaviour."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable, Hashable
from typing import Protocol

PacketHandler = Callable[[bytes, Hashable], None]

UDP_PEER_TIMEOUT_S = 10.0
"""Wall seconds a UDP peer keeps receiving after its last packet (a socket-level matter)."""
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
        self._peers: dict[tuple, float] = {}
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

    def datagram_received(self, data: bytes, addr: tuple) -> None:
        self._peers[addr] = time.monotonic()
        self._on_packet(data, ("udp", addr))

    def error_received(self, exc: Exception) -> None:
        """ICMP port unreachable from a departed peer: nothing to do."""

    def send(self, data: bytes) -> None:
        if self._transport is None or not self._peers:
            return
        cutoff = time.monotonic() - UDP_PEER_TIMEOUT_S
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
        self._tasks: set[asyncio.Task] = set()
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

    def datagram_received(self, data: bytes, addr: tuple) -> None:
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
    raise ValueError(f"transport must be 'udp' or 'tcp', got {kind!r}")


def connection_string(kind: str, host: str, port: int) -> str:
    """How a pymavlink client reaches the endpoint."""
    return f"udpout:{host}:{port}" if kind == "udp" else f"tcp:{host}:{port}"
