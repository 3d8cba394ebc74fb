"""The suite's event loops: a test marked `virtual_clock` (and its async fixtures) runs on
the virtual-time loop, where the ground station and simulated vehicles share one clock
that jumps to the next timer whenever every task waits; every other async test runs on
asyncio's own loop."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Callable, Mapping

import pytest

from sitl_mock.virtual_time import VirtualTimeLoop
from tests.inprocess.vehicles import SimulatedVehicles


def pytest_asyncio_loop_factories(
    config: pytest.Config, item: pytest.Item
) -> Mapping[str, Callable[[], asyncio.AbstractEventLoop]]:
    if item.get_closest_marker("virtual_clock") is not None:
        return {"virtual": VirtualTimeLoop}
    return {"asyncio": asyncio.new_event_loop}


@pytest.fixture
async def vehicles() -> AsyncIterator[SimulatedVehicles]:
    """Simulated vehicles in the test's process (in-memory ports), stopped when it ends."""
    fleet = SimulatedVehicles()
    yield fleet
    await fleet.stop()
