"""Simulated vehicles for the ground station's integration tests: in memory on the virtual
clock (`simulator`, `links`: for tests marked `virtual_clock`, the flight logic's), or on
loopback sockets in wall-clock time (`socket_simulator`, `socket_links`: for the tests of
the transports themselves)."""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from dataclasses import replace
from typing import Any

import pytest

from gcs.mavlink import client
from gcs.mavlink.link import LinkSettings, VehicleLink
from gcs.mavlink.mission_item import Autopilot, Command, Frame, Mission, MissionItem
from sitl_mock import Faults, Simulator, VehicleConfig
from tests.inprocess.vehicles import SimulatedVehicles

CMAC = (-35.363262, 149.165237, 584.0)
FLAVOURS = {"ardupilot": Autopilot.ARDUPILOT, "px4": Autopilot.PX4}
FAST_LINK = LinkSettings(connect_timeout_s=5.0, link_timeout_s=1.0)

SimFactory = Callable[..., Simulator]
Start = Callable[..., Awaitable[Simulator]]
Connect = Callable[..., Awaitable[VehicleLink]]


def vehicle(
    sysid: int,
    autopilot: str = "ardupilot",
    transport: str = "udp",
    home: tuple[float, float, float] = CMAC,
    faults: Faults | None = None,
) -> VehicleConfig:
    offset = (sysid - 1) * 0.0003  # ~30 m apart
    return VehicleConfig(
        sysid=sysid,
        port=0,
        home=(home[0], home[1] + offset, home[2]),
        autopilot=autopilot,
        transport=transport,
        faults=faults or Faults(),
    )


@pytest.fixture
def simulator(request: pytest.FixtureRequest, vehicles: SimulatedVehicles) -> Start:
    """Start simulated vehicles in memory, on the test's virtual clock (vehicles and ground
    station on one clock, at speed-up 1); all stop when the test ends."""
    if request.node.get_closest_marker("virtual_clock") is None:
        raise pytest.UsageError(  # on asyncio's own loop, a flight would take its real time
            f"{request.node.nodeid}: in-memory vehicles need the virtual_clock marker"
        )

    async def start(configs: list[VehicleConfig], seed: int = 0) -> Simulator:
        return await vehicles.start([replace(c, transport="memory") for c in configs], seed)

    return start


@pytest.fixture
async def links(vehicles: SimulatedVehicles) -> AsyncIterator[Connect]:
    """Links to `simulator`'s vehicles over in-memory ports; all closed when the test ends."""
    opened: list[VehicleLink] = []

    async def connect(
        sim: Simulator, sysid: int, settings: LinkSettings = FAST_LINK, **kwargs: Any
    ) -> VehicleLink:
        link = await client.connect(
            sim.connection_string(sysid), settings=settings, opener=vehicles.open, **kwargs
        )
        opened.append(link)
        return link

    yield connect
    for link in opened:
        await link.close()


@pytest.fixture
def socket_simulator() -> Iterator[SimFactory]:
    """Start simulators on loopback sockets, each in a thread of its own and in wall-clock
    time (`speedup` times it); all stop when the test ends."""
    with contextlib.ExitStack() as stack:

        def start(configs: list[VehicleConfig], speedup: float = 20.0, seed: int = 0) -> Simulator:
            sim = Simulator(configs, speedup=speedup, seed=seed)
            stack.enter_context(sim.running())
            return sim

        yield start


@pytest.fixture
async def socket_links() -> AsyncIterator[Callable[..., object]]:
    """Connect VehicleLinks to `socket_simulator`'s vehicles; all closed when the test ends."""
    opened: list[VehicleLink] = []

    async def connect(
        sim: Simulator, sysid: int, settings: LinkSettings = FAST_LINK, **kwargs: Any
    ) -> VehicleLink:
        link = await client.connect(sim.connection_string(sysid), settings=settings, **kwargs)
        opened.append(link)
        return link

    yield connect
    for link in opened:
        await link.close()


def square_mission(autopilot: Autopilot, n_waypoints: int = 4, hold_s: float = 0.0) -> Mission:
    """A small closed mission around CMAC in the flavour's numbering."""
    lat, lon = round(CMAC[0] * 1e7), round(CMAC[1] * 1e7)
    items = [MissionItem(Command.NAV_TAKEOFF, z=10.0, x=lat, y=lon)]
    items.append(MissionItem(Command.DO_CHANGE_SPEED, Frame.MISSION, params=(1, 5.0, -1, 0)))
    for k in range(n_waypoints):
        items.append(
            MissionItem(
                Command.NAV_WAYPOINT,
                params=(hold_s, 0, 0, 0),
                x=lat + 100 * (k % 3),
                y=lon + 100 * k,
                z=10.0 + k,
            )
        )
    items.append(MissionItem(Command.NAV_LAND, x=lat, y=lon))
    if autopilot == Autopilot.ARDUPILOT:
        items.insert(0, MissionItem(Command.NAV_WAYPOINT, Frame.GLOBAL, x=lat, y=lon, z=CMAC[2]))
    return Mission(tuple(items), autopilot, CMAC)
