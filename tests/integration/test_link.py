"""The link against simulated vehicles: identity, streams, link loss, reboot, shared ports.

What the link makes of the vehicle's packets and silences runs on the virtual clock, the
vehicles in memory (tests marked `virtual_clock`); the transports themselves (UDP, TCP,
one UDP port shared by two vehicles) on loopback sockets, in wall-clock time."""

from __future__ import annotations

import asyncio

import pytest

from gcs.mavlink import client
from gcs.mavlink.connection import MavConnection
from gcs.mavlink.errors import ConnectTimeoutError, WaitTimeoutError
from gcs.mavlink.link import LinkSettings
from gcs.mavlink.mission_item import Autopilot
from gcs.mavlink.mission_protocol import MissionClient
from tests.inprocess.vehicles import SimulatedVehicles

from .conftest import FAST_LINK, square_mission, vehicle
from .udp_relay import UdpRelay


@pytest.mark.parametrize(("autopilot", "transport"), [("ardupilot", "udp"), ("px4", "tcp")])
async def test_link_learns_the_vehicle_and_asks_for_its_telemetry(
    socket_simulator, socket_links, autopilot: str, transport: str
) -> None:
    sim = socket_simulator([vehicle(7, autopilot, transport)])
    link = await socket_links(sim, 7)
    assert (link.sysid, link.compid) == (7, 1)
    assert link.autopilot == {"ardupilot": Autopilot.ARDUPILOT, "px4": Autopilot.PX4}[autopilot]
    # real ArduPilot streams nothing until asked: a position proves the request worked
    await link.wait_for("GLOBAL_POSITION_INT", lambda m: m.lat != 0, timeout=3.0)
    await link.wait_for("MISSION_CURRENT", timeout=2.0)
    state = link.state
    assert state.position is not None
    assert state.position.lat == pytest.approx(sim.state(7).lat, abs=1e-5)
    assert state.link_up and not state.armed
    assert state.mode == sim.state(7).mode


@pytest.mark.virtual_clock
async def test_waiting_is_bounded(simulator, links) -> None:
    sim = await simulator([vehicle(1)])
    link = await links(sim, 1)
    with pytest.raises(WaitTimeoutError, match="DEBUG_VECT"):
        await link.wait_for("DEBUG_VECT", timeout=0.2)


@pytest.mark.virtual_clock
async def test_connect_gives_up_when_no_autopilot_answers(
    simulator, vehicles: SimulatedVehicles
) -> None:
    sim = await simulator([vehicle(1)])
    settings = LinkSettings(connect_timeout_s=0.3)
    with pytest.raises(ConnectTimeoutError, match="autopilot 9"):
        await client.connect(
            sim.connection_string(1), sysid=9, settings=settings, opener=vehicles.open
        )


@pytest.mark.virtual_clock
async def test_link_goes_down_on_silence_and_comes_back_with_its_streams(simulator, links):
    sim = await simulator([vehicle(1)])
    link = await links(sim, 1)
    sim.silence(1, seconds=2.0)  # twice the link timeout (1 s)
    await _until(lambda: not link.state.link_up, 2.0)
    await _until(lambda: link.state.link_up, 4.0)
    await link.wait_for("GLOBAL_POSITION_INT", timeout=2.0)


@pytest.mark.virtual_clock
async def test_a_reboot_is_detected(simulator, links) -> None:
    sim = await simulator([vehicle(1)])
    link = await links(sim, 1)
    await MissionClient(link).upload(square_mission(link.autopilot))
    await _until(lambda: link.heartbeat_period_s is not None, 10.0)  # it knows the rate
    sim.reboot(1)
    await _until(lambda: link.state.reboots > 0, 5.0)
    assert link.state.reboots == 1
    assert not sim.mission(1)[1:], "the mock forgets its mission on reboot"
    await link.wait_for("GLOBAL_POSITION_INT", timeout=3.0)  # streams asked for again


async def test_several_vehicles_on_one_port_are_told_apart_by_sysid(socket_simulator) -> None:
    """Failure mode 10: one radio, two vehicles; each link sees only its own system id."""
    sim = socket_simulator([vehicle(1, "ardupilot"), vehicle(2, "px4")])
    async with UdpRelay([sim.port(1), sim.port(2)]) as relay:
        connection = await MavConnection.open(f"udpout:127.0.0.1:{relay.port}")
        try:
            first = await client.attach(connection, sysid=1, settings=FAST_LINK)
            second = await client.attach(connection, sysid=2, settings=FAST_LINK)
            assert (first.autopilot, second.autopilot) == (Autopilot.ARDUPILOT, Autopilot.PX4)
            missions = (square_mission(first.autopilot, 3), square_mission(second.autopilot, 5))
            await asyncio.gather(
                MissionClient(first).upload(missions[0]),
                MissionClient(second).upload(missions[1]),
            )
            assert len(sim.mission(1)) == len(missions[0])
            assert len(sim.mission(2)) == len(missions[1])
            assert first.state.sysid == 1 and second.state.sysid == 2
            await first.close()
            await second.close()
        finally:
            await connection.close()


async def _until(condition, timeout: float) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while not condition():
        assert loop.time() < deadline, "condition not met in time"
        await asyncio.sleep(0.02)
