"""Links that cannot be spoofed (issue 12), against mock vehicles over loopback sockets.

A spoofer is a plain UDP socket on another local port that sends well-formed MAVLink
claiming to be the vehicle: a HEARTBEAT in GUIDED and a GLOBAL_POSITION_INT in London.
A signing vehicle's refusal of unsigned commands is no matter of sockets: it runs on the
virtual clock, the vehicle in memory, so its command timeouts are not waited for.
"""

from __future__ import annotations

import asyncio
import socket
from collections.abc import Callable, Iterator

import pytest

from gcs.mavlink import client
from gcs.mavlink.actions import FlightActions
from gcs.mavlink.connection import Signing
from gcs.mavlink.errors import CommandTimeoutError
from gcs.mavlink.link import LinkSettings, VehicleLink
from sitl_mock import VehicleConfig
from tests.impostor import forged
from tests.inprocess.vehicles import SimulatedVehicles

from .conftest import CMAC, FAST_LINK, vehicle

KEY = bytes(range(32))


@pytest.fixture
def spoofer() -> Iterator[socket.socket]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.2)
    yield sock
    sock.close()


def local_port(link: VehicleLink) -> int:
    transport = link.connection._transport
    return int(transport._transport.get_extra_info("sockname")[1])  # type: ignore[union-attr]


async def received_by_spoofer(sock: socket.socket, seconds: float) -> int:
    loop = asyncio.get_running_loop()
    deadline, count = loop.time() + seconds, 0
    while loop.time() < deadline:
        try:
            await asyncio.to_thread(sock.recv, 2048)
            count += 1
        except TimeoutError:
            pass
    return count


async def test_a_udpout_link_ignores_and_counts_a_spoofer(
    socket_simulator, socket_links, spoofer
) -> None:
    sim = socket_simulator([vehicle(1)])
    link = await socket_links(sim, 1)
    await _until(lambda: link.state.position is not None, 30.0)
    mode_before = link.state.mode
    for _ in range(5):
        spoofer.sendto(forged(1), ("127.0.0.1", local_port(link)))
    await _until(lambda: link.connection.dropped >= 5, 5.0)
    assert link.state.mode == mode_before != "GUIDED"
    assert link.state.position is not None and link.state.position.lat < 0  # not London
    await FlightActions(link).set_mode("LOITER")  # commands go to the vehicle only
    assert await received_by_spoofer(spoofer, 0.5) == 0


async def test_a_udpout_socket_binds_loopback(socket_simulator, socket_links) -> None:
    sim = socket_simulator([vehicle(1)])
    link = await socket_links(sim, 1)
    transport = link.connection._transport
    host = transport._transport.get_extra_info("sockname")[0]
    assert host == "127.0.0.1"


async def test_a_listening_link_keeps_the_address_that_proved_to_be_the_vehicle(
    socket_simulator, spoofer
) -> None:
    listen = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listen.bind(("127.0.0.1", 0))
    port = listen.getsockname()[1]
    listen.close()
    config = VehicleConfig(sysid=1, home=CMAC, transport="tcp", outputs=(f"udp:127.0.0.1:{port}",))
    sim = socket_simulator([config])
    link = await client.connect(f"udpin:127.0.0.1:{port}", settings=FAST_LINK)
    try:
        await _until(lambda: link.state.position is not None, 30.0)
        for _ in range(5):
            spoofer.sendto(forged(1), ("127.0.0.1", port))
        await _until(lambda: link.connection.dropped >= 5, 5.0)
        assert link.state.position is not None and link.state.position.lat < 0
        assert link.state.mode != "GUIDED"
        assert sim.state(1).mode == link.state.mode
    finally:
        await link.close()


@pytest.mark.virtual_clock
async def test_a_signing_vehicle_takes_commands_only_from_a_signing_link(
    simulator, vehicles: SimulatedVehicles
) -> None:
    sim = await simulator([VehicleConfig(sysid=1, home=CMAC, signing_key=KEY)])
    url, opener = sim.connection_string(1), vehicles.open
    settings = LinkSettings(connect_timeout_s=5.0, link_timeout_s=4.0, request_streams=False)
    unsigned = await client.connect(url, settings=settings, opener=opener)  # it hears the beats
    try:
        with pytest.raises(CommandTimeoutError):  # but the vehicle ignores what it says
            await FlightActions(unsigned).set_mode("LOITER")
        assert sim.rejected_packets(1) > 0
    finally:
        await unsigned.close()
    signed = await client.connect(url, settings=settings, signing=Signing(KEY), opener=opener)
    try:
        await FlightActions(signed).set_mode("LOITER")
        assert sim.state(1).mode == "LOITER"
    finally:
        await signed.close()


async def test_a_signing_link_ignores_unsigned_telemetry(socket_simulator, spoofer) -> None:
    sim = socket_simulator([VehicleConfig(sysid=1, home=CMAC, signing_key=KEY, transport="udp")])
    settings = LinkSettings(connect_timeout_s=5.0, link_timeout_s=4.0)
    link = await client.connect(sim.connection_string(1), settings=settings, signing=Signing(KEY))
    try:
        await _until(lambda: link.state.position is not None, 30.0)
        before = link.connection.dropped
        # Unsigned packets from the vehicle's own address are what a spoofer could send:
        # the transport already drops other addresses, so this reaches the signature check.
        link.connection._received(forged(1), link.connection._speakers[1].peer)
        assert link.connection.dropped == before + 2
        assert link.state.position is not None and link.state.position.lat < 0
    finally:
        await link.close()


async def _until(condition: Callable[[], bool], timeout: float) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while not condition():
        if loop.time() > deadline:
            raise AssertionError("condition not met in time")
        await asyncio.sleep(0.02)
