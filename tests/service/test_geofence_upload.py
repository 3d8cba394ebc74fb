"""A flight on a geographic scenario sets up its fence and rally points on every vehicle
with the missions (issue 26, item 4): the service's upload writes and verifies them and
enables the fence with the service's FENCE_ACTION; a flight on a grid scenario uploads
no fence; a vehicle that refuses its fence refuses the flight's upload, its mission and
parameters untouched."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from gcs.mavlink.mission_protocol import MISSION_TYPE_FENCE, MISSION_TYPE_RALLY
from gcs.mission.fence import fence_items, fence_of, rally_items
from gcs.mission.geographic import load_geographic
from planner.cases import load_case
from planner.model.scenario import Scenario
from sitl_mock import Faults, Simulator
from tests.geographic import field, point, polygon, rectangle
from tests.inprocess.flying import bind, register, upload_once_online
from tests.inprocess.service import InProcessService
from tests.inprocess.vehicles import SimulatedVehicles

pytestmark = [pytest.mark.virtual_clock]
GEOJSON = {"Content-Type": "application/geo+json"}


def fenced_field() -> dict[str, Any]:
    document = field(zones=[polygon(rectangle(120, 60, 180, 140), role="no-fly", name="barn")])
    document["features"].append(point(40, 170, role="rally", name="gate"))
    return document


async def flight_on(
    gcs: InProcessService, document: dict[str, Any] | None, faults: Faults | None = None
) -> tuple[Simulator, str]:
    """A planned flight bound to a vehicle at its start; (simulator, flight id)."""
    if document is None:
        created = await gcs.client.post("/scenarios", json=_grid_case())
    else:
        body = json.dumps(document).encode()
        created = await gcs.client.post("/scenarios", content=body, headers=GEOJSON)
    assert created.status_code == 201, created.text
    scenario = Scenario(**created.json()["scenario"])
    planned = await gcs.client.post(f"/scenarios/{created.json()['id']}/plans", json={"wait_s": 30})
    assert planned.status_code == 201, planned.text
    sim = await gcs.vehicles.at_starts(scenario, faults)
    ids = [await register(gcs.client, sim.connection_string(s)) for s in sim.sysids]
    return sim, await bind(gcs.client, planned.json()["id"], scenario, ids)


def _grid_case() -> dict[str, Any]:
    return load_case("case-1").model_dump(mode="json")


@pytest.fixture
async def gcs_land(tmp_path: Path, vehicles: SimulatedVehicles) -> Any:
    """The service with FENCE_ACTION 2 (always land) as its setting."""
    service = InProcessService(tmp_path / "data", vehicles, fence_action=2)
    await service.start()
    yield service
    await service.stop()


async def test_a_geographic_flight_uploads_its_fence_and_rally_points(gcs_land) -> None:
    document = fenced_field()
    sim, flight_id = await flight_on(gcs_land, document)
    answer = await upload_once_online(gcs_land.client, flight_id)
    assert answer["flight"]["state"] == "uploaded", answer
    fence = fence_of(load_geographic(document))
    stored = sim.mission(1, MISSION_TYPE_FENCE)
    assert [(i.command, i.param1, i.x, i.y) for i in stored] == [
        (s.command, s.params[0], s.x, s.y) for s in fence_items(fence)
    ]
    assert [i.command for i in stored].count(5002) == 4  # the barn, excluded
    rally = sim.mission(1, MISSION_TYPE_RALLY)
    altitude = next(i.z for i in sim.mission(1) if i.command == 22)  # the flight's, above home
    assert [(i.x, i.y, i.z) for i in rally] == [
        (r.x, r.y, r.z) for r in rally_items(fence, altitude)
    ]
    params = sim.vehicle(1).params
    assert [params.get(n) for n in ("FENCE_ENABLE", "FENCE_TYPE", "FENCE_ACTION")] == [1, 4, 2]
    assert len(sim.mission(1)) > 3  # and the mission itself


async def test_a_grid_flight_uploads_no_fence(gcs: InProcessService) -> None:
    sim, flight_id = await flight_on(gcs, None)
    answer = await upload_once_online(gcs.client, flight_id)
    assert answer["flight"]["state"] == "uploaded", answer
    for sysid in sim.sysids:
        assert sim.mission(sysid, MISSION_TYPE_FENCE) == []
        assert sim.mission(sysid, MISSION_TYPE_RALLY) == []
        assert sim.vehicle(sysid).params.get("FENCE_ENABLE") == 0


async def test_a_refused_fence_refuses_the_upload_and_touches_nothing_else(
    gcs: InProcessService,
) -> None:
    sim, flight_id = await flight_on(
        gcs, fenced_field(), Faults(reject_missions=True, reject_at="last_item")
    )
    answer = await upload_once_online(gcs.client, flight_id)
    assert answer["flight"]["state"] == "upload_failed", answer
    (vehicle,) = answer["vehicles"]
    assert not vehicle["ok"]
    assert "fence upload failed, flight refused" in vehicle["detail"], vehicle
    assert sim.mission(1, MISSION_TYPE_FENCE) == [] and len(sim.mission(1)) <= 1
    assert sim.vehicle(1).params.get("FENCE_ENABLE") == 0
    started = await gcs.client.post(f"/flights/{flight_id}/start")
    assert started.status_code == 409, started.text
