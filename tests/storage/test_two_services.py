"""Several service processes, one database (issue 27, part 4), for real: two `mvo-gcs
serve` processes on one PostgreSQL database and mock vehicles both can reach. A flight is
controlled by the service that uploaded it; the other refuses requests for it with a 409
naming where it lives. The controlling process is killed (`kill -9`) mid-flight: the
other takes the flight over, nothing is uploaded again, its missions are paused (nobody
keeps the passing order) and then resumed by the survivor, from where each vehicle is:
the flight lands at its goals, and hold, continue and abort (land) work from the
survivor. A planning job is run by one service only.

How fast the takeover is, is bench/takeover_bench.py's business: nothing here is timed.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from sqlalchemy import create_engine, func, select

from gcs.service.storage.tables import JobRow, UploadRow
from planner.cases import load_case
from tests.e2e.flying import Flight, fleet_at_starts, online, wait_for
from tests.inprocess.vehicles import FAST_BOOT
from tests.storage.pair import pair, taken_over_by, wait_taken_over
from tests.storage.postgres import PostgresServer

pytestmark = pytest.mark.slow
SPEEDUP = 2.0  # slow enough that the vehicles are still flying when the takeover is done
# ArduCopter's boot squeezed: at 2x its 41.5 s to arm were 21 wall seconds of each flight
# test spent waiting before the take-off; the boot is not what is tested here.


@pytest.fixture
def database_url(postgres: PostgresServer) -> Iterator[str]:
    with postgres.database() as url:
        yield url


def test_the_survivor_takes_over_a_killed_services_flight(
    tmp_path: Path, database_url: str
) -> None:
    with (
        fleet_at_starts(load_case("case-6"), speedup=SPEEDUP, **FAST_BOOT).running() as sim,
        pair(tmp_path, database_url) as (a, b),
        a.client() as on_a,
        b.client() as on_b,
    ):
        flight = Flight.make(on_a, sim, "case-6")
        flight.fly()  # uploaded and started by a: a controls it
        wait_for(  # registered on a; b connects to them too, ready to take over
            lambda: all(online(on_b, v) for v in flight.vehicle_ids), 30, "b's links"
        )

        assert on_b.get(f"/flights/{flight.id}").json()["state"] == "flying"  # stored: anyone
        refused = on_b.post(f"/flights/{flight.id}/pause")
        assert refused.status_code == 409, refused.text
        assert "service a at " + a.url in refused.json()["detail"]
        assert on_b.get(f"/flights/{flight.id}/live-state").status_code == 409
        vehicle = flight.vehicle_ids[0]
        held_elsewhere = on_b.post(f"/vehicles/{vehicle}/hold")
        assert held_elsewhere.status_code == 409, held_elsewhere.text
        assert "service a at " + a.url in held_elsewhere.json()["detail"]

        a.kill()  # kill -9: no clean stop, no release
        wait_taken_over(on_b, flight.id, "b")
        assert flight.airborne(), "the vehicles landed before the takeover: slow the mock"
        flight.client = on_b
        note = on_b.get(f"/flights/{flight.id}").json()["note"]
        assert note.startswith("taken over by service b at " + b.url + " from a:"), note
        # Nobody keeps the passing order now: b pauses every mission still flown.
        every = len(flight.vehicle_ids)
        wait_for(lambda: len(_unfollowed_paused(on_b, flight.id)) == every, 30, "all paused", 0.5)
        assert all(e["ok"] for e in _unfollowed_paused(on_b, flight.id))

        wait_for(
            lambda: all(
                v["online"] for v in on_b.get(f"/flights/{flight.id}/live-state").json()["vehicles"]
            ),
            30,
            "the vehicles re-attached on b",
        )
        # b resumes it by itself once every vehicle is heard and paused (each stopped,
        # then let go in the passing order); the operator's hold and continue work on it.
        resumed = wait_for(lambda: _auto_resumed(on_b, flight.id), 60, "b's resume", 0.5)
        assert resumed["ok"], resumed
        held = flight.post("pause")
        assert held.status_code == 200, held.text
        assert [v["ok"] for v in held.json()["vehicles"]] == [True] * len(flight.vehicle_ids)
        assert flight.state() == "paused"
        continued = flight.post("continue")
        assert continued.status_code == 200, continued.text
        assert flight.wait_state("landed", "ended", "aborted") == "landed"
        assert not flight.airborne()
        assert taken_over_by(on_b, flight.id, "b") is not None
        separation = sim.min_separation()
        scenario = load_case("case-6")
        two_r = 2 * max(u.radius for u in scenario.uavs) * scenario.grid.cell_size_m
        assert separation is not None and separation.distance_m >= two_r, separation

    engine = create_engine(database_url)
    try:
        with engine.connect() as connection:
            uploads = connection.scalar(
                select(func.count()).select_from(UploadRow).where(UploadRow.flight_id == flight.id)
            )
            owners = set(connection.scalars(select(JobRow.owner_id)))
    finally:
        engine.dispose()
    assert uploads == len(flight.vehicle_ids)  # each mission once: nothing uploaded again
    assert owners == {"a"}  # the plan's job was claimed and run by a alone
    assert not [p for p in b.problems() if "Traceback" in p or '" 500' in p]


def _auto_resumed(client: httpx.Client, flight_id: str) -> dict[str, Any] | None:
    events = client.get(f"/flights/{flight_id}/events", params={"limit": 10000}).json()
    return next((e["data"] for e in events if e["kind"] == "AutoResumed"), None)


def _unfollowed_paused(client: httpx.Client, flight_id: str) -> list[dict[str, Any]]:
    events = client.get(f"/flights/{flight_id}/events", params={"limit": 10000}).json()
    return [e["data"] for e in events if e["kind"] == "UnfollowedPaused"]


def test_an_abort_under_way_is_carried_on_by_the_survivor(
    tmp_path: Path, database_url: str
) -> None:
    """The controller dies while its abort is under way: the survivor takes the
    `aborting` flight over, sends the abort again to every vehicle not yet down, and
    closes the flight once they all are."""
    with (
        fleet_at_starts(load_case("case-6"), speedup=SPEEDUP, **FAST_BOOT).running() as sim,
        pair(tmp_path, database_url) as (a, b),
        a.client() as on_a,
        b.client() as on_b,
    ):
        flight = Flight.make(on_a, sim, "case-6")
        flight.fly()
        aborted = flight.post("abort", mode="land")
        assert aborted.status_code == 200, aborted.text
        a.kill()
        wait_for(lambda: taken_over_by(on_b, flight.id, "b"), 60, "b to take the aborting flight")
        taken = taken_over_by(on_b, flight.id, "b")
        assert taken is not None and taken["data"]["state"] == "aborting", taken
        flight.client = on_b
        wait_for(lambda: flight.modes() == {"LAND"}, 30, "every vehicle in LAND")
        flight.wait_state("aborted")
        assert not flight.airborne()


def test_a_job_is_run_by_the_service_that_took_it(tmp_path: Path, database_url: str) -> None:
    """Plans asked of both services at once: each job is claimed once, by one of them."""
    scenario = load_case("case-1").model_dump(mode="json")
    with pair(tmp_path, database_url) as (a, b), a.client() as on_a, b.client() as on_b:
        sid = on_a.post("/scenarios", json=scenario).json()["id"]
        for client in (on_a, on_b, on_a, on_b):
            answer = client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30})
            assert answer.status_code == 201, answer.text
    engine = create_engine(database_url)
    try:
        with engine.connect() as connection:
            rows = list(connection.execute(select(JobRow.owner_id, JobRow.state)))
    finally:
        engine.dispose()
    assert sorted(rows) == [("a", "done"), ("a", "done"), ("b", "done"), ("b", "done")]
