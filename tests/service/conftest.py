"""The service in the test's own process, with simulated vehicles in memory; each module
here is marked `virtual_clock`, so all of it runs on one virtual clock."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from tests.inprocess.service import InProcessService
from tests.inprocess.vehicles import SimulatedVehicles


@pytest.fixture
async def gcs(tmp_path: Path, vehicles: SimulatedVehicles) -> AsyncIterator[InProcessService]:
    service = InProcessService(tmp_path / "data", vehicles)
    await service.start()
    yield service
    await service.stop()
