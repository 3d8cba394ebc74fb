"""The service's own flows on PostgreSQL, in process with simulated vehicles on one
virtual clock: a scenario, its plan, a restart, vehicles, a flight uploaded and flown
to the landing, its events and uploads stored, another restart, and the deletes.

On SQLite the same flow is flown by tests/service (test_case_vi_flight.py,
test_api_basics.py), so it runs here on PostgreSQL only: seconds of suite time saved."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from planner.cases import load_case
from tests.inprocess.flying import bind, register, upload_once_online
from tests.inprocess.service import InProcessService, until
from tests.inprocess.vehicles import SimulatedVehicles

pytestmark = [pytest.mark.virtual_clock]


@pytest.fixture
async def gcs(
    tmp_path: Path, vehicles: SimulatedVehicles, database_url: str
) -> AsyncIterator[InProcessService]:
    service = InProcessService(tmp_path / "data", vehicles, database_url=database_url)
    await service.start()
    yield service
    await service.stop()


@pytest.mark.parametrize("database_url", ["postgresql"], indirect=True)
async def test_plan_fly_restart_and_delete(gcs: InProcessService) -> None:
    scenario = load_case("case-6")
    vehicles = await gcs.vehicles.at_starts(scenario)
    client = gcs.client
    sid = (await client.post("/scenarios", json=scenario.model_dump(mode="json"))).json()["id"]
    planned = await client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30})
    assert planned.status_code == 201, planned.text
    plan = planned.json()

    await gcs.restart()
    client = gcs.client
    assert (await client.get(f"/plans/{plan['id']}")).json() == plan
    assert [s["id"] for s in (await client.get("/scenarios")).json()] == [sid]
    ids = [await register(client, vehicles.connection_string(k)) for k in vehicles.sysids]
    fid = await bind(client, plan["id"], scenario, ids)

    uploaded = await upload_once_online(client, fid)
    assert uploaded["flight"]["state"] == "uploaded", uploaded
    started = await client.post(f"/flights/{fid}/start")
    assert started.status_code == 202, started.text

    async def over() -> bool:
        state = (await client.get(f"/flights/{fid}")).json()["state"]
        return state in ("landed", "ended", "aborted")

    await until(over, 600, "the flight's end")
    assert (await client.get(f"/flights/{fid}")).json()["state"] == "landed"
    events = (await client.get(f"/flights/{fid}/events", params={"limit": 10_000})).json()
    kinds = [e["kind"] for e in events]
    assert {"ItemReached", "VehicleFinished", "FlightEnded"} <= set(kinds), kinds
    page = (await client.get(f"/flights/{fid}/events", params={"after": events[1]["id"]})).json()
    assert page == events[2:]
    mission = await client.get(f"/flights/{fid}/missions/uav1.plan")
    assert mission.status_code == 200, mission.text

    await gcs.restart()
    client = gcs.client
    assert (await client.get(f"/flights/{fid}")).json()["state"] == "landed"
    stored = (await client.get(f"/flights/{fid}/events", params={"limit": 10_000})).json()
    assert stored == events
    assert (await client.get(f"/flights/{fid}/missions/uav1.plan")).text == mission.text

    assert (await client.delete(f"/flights/{fid}")).status_code == 204
    assert (await client.get(f"/flights/{fid}/events")).status_code == 404
    assert (await client.delete(f"/scenarios/{sid}")).status_code == 204
    assert (await client.get(f"/plans/{plan['id']}")).status_code == 404
