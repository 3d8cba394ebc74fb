"""A radio that puts several simulated vehicles behind one UDP port (failure mode 10)."""

from __future__ import annotations

import asyncio


class _Side(asyncio.DatagramProtocol):
    def __init__(self, relay: UdpRelay) -> None:
        self.relay = relay

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        self.relay.received(data, addr)


class UdpRelay:
    """Forwards the GCS's packets to every vehicle and every vehicle's packets to the GCS."""

    def __init__(self, vehicle_ports: list[int]) -> None:
        self.vehicles = [("127.0.0.1", port) for port in vehicle_ports]
        self.port = 0
        self._gcs: tuple[str, int] | None = None
        self._transport: asyncio.DatagramTransport | None = None

    async def __aenter__(self) -> UdpRelay:
        loop = asyncio.get_running_loop()
        self._transport, _ = await loop.create_datagram_endpoint(
            lambda: _Side(self), local_addr=("127.0.0.1", 0)
        )
        self.port = self._transport.get_extra_info("sockname")[1]
        return self

    async def __aexit__(self, *exc: object) -> None:
        if self._transport is not None:
            self._transport.close()

    def received(self, data: bytes, addr: tuple[str, int]) -> None:
        assert self._transport is not None
        if addr in self.vehicles:
            if self._gcs is not None:
                self._transport.sendto(data, self._gcs)
            return
        self._gcs = addr
        for target in self.vehicles:
            self._transport.sendto(data, target)
