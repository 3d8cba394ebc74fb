"""The suite's event loops: a test marked `virtual_clock` (and its async fixtures) runs on
the virtual-time loop, where the ground station and simulated vehicles share one clock
that jumps to the next timer whenever every task waits; every other async test runs on
asyncio's own loop.

Temporary files (every test's data directory, SQLite databases, the PostgreSQL cluster)
go to memory (/dev/shm) when it has room and TMPDIR names no other place: the tests'
databases commit hundreds of times a flight, and each commit's fsync on a disk costs
milliseconds of waiting that say nothing about the product (kill -9 restarts keep what
was written either way: the kernel holds it).

Property tests draw the same examples on every run (hypothesis's `suite` profile:
derandomized, no example database), so a run that fails replays as it failed, and a
clone's leftover database cannot replay an old failure into a new run (a loaded run
once failed that way). `HYPOTHESIS_PROFILE=explore` draws fresh examples each run and
keeps the failing ones, to look for new failures on purpose."""

from __future__ import annotations

import asyncio
import os
import shutil
import tempfile
from collections.abc import AsyncIterator, Callable, Mapping
from pathlib import Path

import pytest
from hypothesis import settings

from sitl_mock.virtual_time import VirtualTimeLoop
from tests.inprocess.vehicles import SimulatedVehicles

MEMORY = Path("/dev/shm")
MEMORY_NEEDED = 4 * 2**30
"""Free bytes /dev/shm must have to be used (a container's default 64 MB would not do)."""

settings.register_profile("suite", derandomize=True, database=None, deadline=None)
settings.register_profile("explore", deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "suite"))


def pytest_configure(config: pytest.Config) -> None:
    if "TMPDIR" in os.environ or not MEMORY.is_dir():
        return
    if shutil.disk_usage(MEMORY).free >= MEMORY_NEEDED:
        os.environ["TMPDIR"] = str(MEMORY)  # the service subprocesses' too
        tempfile.tempdir = None  # gettempdir() looks again


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
