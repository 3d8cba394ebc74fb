"""The service in process: scenarios, plans, jobs, auth, bad input and restarts.

The in-process service plans on the loop (plan_workers=0): a plan is done before any
other request is served, so the tests about a job that is still running (its progress,
its cancellation, a restart while it runs) get a service with a planning process, as
`mvo-gcs serve` has. That process plans in real time while the loop's clock is virtual,
so they wait for the job on its live WebSocket, which hears every progress report as it
comes, never on the clock.
"""

from __future__ import annotations

import json
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import pytest
from httpx_ws import AsyncWebSocketSession

from planner.cases import load_case
from tests.inprocess.flying import LONG_PLAN
from tests.inprocess.service import InProcessService
from tests.inprocess.vehicles import SimulatedVehicles

pytestmark = [pytest.mark.virtual_clock]

CASE_VI = load_case("case-6").model_dump(mode="json")
FINAL = {"done", "failed", "cancelled", "interrupted"}


@pytest.fixture
async def planning(tmp_path: Path, vehicles: SimulatedVehicles) -> AsyncIterator[InProcessService]:
    """The service with one planning process: a long plan runs while requests are served."""
    service = InProcessService(tmp_path / "data", vehicles, plan_workers=1)
    await service.start()
    yield service
    await service.stop()


async def _next_job(
    ws: AsyncWebSocketSession, wanted: Callable[[dict[str, Any]], bool]
) -> dict[str, Any]:
    """The first job the live stream sends that is `wanted`; AssertionError if the job
    ends first."""
    while True:
        job: dict[str, Any] = await ws.receive_json()
        if wanted(job):
            return job
        assert job["state"] not in FINAL, job


def _progressing(job: dict[str, Any]) -> bool:
    return bool(job["state"] == "running" and job["percent"] > 0)


async def test_mutating_requests_need_the_token(gcs: InProcessService) -> None:
    async with gcs.anonymous() as anonymous, gcs.anonymous("wrong") as wrong:
        assert (await anonymous.post("/scenarios", json=CASE_VI)).status_code == 401
        assert (await wrong.post("/scenarios", json=CASE_VI)).status_code == 403
        assert (await anonymous.post("/scenarios/x/plans", json={})).status_code == 401
        assert (await anonymous.delete("/scenarios/x")).status_code == 401
        listed = await anonymous.get("/scenarios")  # reading is open
        assert listed.status_code == 200 and listed.json() == []


async def test_case_vi_is_planned_at_once_and_stored(gcs: InProcessService) -> None:
    client = gcs.client
    created = await client.post("/scenarios", json=CASE_VI)
    assert created.status_code == 201
    sid = created.json()["id"]
    answer = await client.post(f"/scenarios/{sid}/plans", json={"iterations": 100, "wait_s": 30})
    assert answer.status_code == 201, answer.text
    plan = answer.json()
    assert plan["plan"]["feasible"] is True
    assert [u["id"] for u in plan["plan"]["uavs"]] == ["uav1", "uav2", "uav3"]
    assert (await client.get(f"/plans/{plan['id']}")).json() == plan
    assert [p["id"] for p in (await client.get(f"/scenarios/{sid}/plans")).json()] == [plan["id"]]
    metrics = (await client.get("/metrics")).text
    assert 'mvo_gcs_plans_total{outcome="feasible"} 1.0' in metrics


async def test_a_long_plan_is_a_job_that_reports_progress_and_can_be_cancelled(
    planning: InProcessService,
) -> None:
    gcs = planning
    client = gcs.client
    sid = (await client.post("/scenarios", json=CASE_VI)).json()["id"]
    answer = await client.post(f"/scenarios/{sid}/plans", json=LONG_PLAN | {"wait_s": 0})
    assert answer.status_code == 202
    job_id = answer.json()["id"]
    assert answer.headers["location"] == f"/jobs/{job_id}"
    async with gcs.websocket(f"/jobs/{job_id}/live") as ws:
        running = await _next_job(ws, _progressing)
        assert 0 < running["percent"] < 100 and running["best_cost"] is not None
        assert (await client.post(f"/jobs/{job_id}/cancel")).status_code == 202
        done = await _next_job(ws, lambda job: job["state"] in FINAL)
    assert done["state"] == "cancelled" and done["plan_id"] is None
    assert (await client.get(f"/jobs/{job_id}")).json()["state"] == "cancelled"
    again = await client.post(f"/jobs/{job_id}/cancel")
    assert again.status_code == 409 and "cancelled" in again.json()["detail"]


