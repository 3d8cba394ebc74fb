"""The operator stays in control (issue 10), over real HTTP against a real `mvo-gcs serve`:
what needs a real server process. The rest of issue 10's tests run in process, on the
virtual clock, in tests/service/test_operator_control.py.

- Deleting a scenario while it is planned: the plan runs in a planning process, in real
  time, while the service waits (bounded) for its cancellation before deleting.
- A restart after a crash (kill -9): the flight is interrupted, and abort still works.

Times are never asserted.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from planner.cases import load_case
from tests.e2e.flying import Flight, fleet_at_starts, wait_for
from tests.inprocess.vehicles import FAST_BOOT
from tests.service_process import ServiceProcess

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServiceProcess]:
    proc = ServiceProcess(tmp_path_factory.mktemp("operator") / "data")
    proc.start()
    yield proc
    proc.stop()
    assert not [p for p in proc.problems() if "Traceback" in p or '" 500' in p]


@pytest.fixture
def client(service: ServiceProcess) -> Iterator[httpx.Client]:
    with service.client() as c:
        yield c


# --- nothing an open flight uses can be deleted --------------------------------------------


def test_deleting_a_scenario_cancels_its_planning_first(client: httpx.Client) -> None:
    scenario = load_case("case-6")
    sid = client.post("/scenarios", json=scenario.model_dump(mode="json")).json()["id"]
    job = client.post(
        f"/scenarios/{sid}/plans", json={"iterations": 50_000, "population": 30, "wait_s": 0}
    )
    assert job.status_code == 202, job.text
    before = _metric(client, 'mvo_gcs_plans_total{outcome="cancelled"}')
    assert client.delete(f"/scenarios/{sid}").status_code == 204
    assert _metric(client, 'mvo_gcs_plans_total{outcome="cancelled"}') == before + 1
    assert client.get(f"/jobs/{job.json()['id']}").status_code == 404


# --- a restart keeps the operator in control -------------------------------------------------


def _abort_lands_everyone(flight: Flight) -> dict:
    answer = flight.post("abort", mode="land")
    assert answer.status_code == 200, answer.text
    body = answer.json()
    assert body["flight"]["state"] == "aborting", body
    assert [v["ok"] for v in body["vehicles"]] == [True] * len(flight.vehicle_ids), body
    wait_for(lambda: flight.modes() == {"LAND"}, 30, "every vehicle in LAND")
    flight.wait_state("aborted")
    assert not flight.airborne()
    return body


def test_after_a_restart_the_flight_is_interrupted_and_abort_still_works(
    tmp_path: Path,
) -> None:
    service = ServiceProcess(tmp_path / "data")
    service.start()
    try:
        with fleet_at_starts(load_case("case-6"), speedup=10.0, **FAST_BOOT).running() as sim:
            with service.client() as client:
                flight = Flight.make(client, sim, "case-6")
                flight.fly()
                # Held, so that they are still up however long the restart takes on a busy
                # machine (flying on, they may land first; the flight then rightly ends).
                assert flight.post("pause").is_success
            service.kill()  # as a crash would: no clean shutdown
            service.start()
            with service.client() as client:
                flight.client = client
                assert flight.state() == "interrupted"
                events = client.get(f"/flights/{flight.id}/events", params={"limit": 10000})
                said = [e["data"] for e in events.json() if e["kind"] == "FlightState"]
                assert said[-1]["state"] == "interrupted", said  # in its history too
                assert said[-1]["note"] == "the service restarted"
                live = client.get(f"/flights/{flight.id}/live-state").json()
                wait_for(
                    lambda: all(
                        v["online"] and v["armed"]
                        for v in client.get(f"/flights/{flight.id}/live-state").json()["vehicles"]
                    ),
                    30,
                    "vehicles re-attached",
                )
                assert live["state"] == "interrupted"

                def paused() -> list[dict]:  # nobody followed them: each mission is paused
                    got = client.get(f"/flights/{flight.id}/events", params={"limit": 10000})
                    return [e for e in got.json() if e["kind"] == "UnfollowedPaused"]

                # Each is told of: paused again where the operator's hold left it in its
                # mission (AUTO), found braked where the mission would not pause or where
                # its GCS failsafe braked it while the service was down (BRAKE).
                wait_for(lambda: len(paused()) == len(sim.sysids), 30, "missions paused")
                refused = flight.post("upload")
                assert refused.status_code == 409, refused.text
                _abort_lands_everyone(flight)
    finally:
        service.stop()


# --- helpers --------------------------------------------------------------------------------


def _metric(client: httpx.Client, name: str) -> float:
    for line in client.get("/metrics").text.splitlines():
        if line.startswith(name + " "):
            return float(line.split()[-1])
    return 0.0
