"""A plan's mission files (`GET /plans/{id}/missions`, `.../{uav}.plan`, `.waypoints`):
made once per plan and options, off the event loop, and kept (issue 28, "Readers can
starve the operator").

Each reader used to validate the plan, pace every mission (`flight_plan`: seconds for a
large plan) and render its answer; 40 readers of a 100-UAV plan held the operator's abort
for 17.8 s. Here the computations are counted: many identical readers cost one, at most
one runs at a time, a refusal (409, 422) is answered as before, a deleted plan is 404 and
leaves nothing behind, and the cache is bounded.
"""

from __future__ import annotations

import asyncio
import json
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any

import pytest

import gcs.mission.flight_plan as flight_plan_module
from gcs.mavlink.mission_item import Autopilot
from gcs.mission.files import plan_text, waypoints_text
from gcs.mission.flight_plan import UnsafeSpeed
from planner.cases import load_case
from planner.model.plan import Plan
from planner.model.scenario import Scenario
from tests.inprocess.service import InProcessService, until

CASE_VI = load_case("case-6").model_dump(mode="json")
ORIGINAL = flight_plan_module.flight_plan


class Computations:
    """Every call of `flight_plan` made by the service (wherever it imported it from):
    how many, and how many ran at once at most. `hold_s`: a call waits up to that long
    (real seconds) for another to run beside it, so that calls that may overlap do."""

    def __init__(self, hold_s: float = 0.0) -> None:
        self.calls = 0
        self.running = 0
        self.peak = 0
        self.hold_s = hold_s
        self._lock = threading.Lock()
        self._joined = threading.Condition(self._lock)

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        with self._lock:
            self.calls += 1
            self.running += 1
            self.peak = max(self.peak, self.running)
            self._joined.notify_all()
            if self.hold_s:
                self._joined.wait_for(lambda: self.running > 1, self.hold_s)
        try:
            return ORIGINAL(*args, **kwargs)
        finally:
            with self._lock:
                self.running -= 1


@pytest.fixture
def computations(monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[..., Computations]]:
    def patch(hold_s: float = 0.0) -> Computations:
        counter = Computations(hold_s)
        for name, module in list(sys.modules.items()):
            if name.startswith("gcs.") and getattr(module, "flight_plan", None) is ORIGINAL:
                monkeypatch.setattr(module, "flight_plan", counter)
        return counter

    yield patch


async def planned(gcs: InProcessService, scenario: dict[str, Any] = CASE_VI) -> tuple[str, str]:
    """A scenario and its plan, through the API: (scenario id, plan id)."""
    sid = (await gcs.client.post("/scenarios", json=scenario)).json()["id"]
    answer = await gcs.client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30})
    assert answer.status_code == 201, answer.text
    return sid, answer.json()["id"]


async def stored_plan(gcs: InProcessService, plan_id: str) -> Plan:
    return Plan(**(await gcs.client.get(f"/plans/{plan_id}")).json()["plan"])


@pytest.mark.virtual_clock
async def test_identical_concurrent_readers_share_one_computation(
    gcs: InProcessService, computations: Callable[..., Computations]
) -> None:
    _, pid = await planned(gcs)
    counted = computations()
    paths = [
        f"/plans/{pid}/missions",
        f"/plans/{pid}/missions/uav1.plan",
        f"/plans/{pid}/missions/uav3.waypoints",
    ] * 8
    answers = await asyncio.gather(*(gcs.client.get(p) for p in paths))
    assert [a.status_code for a in answers] == [200] * len(paths), answers[0].text
    assert counted.calls == 1
    for path, answer in zip(paths, answers, strict=True):
        assert answer.content == answers[paths.index(path)].content

    again = await asyncio.gather(*(gcs.client.get(p) for p in paths[:3]))
    assert [a.content for a in again] == [a.content for a in answers[:3]]
    assert counted.calls == 1  # kept: later readers cost nothing either

    # the answers are those of the missions a flight would fly, as before
    scenario, plan = Scenario(**CASE_VI), await stored_plan(gcs, pid)
    autopilots = dict.fromkeys((u.id for u in plan.uavs), Autopilot.ARDUPILOT)
    flight = ORIGINAL(plan, scenario, autopilots)
    items = json.loads(answers[0].content)
    assert [m["uav_id"] for m in items] == list(flight.missions)
    for mission in items:
        expected = flight.missions[mission["uav_id"]].items
        assert len(mission["items"]) == len(expected)
        assert [i["command"] for i in mission["items"]] == [i.command for i in expected]
        assert [(i["x"], i["y"]) for i in mission["items"]] == [(i.x, i.y) for i in expected]
    assert answers[1].text == plan_text(flight.missions["uav1"], flight.notes("uav1"))
    assert answers[1].headers["content-type"] == "application/json"
    assert answers[2].text == waypoints_text(flight.missions["uav3"])
    assert answers[2].headers["content-type"] == "text/plain; charset=utf-8"
    assert answers[2].headers["content-disposition"] == 'attachment; filename="uav3.waypoints"'


