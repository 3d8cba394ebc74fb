"""Property-based tests of the whole API from its own OpenAPI schema (schemathesis's
command line, which runs its examples, coverage, fuzzing and stateful phases): no 5xx,
every status code documented, every answer matching its schema, invalid data refused."""

from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

import httpx

from gcs.service.states import FlightState
from planner.cases import load_case
from tests.e2e.flying import Flight, fleet_at_starts
from tests.inprocess.vehicles import FAST_BOOT
from tests.service_process import TOKEN, ServiceProcess

# `positive_data_acceptance` is left out on purpose: a scenario can be valid by its JSON
# schema and still be refused (422) by rules a schema cannot state (cells inside the grid,
# reachable goals, the evaluation budget of a plan request).
CHECKS_LEFT_OUT = "positive_data_acceptance"
MAX_EXAMPLES = 15
"""Examples per operation of the fuzzing and stateful phases on the empty service. The
coverage phase (its size set by the schema, not by this) already sends each of the 41
operations its boundary and invalid values, 1769 requests; fuzzing at 15 adds about 550
more (at 30 about 1090, 16 s of the test's 31 s on an idle machine; the stateful phase
costs 3 s either way)."""


def run_schemathesis(
    url: str, cwd: Path, max_examples: int, phases: str = "examples,coverage,fuzzing,stateful"
) -> subprocess.CompletedProcess[str]:
    """Schemathesis's command line against `url`; it reads `schemathesis.toml` in `cwd`."""
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "schemathesis.cli",
            "run",
            f"{url}/openapi.json",
            "--header",
            f"Authorization: Bearer {TOKEN}",
            "--checks",
            "all",
            "--exclude-checks",
            CHECKS_LEFT_OUT,
            "--phases",
            phases,
            "--max-examples",
            str(max_examples),
            "--seed",
            "1",
            "--workers",
            "1",
            "--request-timeout",
            "60",
        ],
        capture_output=True,
        text=True,
        timeout=400,
        cwd=cwd,
    )


def assert_passed(run: subprocess.CompletedProcess[str]) -> None:
    assert run.returncode == 0, run.stdout[-6000:] + run.stderr[-2000:]
    assert " passed" in run.stdout and "failure" not in run.stdout.split("SUMMARY")[-1]


def test_schemathesis_finds_no_server_error_and_no_schema_violation(tmp_path: Path) -> None:
    service = ServiceProcess(
        tmp_path / "data",
        {"MVO_GCS_MAX_PLAN_EVALUATIONS": "20000", "MVO_GCS_INLINE_PLAN_WAIT_S": "0"},
    )
    service.start()
    try:
        run = run_schemathesis(service.url, tmp_path, max_examples=MAX_EXAMPLES)
    finally:
        service.stop()
    assert_passed(run)


class DeletionWatch(threading.Thread):
    """Polls, while schemathesis runs, that nothing the open flight uses has gone.

    A resource found missing and then the flight found still open means it was deleted
    while the flight was open; the other order cannot give a false alarm."""

    def __init__(self, client: httpx.Client, flight_id: str, used: list[str]) -> None:
        super().__init__(daemon=True)
        self.client, self.flight_id, self.used = client, flight_id, used
        self.stop = threading.Event()
        self.open_polls = 0
        self.deleted_while_open: list[str] = []

    def run(self) -> None:
        while not self.stop.wait(0.2):
            missing = [p for p in self.used if self.client.get(p).status_code == 404]
            state = self.client.get(f"/flights/{self.flight_id}")
            if state.status_code == 200 and FlightState(state.json()["state"]).is_open:
                self.open_polls += 1
                self.deleted_while_open += missing


def test_schemathesis_on_a_service_with_a_flight_in_the_air(tmp_path: Path) -> None:
    """The same checks with every path parameter fixed to something that exists (a
    scenario, its plan and job, registered vehicles, a flight paused in the air), so that
    the operator's commands, uploads and deletions are tried on an open flight. The
    stateful phase is left out: fixed identifiers override the ones its links carry."""
    service = ServiceProcess(tmp_path / "data", {"MVO_GCS_MAX_PLAN_EVALUATIONS": "20000"})
    service.start()
    # Slow enough that the flight stays open a while after the fuzzer aborts it.
    sim = fleet_at_starts(load_case("case-1"), speedup=10.0, **FAST_BOOT)
    try:
        with sim.running(), service.client() as client, service.client() as watch_client:
            flight = Flight.make(client, sim)
            flight.fly()
            assert flight.post("pause").is_success
            fixed = {
                "scenario_id": flight.scenario_id,
                "plan_id": flight.plan["id"],
                "job_id": client.get("/jobs").json()[0]["id"],
                "flight_id": flight.id,
                "vehicle_id": flight.vehicle_ids[0],
                "uav_id": flight.scenario.uavs[0].id,
            }
            (tmp_path / "schemathesis.toml").write_text(
                "[parameters]\n" + "".join(f'"path.{k}" = "{v}"\n' for k, v in fixed.items())
            )
            used = [f"/scenarios/{flight.scenario_id}", f"/plans/{flight.plan['id']}"]
            watch = DeletionWatch(
                watch_client, flight.id, used + [f"/vehicles/{v}" for v in flight.vehicle_ids]
            )
            watch.start()
            run = run_schemathesis(service.url, tmp_path, 10, "examples,coverage,fuzzing")
            watch.stop.set()
            watch.join(timeout=30)
    finally:
        service.stop()
    assert_passed(run)
    assert watch.open_polls > 0, "the flight was never seen open"
    assert watch.deleted_while_open == []
    assert service.problems() == []
