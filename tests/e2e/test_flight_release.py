"""A flight that has ended leaves nothing behind (issue 10, invariant 8).

In process (the service's app under Starlette's TestClient, mock vehicles on loopback),
so that the test can look at what the service holds: after 50 flights in a row the
links carry as many callbacks as before the first, no flight is kept live, and the
memory the service holds is flat.
"""

from __future__ import annotations

import gc
import tracemalloc
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from gcs.service.api.app import create_app
from gcs.service.settings import Settings
from planner.cases import load_case
from planner.scenario import Scenario
from tests.e2e.flying import fleet_at_starts, wait_for
from tests.service_process import TOKEN

FLIGHTS = 50
FLOWN = 2  # flown there and back; the others uploaded and cancelled


@pytest.fixture
def service(tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(
        data_dir=tmp_path / "data",
        token=TOKEN,
        discovery_url="",
        plan_workers=1,
        allowed_hosts=["testserver"],  # Starlette's TestClient's Host
    )
    with TestClient(create_app(settings)) as client:
        client.headers["Authorization"] = f"Bearer {TOKEN}"
        yield client


def test_fifty_flights_in_a_row_leave_callbacks_and_memory_flat(service: TestClient) -> None:
    services = service.app.state.services  # type: ignore[attr-defined]
    scenario = load_case("case-1")
    with fleet_at_starts(scenario).running() as sim:
        there, back = _plan(service, scenario), _plan(service, _reversed(scenario))
        ids = [
            service.post("/vehicles", json={"connection": sim.connection_string(k)}).json()["id"]
            for k in sim.sysids
        ]
        bindings = dict(zip(["uav1", "uav2"], ids, strict=True))
        wait_for(lambda: all(_online(service, v) for v in ids), 30, "vehicles online")
        links = [services.registry.link(v) for v in ids]
        before = [link.callback_count for link in links]
        tracemalloc.start()
        try:
            for k in range(FLIGHTS):
                plan = back if k == 1 else there  # the second flight flies home again
                _one_flight(service, plan, bindings, fly=k < FLOWN)
                assert [link.callback_count for link in links] == before, k
                assert not services.flights.book.active, k
                if k == 9:
                    first = _service_memory(service)
            last = _service_memory(service)
        finally:
            tracemalloc.stop()
    growth = sum(s.size_diff for s in last.compare_to(first, "filename"))
    top = "\n".join(str(s) for s in last.compare_to(first, "lineno")[:8])
    assert growth < 1_000_000, f"{growth / 1e6:.1f} MB more after 40 more flights:\n{top}"


def _service_memory(client: TestClient) -> tracemalloc.Snapshot:
    """What the service holds once its stored events are written, without the simulated
    vehicles that share the process (their tracks grow with simulated time)."""
    services = client.app.state.services  # type: ignore[attr-defined]
    client.portal.call(services.events.flush)  # type: ignore[union-attr]
    gc.collect()
    return tracemalloc.take_snapshot().filter_traces(
        [
            tracemalloc.Filter(False, "*/sitl_mock/*"),
            tracemalloc.Filter(False, "*/numpy/*"),
            tracemalloc.Filter(False, tracemalloc.__file__),
        ]
    )


def _plan(client: TestClient, scenario: Scenario) -> str:
    answer = client.post("/scenarios", json=scenario.model_dump(mode="json"))
    assert answer.status_code == 201, answer.text
    sid = answer.json()["id"]
    plan = client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30}).json()
    assert plan["plan"]["feasible"], plan
    return str(plan["id"])


def _reversed(scenario: Scenario) -> Scenario:
    uavs = [u.model_copy(update={"start": u.goal, "goal": u.start}) for u in scenario.uavs]
    return scenario.model_copy(update={"uavs": uavs, "name": f"{scenario.name} back"})


def _one_flight(client: TestClient, plan_id: str, bindings: dict[str, str], *, fly: bool) -> None:
    flight = client.post("/flights", json={"plan_id": plan_id, "bindings": bindings}).json()["id"]
    uploaded = client.post(f"/flights/{flight}/upload")
    assert uploaded.status_code == 200 and uploaded.json()["flight"]["state"] == "uploaded"
    if not fly:
        assert client.post(f"/flights/{flight}/cancel").json()["state"] == "cancelled"
        return
    assert client.post(f"/flights/{flight}/start").status_code == 202
    wait_for(lambda: _state(client, flight) in ("landed", "ended", "interrupted"), 120, "end")
    assert _state(client, flight) == "landed"


def _state(client: TestClient, flight: str) -> str:
    return str(client.get(f"/flights/{flight}").json()["state"])


def _online(client: TestClient, vehicle: str) -> bool:
    return bool(client.get(f"/vehicles/{vehicle}").json()["live"]["online"])
