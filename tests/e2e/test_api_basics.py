"""The service over real HTTP: scenarios, plans, jobs, auth, bad input and restarts."""

from __future__ import annotations

import json
import time

import httpx

from planner.cases import load_case
from tests.e2e.flying import wait_for
from tests.service_process import ServiceProcess

CASE_VI = load_case("case-6").model_dump(mode="json")
# The paper's flow with every iteration run: minutes of work, so it is still running
# whenever the test looks (the anytime default ends case VI within a tenth of a second).
LONG_PLAN = {
    "objective": "paper",
    "iterations": 20_000,
    "population": 60,
    "time_budget_s": None,
    "patience": None,
}


def _wait_job(client: httpx.Client, job_id: str, states: set[str], timeout: float = 60) -> dict:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job = client.get(f"/jobs/{job_id}").json()
        if job["state"] in states:
            return job
        time.sleep(0.1)
    raise AssertionError(f"job {job_id} never reached {states}: {job}")


def test_mutating_requests_need_the_token(service: ServiceProcess) -> None:
    with service.client(token=None) as anonymous, service.client("wrong") as wrong:
        assert anonymous.post("/scenarios", json=CASE_VI).status_code == 401
        assert wrong.post("/scenarios", json=CASE_VI).status_code == 403
        assert anonymous.post("/scenarios/x/plans", json={}).status_code == 401
        assert anonymous.delete("/scenarios/x").status_code == 401
        assert anonymous.get("/scenarios").status_code == 200  # reading is open
        assert anonymous.get("/scenarios").json() == []


def test_case_vi_is_planned_at_once_and_stored(service: ServiceProcess) -> None:
    with service.client() as client:
        created = client.post("/scenarios", json=CASE_VI)
        assert created.status_code == 201
        sid = created.json()["id"]
        answer = client.post(f"/scenarios/{sid}/plans", json={"iterations": 100, "wait_s": 30})
        assert answer.status_code == 201, answer.text
        plan = answer.json()
        assert plan["plan"]["feasible"] is True
        assert [u["id"] for u in plan["plan"]["uavs"]] == ["uav1", "uav2", "uav3"]
        assert client.get(f"/plans/{plan['id']}").json() == plan
        assert [p["id"] for p in client.get(f"/scenarios/{sid}/plans").json()] == [plan["id"]]
        metrics = client.get("/metrics").text
        assert 'mvo_gcs_plans_total{outcome="feasible"} 1.0' in metrics


def test_a_long_plan_is_a_job_that_reports_progress_and_can_be_cancelled(
    service: ServiceProcess,
) -> None:
    with service.client() as client:
        sid = client.post("/scenarios", json=CASE_VI).json()["id"]
        answer = client.post(
            f"/scenarios/{sid}/plans",
            json=LONG_PLAN | {"wait_s": 0},
        )
        assert answer.status_code == 202
        assert answer.headers["location"] == f"/jobs/{answer.json()['id']}"
        job = _wait_job(client, answer.json()["id"], {"running"})
        running = wait_for(
            lambda: (j := client.get(f"/jobs/{job['id']}").json())["percent"] > 0 and j,
            30,
            "a progress report",
        )
        assert 0 < running["percent"] < 100 and running["best_cost"] is not None
        assert client.post(f"/jobs/{job['id']}/cancel").status_code == 202
        done = _wait_job(client, job["id"], {"cancelled", "done", "failed"}, timeout=10)
        assert done["state"] == "cancelled" and done["plan_id"] is None
        again = client.post(f"/jobs/{job['id']}/cancel")
        assert again.status_code == 409 and "cancelled" in again.json()["detail"]


def test_bad_requests_get_a_4xx_that_says_what_and_where(service: ServiceProcess) -> None:
    with service.client() as client:
        broken = client.post(
            "/scenarios", content=b'{"grid": ', headers={"content-type": "application/json"}
        )
        assert broken.status_code == 422 and broken.json()["detail"][0]["type"] == "json_invalid"

        unknown = client.post("/scenarios", json={**CASE_VI, "colour": "red"})
        assert unknown.status_code == 422
        assert unknown.json()["detail"][0]["loc"] == ["body", "colour"]

        outside = json.loads(json.dumps(CASE_VI))
        outside["uavs"][0]["goal"] = [40, 3]
        answer = client.post("/scenarios", json=outside)
        assert answer.status_code == 422 and "uavs[0].goal" in answer.text

        walled = {
            "grid": {"width": 5, "height": 5},
            "uavs": [{"id": "a", "start": [0, 0], "goal": [4, 4]}],
            "obstacles": [[2, y] for y in range(5)],
        }
        answer = client.post("/scenarios", json=walled)
        assert answer.status_code == 422 and "cannot be reached" in answer.text

        missing = client.get("/scenarios/nope")
        assert missing.status_code == 404 and "nope" in missing.json()["detail"]
        assert client.post("/scenarios/nope/plans", json={}).status_code == 404
        assert client.get("/jobs/nope").status_code == 404

        sid = client.post("/scenarios", json=CASE_VI).json()["id"]
        bad_algorithm = client.post(f"/scenarios/{sid}/plans", json={"algorithm": "pso"})
        assert bad_algorithm.status_code == 422 and "pso" in bad_algorithm.text
        too_big = client.post(
            f"/scenarios/{sid}/plans",
            json={"population": 500, "iterations": 100_000, "time_budget_s": None},
        )
        assert too_big.status_code == 422 and "limit" in too_big.json()["detail"]
        too_long = client.post(f"/scenarios/{sid}/plans", json={"time_budget_s": 500})
        assert too_long.status_code == 422 and "limit" in too_long.json()["detail"]

        huge = client.post(
            "/scenarios",
            content=b"[" + b"0," * 600_000 + b"0]",
            headers={"content-type": "application/json"},
        )
        assert huge.status_code == 413


def test_everything_survives_a_restart_and_a_running_job_is_marked_interrupted(
    service: ServiceProcess,
) -> None:
    with service.client() as client:
        sid = client.post("/scenarios", json=CASE_VI).json()["id"]
        plan = client.post(f"/scenarios/{sid}/plans", json={"iterations": 50, "wait_s": 30})
        long = client.post(f"/scenarios/{sid}/plans", json=LONG_PLAN | {"wait_s": 0}).json()
        _wait_job(client, long["id"], {"running"})
    service.kill()
    service.start()
    with service.client() as client:
        assert client.get(f"/scenarios/{sid}").json()["scenario"] == CASE_VI
        assert client.get(f"/plans/{plan.json()['id']}").json() == plan.json()
        job = client.get(f"/jobs/{long['id']}").json()
        assert job["state"] == "interrupted" and job["error"]