@pytest.mark.virtual_clock
async def test_refusals_answer_as_before_once_computed(
    gcs: InProcessService, computations: Callable[..., Computations]
) -> None:
    _, pid = await planned(gcs)
    _, no_origin = await planned(gcs, {**CASE_VI, "origin": None})
    counted = computations()

    # 422: a speed the plan cannot be kept safe at, with the highest one it can
    scenario, plan = Scenario(**CASE_VI), await stored_plan(gcs, pid)
    with pytest.raises(UnsafeSpeed) as refused:
        ORIGINAL(
            plan,
            scenario,
            dict.fromkeys((u.id for u in plan.uavs), Autopilot.ARDUPILOT),
            max_speed_m_s=20.0,
        )
    counted.calls = 0
    fast = [
        f"/plans/{pid}/missions?max_speed_m_s=20",
        f"/plans/{pid}/missions/uav2.plan?max_speed_m_s=20",
        f"/plans/{pid}/missions/uav9.plan?max_speed_m_s=20",  # 422 before the UAV's 404
    ] * 3
    answers = await asyncio.gather(*(gcs.client.get(p) for p in fast))
    assert {a.status_code for a in answers} == {422}
    body = answers[0].json()
    assert body == {
        "detail": str(refused.value),
        "highest_safe_speed_m_s": refused.value.highest_safe_m_s,
    }
    assert all(a.json() == body for a in answers)
    assert counted.calls == 1

    # 409: a plan that cannot be flown (no origin); 404: no such UAV, no such plan
    unflyable = await asyncio.gather(
        *(gcs.client.get(f"/plans/{no_origin}/missions/uav1.plan") for _ in range(3))
    )
    assert {a.status_code for a in unflyable} == {409}
    assert unflyable[0].json() == {"detail": "scenario 'case-6' has no origin: it cannot be flown"}
    assert counted.calls == 2
    unknown = await gcs.client.get(f"/plans/{pid}/missions/uav9.waypoints")
    assert unknown.status_code == 404
    assert unknown.json() == {"detail": f"no UAV in plan {pid} with id 'uav9'"}
    missing = await gcs.client.get("/plans/nosuchplan/missions")
    assert missing.status_code == 404
    assert missing.json() == {"detail": "no plan with id 'nosuchplan'"}
    invalid = await gcs.client.get(f"/plans/{pid}/missions?altitude_m=0")
    assert invalid.status_code == 422 and "altitude_m" in invalid.text
    assert counted.calls == 3  # the defaults, for the 404 of uav9


@pytest.mark.virtual_clock
async def test_a_reader_who_gives_up_does_not_cancel_the_others(
    gcs: InProcessService, computations: Callable[..., Computations]
) -> None:
    _, pid = await planned(gcs)
    counted = computations()
    impatient = asyncio.ensure_future(gcs.client.get(f"/plans/{pid}/missions"))
    patient = asyncio.ensure_future(gcs.client.get(f"/plans/{pid}/missions/uav2.plan"))
    kept = gcs.app.state.services.missions if gcs.app is not None else None
    assert kept is not None
    # both are waiting for it once it is under way: each joins as it finds the plan
    await until(lambda: len(kept) == 1, 1, "the computation under way", every=0.0005)
    assert counted.calls == 0
    impatient.cancel()
    answer = await patient
    assert answer.status_code == 200, answer.text
    assert impatient.cancelled() and counted.calls == 1
    assert (await gcs.client.get(f"/plans/{pid}/missions")).status_code == 200
    assert counted.calls == 1


@pytest.mark.virtual_clock
async def test_a_deleted_plan_is_404_and_nothing_of_it_is_kept(gcs: InProcessService) -> None:
    kept = gcs.app.state.services.missions if gcs.app is not None else None
    assert kept is not None
    sid, pid = await planned(gcs)
    second = await gcs.client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30})
    other = second.json()["id"]
    for plan_id in (pid, other):
        assert (await gcs.client.get(f"/plans/{plan_id}/missions/uav1.plan")).status_code == 200
    assert len(kept) == 2

    assert (await gcs.client.delete(f"/plans/{pid}")).status_code == 204
    assert len(kept) == 1
    gone = await gcs.client.get(f"/plans/{pid}/missions/uav1.plan")
    assert gone.status_code == 404 and gone.json() == {"detail": f"no plan with id {pid!r}"}

    assert (await gcs.client.delete(f"/scenarios/{sid}")).status_code == 204  # its plans too
    assert len(kept) == 0
    assert (await gcs.client.get(f"/plans/{other}/missions")).status_code == 404


