"""`candidates` in a plan request: several seeds planned, the plan the vehicles fly soonest
kept (as `GET /plans/{id}/timing` times it), and refusals of what cannot be timed."""

from __future__ import annotations

from typing import Any

import pytest

from gcs.mission.flight_choice import WIDER_M
from gcs.service import planning_pool
from planner.experiments.scenario_generator import gap_swap_scenario
from planner.model.plan import Plan
from planner.model.scenario import Origin, Scenario
from planner.pipeline import PlannerSettings
from planner.pipeline import plan as plan_anyway
from tests.inprocess.service import InProcessService

pytestmark = pytest.mark.virtual_clock

SWAP = gap_swap_scenario(0, uavs=6).model_copy(
    update={"origin": Origin(lat=-35.36, lon=149.16, alt_m=584.0)}
)
"""Six UAVs through a gap: its first three candidates fly some twenty seconds apart at 5 m/s."""
DETERMINISTIC = {"time_budget_s": None, "wait_s": 60}


async def _plan(gcs: InProcessService, sid: str, **request: Any) -> dict[str, Any]:
    answer = await gcs.client.post(f"/scenarios/{sid}/plans", json={**DETERMINISTIC, **request})
    assert answer.status_code == 201, answer.text
    body: dict[str, Any] = answer.json()
    return body


async def _timed_s(gcs: InProcessService, plan_id: str, speed: float) -> float:
    answer = await gcs.client.get(f"/plans/{plan_id}/timing?max_speed_m_s={speed:g}")
    assert answer.status_code == 200, answer.text
    duration: float = answer.json()["duration_s"]
    return duration


async def test_of_three_seeds_the_plan_flown_soonest_is_kept(gcs: InProcessService) -> None:
    sid = (await gcs.client.post("/scenarios", json=SWAP.model_dump(mode="json"))).json()["id"]
    each = {}
    for k, seed in enumerate((1, 2, 3)):  # candidate k: the next seed, 0.5 m more clearance
        alone = await _plan(gcs, sid, seed=seed, clearance_m=1.3 + k * WIDER_M)
        assert alone["candidates"] is None
        each[seed] = await _timed_s(gcs, alone["id"], 5.0)
    assert len(set(each.values())) > 1, each  # otherwise there is nothing to choose
    chosen = await _plan(gcs, sid, seed=1, clearance_m=1.3, candidates=3, flight_speed_m_s=5.0)
    soonest = min(each, key=each.__getitem__)
    assert chosen["plan"]["seed"] == soonest
    assert await _timed_s(gcs, chosen["id"], 5.0) == each[soonest]
    trials = chosen["candidates"]  # what each came to, as each seed's own plan times
    assert [(t["seed"], t["duration_s"], t["kept"]) for t in trials] == [
        (seed, each[seed], seed == soonest) for seed in (1, 2, 3)
    ]
    assert [t["clearance_m"] for t in trials] == [1.3, 1.3 + WIDER_M, 1.3 + 2 * WIDER_M]
    assert all(t["refusal"] is None and t["same_as"] is None for t in trials)
    again = (await gcs.client.get(f"/plans/{chosen['id']}")).json()
    assert again["candidates"] == trials
    jobs = (await gcs.client.get("/jobs")).json()
    job = next(j for j in jobs if j["plan_id"] == chosen["id"])
    assert {"candidates": 3, "flight_speed_m_s": 5.0}.items() <= job["settings"].items()


async def test_candidates_share_the_time_budget(
    gcs: InProcessService, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Three candidates of a 3 s budget plan 1 s each, seeds 1 to 3; the job says what
    was asked for."""
    budgets: list[tuple[int, float | None]] = []

    def plan(scenario: Scenario, settings: PlannerSettings, progress: Any = None) -> Plan:
        budgets.append((settings.seed, settings.time_budget_s))
        return plan_anyway(scenario, settings, progress)

    monkeypatch.setattr(planning_pool, "plan", plan)
    sid = (await gcs.client.post("/scenarios", json=SWAP.model_dump(mode="json"))).json()["id"]
    chosen = await _plan(gcs, sid, candidates=3, time_budget_s=3.0)
    assert budgets == [(1, pytest.approx(1.0)), (2, pytest.approx(1.0)), (3, pytest.approx(1.0))]
    job = next(j for j in (await gcs.client.get("/jobs")).json() if j["plan_id"] == chosen["id"])
    assert job["settings"]["time_budget_s"] == 3.0 and job["settings"]["candidates"] == 3


async def test_candidates_need_an_origin_and_stay_within_bounds(gcs: InProcessService) -> None:
    nowhere = SWAP.model_copy(update={"origin": None}).model_dump(mode="json")
    sid = (await gcs.client.post("/scenarios", json=nowhere)).json()["id"]
    answer = await gcs.client.post(f"/scenarios/{sid}/plans", json={"candidates": 2})
    assert answer.status_code == 422
    assert "has no origin" in answer.json()["detail"]
    for bad in ({"candidates": 0}, {"candidates": 9}, {"flight_speed_m_s": 25}):
        answer = await gcs.client.post(f"/scenarios/{sid}/plans", json=bad)
        assert answer.status_code == 422, bad
        assert next(iter(bad)) in answer.text
    many = {"candidates": 8, "population": 500, "iterations": 1000, "time_budget_s": None}
    answer = await gcs.client.post(f"/scenarios/{sid}/plans", json=many)
    assert answer.status_code == 422 and "x candidates" in answer.json()["detail"]
