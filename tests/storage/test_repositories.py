"""Every repository operation, the conditional state moves, the cascades and the restart
path (`Database.recover`, a reopened database), each on SQLite and on PostgreSQL."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from datetime import timedelta

import pytest
from sqlalchemy.exc import IntegrityError

from gcs.service.states import OPEN, FlightState, JobState, StateConflict
from gcs.service.storage import (
    Database,
    FlightRepository,
    JobRepository,
    NotFound,
    PlanRepository,
    ScenarioRepository,
    VehicleRepository,
)
from gcs.service.storage.tables import (
    EventRow,
    FlightRow,
    JobRow,
    PlanRow,
    ScenarioRow,
    UploadRow,
    VehicleRow,
)

F = FlightState
BODY = {"name": "s", "nested": {"cells": [[1, 2], [3.5, -4.25]], "ok": True}, "text": "ünï ✈"}


@pytest.fixture
def db(database_url: str) -> Iterator[Database]:
    database = Database(database_url)
    yield database
    database.close()


async def _scenario_with_plan(db: Database) -> tuple[str, str]:
    scenario = await ScenarioRepository(db).add(ScenarioRow(name="s", body=BODY))
    plan = await PlanRepository(db).add(PlanRow(scenario_id=scenario.id, feasible=True, body={}))
    return scenario.id, plan.id


async def _flight(db: Database, plan_id: str, state: FlightState = F.CREATED) -> str:
    row = FlightRow(plan_id=plan_id, bindings={"uav1": "v1"}, options={}, state=state.value)
    return str((await FlightRepository(db).add(row)).id)


async def test_generic_operations_get_page_count_add_update_delete(db: Database) -> None:
    scenarios = ScenarioRepository(db)
    added = [await scenarios.add(ScenarioRow(name=f"s{i}", body=BODY)) for i in range(5)]
    assert await scenarios.count() == 5
    got = await scenarios.get(added[2].id)
    assert (got.name, got.body) == ("s2", BODY)  # JSON round trip, unicode and floats
    assert [r.name for r in await scenarios.page(limit=2, offset=1)] == ["s1", "s2"]
    assert [r.name for r in await scenarios.page()] == [f"s{i}" for i in range(5)]
    assert (await scenarios.update(added[0].id, name="renamed")).name == "renamed"
    assert (await scenarios.get(added[0].id)).name == "renamed"
    await scenarios.delete(added[1].id)
    assert await scenarios.count() == 4
    for call in (scenarios.get, scenarios.delete):
        with pytest.raises(NotFound, match="no scenario with id 'nope'"):
            await call("nope")
    with pytest.raises(NotFound):
        await scenarios.update("nope", name="x")


async def test_plans_of_a_scenario(db: Database) -> None:
    sid, first = await _scenario_with_plan(db)
    plans = PlanRepository(db)
    second = await plans.add(PlanRow(scenario_id=sid, feasible=False, body={"paths": []}))
    other, _ = await _scenario_with_plan(db)
    assert [p.id for p in await plans.for_scenario(sid)] == [first, second.id]
    assert [p.id for p in await plans.for_scenario(sid, limit=1)] == [first]
    assert sorted(await plans.ids_for_scenario(sid)) == sorted([first, second.id])
    assert len(await plans.ids_for_scenario(other)) == 1
    assert (await plans.get(second.id)).feasible is False


async def test_jobs_update_move_and_list_unfinished(db: Database) -> None:
    sid, _ = await _scenario_with_plan(db)
    jobs = JobRepository(db)
    job = await jobs.add(JobRow(scenario_id=sid, settings={"seed": 1}))
    done = await jobs.add(JobRow(scenario_id=sid, settings={}, state=JobState.DONE.value))
    assert (job.state, job.percent) == ("queued", 0.0)
    updated = await jobs.update(job.id, percent=42.5, best_cost=1.25)
    assert (updated.percent, updated.best_cost) == (42.5, 1.25)
    assert updated.updated_at - job.updated_at >= timedelta(0)
    assert (await jobs.transition(job.id, JobState.RUNNING)).state == "running"
    assert [j.id for j in await jobs.unfinished_for_scenario(sid)] == [job.id]
    with pytest.raises(StateConflict):
        await jobs.transition(done.id, JobState.RUNNING)  # a late report reopens nothing
    assert (await jobs.transition(job.id, JobState.DONE, plan_id="p")).plan_id == "p"
    assert await jobs.unfinished_for_scenario(sid) == []


async def test_vehicles_one_per_endpoint_and_system_id(db: Database) -> None:
    vehicles = VehicleRepository(db)
    one = await vehicles.add(VehicleRow(name="a", connection="tcp:127.0.0.1:5760", sysid=1))
    two = await vehicles.add(VehicleRow(name="b", connection="tcp:127.0.0.1:5760", sysid=2))
    anyone = await vehicles.add(VehicleRow(name="c", connection="udpin:127.0.0.1:14551"))
    found = [
        await vehicles.by_connection("tcp:127.0.0.1:5760", 2),
        await vehicles.by_connection("tcp:127.0.0.1:5760", None),
        await vehicles.by_connection("udpin:127.0.0.1:14551", 7),
    ]
    assert [row.id if row else None for row in found] == [two.id, one.id, anyone.id]
    assert await vehicles.by_connection("tcp:127.0.0.1:5760", 3) is None
    assert await vehicles.by_connection("tcp:127.0.0.1:5770", 1) is None
    with pytest.raises(IntegrityError):
        await vehicles.add(VehicleRow(name="again", connection="tcp:127.0.0.1:5760", sysid=1))
    assert await vehicles.count() == 3  # the refused one left nothing behind


async def test_flights_move_list_events_and_uploads(db: Database) -> None:
    _, plan_id = await _scenario_with_plan(db)
    flights = FlightRepository(db)
    fid = await _flight(db, plan_id)
    closed = await _flight(db, plan_id, F.LANDED)
    moved = await flights.transition(fid, F.UPLOADING, "going up")
    assert (moved.state, moved.note, moved.updated_at is not None) == (
        "uploading",
        "going up",
        True,
    )
    with pytest.raises(StateConflict, match="is uploading: it cannot become landed"):
        await flights.transition(fid, F.LANDED)
    with pytest.raises(NotFound):
        await flights.transition("nope", F.UPLOADING)
    assert [f.id for f in await flights.open_flights()] == [fid]
    assert {f.id for f in await flights.for_plans([plan_id, "other"])} == {fid, closed}

    events = [EventRow(flight_id=fid, kind=f"K{i}", uav_id="uav1", data={"i": i}) for i in range(7)]
    await flights.record_events(events[:4])
    await flights.record_events(events[4:])
    stored = await flights.events(fid)
    assert [(e.kind, e.data) for e in stored] == [(f"K{i}", {"i": i}) for i in range(7)]
    page = await flights.events(fid, after=stored[2].id, limit=2)
    assert [e.kind for e in page] == ["K3", "K4"]
    assert await flights.events(closed) == []

    mission = {"items": [{"seq": 0, "x": 473977420, "y": 85455940, "z": 20.0}]}
    for uav in ("uav2", "uav1"):
        await flights.record_upload(
            UploadRow(flight_id=fid, uav_id=uav, vehicle_id="v", ok=True, items=1, mission=mission)
        )
    uploads = await flights.uploads(fid)
    assert [(u.uav_id, u.mission, u.detail) for u in uploads] == [
        ("uav2", mission, ""),
        ("uav1", mission, ""),
    ]


async def test_two_movers_cannot_both_win(db: Database) -> None:
    """The follower's "landed" and an operator's abort race on a flying flight: one
    conditional UPDATE each, and exactly one of them moves it (PostgreSQL's second
    UPDATE waits for the first's row lock, then finds the state changed)."""
    _, plan_id = await _scenario_with_plan(db)
    flights = FlightRepository(db)
    for _ in range(5):
        fid = await _flight(db, plan_id, F.FLYING)
        results = await asyncio.gather(
            flights.transition(fid, F.ABORTING),
            flights.transition(fid, F.LANDED),
            return_exceptions=True,
        )
        won = [r for r in results if isinstance(r, FlightRow)]
        assert len(won) == 1 and sum(isinstance(r, StateConflict) for r in results) == 1
        assert (await flights.get(fid)).state == won[0].state


async def test_deleting_a_scenario_takes_everything_under_it(db: Database) -> None:
    sid, plan_id = await _scenario_with_plan(db)
    fid = await _flight(db, plan_id)
    await JobRepository(db).add(JobRow(scenario_id=sid, settings={}))
    flights = FlightRepository(db)
    await flights.record_events([EventRow(flight_id=fid, kind="K", data={})])
    await flights.record_upload(
        UploadRow(flight_id=fid, uav_id="u", vehicle_id="v", ok=False, items=0)
    )
    kept_sid, kept_plan = await _scenario_with_plan(db)
    kept_flight = await _flight(db, kept_plan)
    await ScenarioRepository(db).delete(sid)
    counts = {
        repo.kind: await repo.count() for repo in (PlanRepository(db), JobRepository(db), flights)
    }
    assert counts == {"plan": 1, "job": 0, "flight": 1}
    assert await flights.events(fid) == [] and await flights.uploads(fid) == []
    assert (await flights.get(kept_flight)).plan_id == kept_plan
    assert (await ScenarioRepository(db).get(kept_sid)).body == BODY


async def test_a_restart_keeps_everything_and_interrupts_unfinished_work(database_url: str) -> None:
    """What the service's start does after a crash: reopen, then `recover`."""
    db = Database(database_url)
    sid, plan_id = await _scenario_with_plan(db)
    flight_ids = {state: await _flight(db, plan_id, state) for state in FlightState}
    jobs = JobRepository(db)
    job_ids = {
        state: (await jobs.add(JobRow(scenario_id=sid, settings={}, state=state.value))).id
        for state in JobState
    }
    await FlightRepository(db).record_events(
        [EventRow(flight_id=flight_ids[F.FLYING], kind="K", data={})]
    )
    db.close()

    db = Database(database_url)
    try:
        recovered = db.recover()
        unfinished = {JobState.QUEUED, JobState.RUNNING}
        assert recovered == {"jobs": len(unfinished), "flights": len(OPEN) - 1}
        assert db.recover() == {"jobs": 0, "flights": 0}  # a second start finds nothing new
        flights, jobs = FlightRepository(db), JobRepository(db)
        for state, fid in flight_ids.items():
            row = await flights.get(fid)
            if state in OPEN and state != F.INTERRUPTED:
                assert (row.state, row.note) == ("interrupted", "the service restarted"), state
            else:
                assert row.state == state, state
        for job_state, job_id in job_ids.items():
            job = await jobs.get(job_id)
            expected = JobState.INTERRUPTED if job_state in unfinished else job_state
            assert job.state == expected, job_state
        # the events kept, and the interruption in the flight's history (issue 28)
        kept, said = await flights.events(flight_ids[F.FLYING])
        assert (kept.kind, said.kind, said.data["state"]) == ("K", "FlightState", "interrupted")
        assert (await ScenarioRepository(db).get(sid)).body == BODY
    finally:
        db.close()