async def test_bad_requests_get_a_4xx_that_says_what_and_where(gcs: InProcessService) -> None:
    client = gcs.client
    broken = await client.post(
        "/scenarios", content=b'{"grid": ', headers={"content-type": "application/json"}
    )
    assert broken.status_code == 422 and broken.json()["detail"][0]["type"] == "json_invalid"

    unknown = await client.post("/scenarios", json={**CASE_VI, "colour": "red"})
    assert unknown.status_code == 422
    assert unknown.json()["detail"][0]["loc"] == ["body", "colour"]

    outside = json.loads(json.dumps(CASE_VI))
    outside["uavs"][0]["goal"] = [40, 3]
    answer = await client.post("/scenarios", json=outside)
    assert answer.status_code == 422 and "uavs[0].goal" in answer.text

    walled = {
        "grid": {"width": 5, "height": 5},
        "uavs": [{"id": "a", "start": [0, 0], "goal": [4, 4]}],
        "obstacles": [[2, y] for y in range(5)],
    }
    answer = await client.post("/scenarios", json=walled)
    assert answer.status_code == 422 and "cannot be reached" in answer.text

    missing = await client.get("/scenarios/nope")
    assert missing.status_code == 404 and "nope" in missing.json()["detail"]
    assert (await client.post("/scenarios/nope/plans", json={})).status_code == 404
    assert (await client.get("/jobs/nope")).status_code == 404

    sid = (await client.post("/scenarios", json=CASE_VI)).json()["id"]
    bad_algorithm = await client.post(f"/scenarios/{sid}/plans", json={"algorithm": "pso"})
    assert bad_algorithm.status_code == 422 and "pso" in bad_algorithm.text
    too_big = await client.post(
        f"/scenarios/{sid}/plans",
        json={"population": 500, "iterations": 100_000, "time_budget_s": None},
    )
    assert too_big.status_code == 422 and "limit" in too_big.json()["detail"]
    too_long = await client.post(f"/scenarios/{sid}/plans", json={"time_budget_s": 500})
    assert too_long.status_code == 422 and "limit" in too_long.json()["detail"]

    huge = await client.post(
        "/scenarios",
        content=b"[" + b"0," * 600_000 + b"0]",
        headers={"content-type": "application/json"},
    )
    assert huge.status_code == 413


async def test_everything_survives_a_restart_and_a_running_job_is_marked_interrupted(
    planning: InProcessService,
) -> None:
    """A job still planning when the service stops is not lost, nor left `running` for
    ever, nor passed off as cancelled on request: it is `interrupted` at the next start."""
    gcs = planning
    client = gcs.client
    sid = (await client.post("/scenarios", json=CASE_VI)).json()["id"]
    short = await client.post(f"/scenarios/{sid}/plans", json={"iterations": 50, "wait_s": 0})
    async with gcs.websocket(f"/jobs/{short.json()['id']}/live") as ws:
        done = await _next_job(ws, lambda job: job["state"] == "done")
    plan = (await client.get(f"/plans/{done['plan_id']}")).json()
    assert plan["plan"]["feasible"], plan
    long = await client.post(f"/scenarios/{sid}/plans", json=LONG_PLAN | {"wait_s": 0})
    assert long.status_code == 202, long.text
    job_id = long.json()["id"]
    async with gcs.websocket(f"/jobs/{job_id}/live") as ws:
        await _next_job(ws, _progressing)
    await gcs.restart()
    client = gcs.client
    assert (await client.get(f"/scenarios/{sid}")).json()["scenario"] == CASE_VI
    assert (await client.get(f"/plans/{plan['id']}")).json() == plan
    job = (await client.get(f"/jobs/{job_id}")).json()
    assert job["state"] == "interrupted" and job["error"], job