@pytest.mark.virtual_clock
async def test_the_cache_is_bounded_least_recently_used_first(
    gcs: InProcessService, computations: Callable[..., Computations]
) -> None:
    assert gcs.app is not None
    kept = gcs.app.state.services.missions
    kept.max_entries = 3
    _, pid = await planned(gcs)
    counted = computations()

    async def read(altitude: int) -> None:
        answer = await gcs.client.get(f"/plans/{pid}/missions/uav1.plan?altitude_m={altitude}")
        assert answer.status_code == 200, answer.text

    for altitude in (10, 11, 12, 13):
        await read(altitude)
    assert counted.calls == 4 and len(kept) == 3
    await read(13)
    await read(11)
    assert counted.calls == 4  # still kept
    await read(10)  # the oldest was dropped: made again, and 12 (least recently read) goes
    assert counted.calls == 5 and len(kept) == 3
    await read(13)
    await read(11)
    assert counted.calls == 5
    await read(12)
    assert counted.calls == 6


async def test_at_most_one_computation_runs_at_once(
    gcs: InProcessService, computations: Callable[..., Computations]
) -> None:
    """On real threads (asyncio's own loop): readers asking for four different speeds
    wait for each other's computations instead of running four beside the loop."""
    _, pid = await planned(gcs)
    counted = computations(hold_s=0.3)  # would a second computation start meanwhile?
    speeds = (3, 4, 5, 6)
    answers = await asyncio.gather(
        *(gcs.client.get(f"/plans/{pid}/missions?max_speed_m_s={v}") for v in speeds)
    )
    assert [a.status_code for a in answers] == [200] * len(speeds)
    assert counted.calls == len(speeds)
    assert counted.peak == 1


@pytest.mark.virtual_clock
async def test_the_timing_at_a_speed_is_the_flights_own_and_is_kept(
    gcs: InProcessService, computations: Callable[..., Computations]
) -> None:
    """`GET /plans/{id}/timing`: the flight a plan makes at the options, timed as flights
    are (each arrival, whom each UAV lets pass first), kept like the mission files but
    apart from them (the missions alone do not time most flights)."""
    _, pid = await planned(gcs)
    scenario, plan = Scenario(**CASE_VI), await stored_plan(gcs, pid)
    autopilots = dict.fromkeys((u.id for u in plan.uavs), Autopilot.ARDUPILOT)
    counted = computations()
    for speed in (5.0, 10.0):
        flight = ORIGINAL(plan, scenario, autopilots, max_speed_m_s=speed)
        counted.calls = 0
        path = f"/plans/{pid}/timing?max_speed_m_s={speed:g}"
        answers = await asyncio.gather(*(gcs.client.get(path) for _ in range(3)))
        assert [a.status_code for a in answers] == [200] * 3, answers[0].text
        assert counted.calls == 1  # three readers, one computation
        body = answers[0].json()
        assert body["max_speed_m_s"] == speed
        assert body["duration_s"] == pytest.approx(flight.duration_s, abs=0.01)
        arrivals = {u["uav_id"]: u["arrival_s"] for u in body["uavs"]}
        timed = {uav: t.arrival_s for uav, t in flight.timed.items()}
        assert arrivals == pytest.approx(timed, abs=0.01)
        assert max(arrivals.values()) == body["duration_s"]
        leaders = {u["uav_id"]: u["lets_pass_first"] for u in body["uavs"]}
        assert leaders == {
            uav: sorted({w.leader for w in flight.order.waits.get(uav, [])}) for uav in timed
        }
        assert any(leaders.values())  # case VI: someone lets another pass first
        missions = await gcs.client.get(f"/plans/{pid}/missions?max_speed_m_s={speed:g}")
        assert missions.status_code == 200
        assert counted.calls == 2  # the missions are made apart from the timing
        assert (await gcs.client.get(path)).content == answers[0].content
        assert counted.calls == 2  # kept


@pytest.mark.virtual_clock
async def test_the_timing_refuses_as_the_missions_do(gcs: InProcessService) -> None:
    """422 for a speed the plan cannot be kept safe at (with the highest one it can) or an
    invalid option, 409 for a plan that cannot be flown, 404 for no such plan."""
    _, pid = await planned(gcs)
    _, no_origin = await planned(gcs, {**CASE_VI, "origin": None})
    fast = await gcs.client.get(f"/plans/{pid}/timing?max_speed_m_s=20")
    missions = await gcs.client.get(f"/plans/{pid}/missions?max_speed_m_s=20")
    assert fast.status_code == missions.status_code == 422
    assert fast.json() == missions.json()
    assert fast.json()["highest_safe_speed_m_s"] < 20
    unflyable = await gcs.client.get(f"/plans/{no_origin}/timing")
    assert unflyable.status_code == 409
    assert unflyable.json() == {"detail": "scenario 'case-6' has no origin: it cannot be flown"}
    missing = await gcs.client.get("/plans/nosuchplan/timing")
    assert missing.status_code == 404
    assert missing.json() == {"detail": "no plan with id 'nosuchplan'"}
    invalid = await gcs.client.get(f"/plans/{pid}/timing?max_speed_m_s=0")
    assert invalid.status_code == 422 and "max_speed_m_s" in invalid.text
