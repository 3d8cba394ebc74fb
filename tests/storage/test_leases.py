"""Leases (several services on one database), on SQLite and on PostgreSQL: a flight is
held by one service at a time, a job is claimed once, a holder whose lease has run out
loses its rows to another, and a restart on a shared database leaves a live service's
rows alone. A lease that has run out is made with a negative length: no clock is waited
on."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Iterator

import pytest

from gcs.service.states import FlightState, JobState
from gcs.service.storage import Database, FlightRepository, JobRepository
from gcs.service.storage.leases import Holder, LeaseRepository
from gcs.service.storage.tables import FlightRow, JobRow
from tests.storage.test_repositories import _flight, _scenario_with_plan

F = FlightState
A = Holder("host:8001/a", "http://127.0.0.1:8001")
B = Holder("host:8002/b", "http://127.0.0.1:8002")
LEASE_S = 60.0  # long enough never to run out during a test
RUN_OUT = -1.0  # a lease that has already run out


@pytest.fixture
def db(database_url: str) -> Iterator[Database]:
    database = Database(database_url)
    yield database
    database.close()


async def test_one_holder_at_a_time_until_its_lease_runs_out(db: Database) -> None:
    _, plan_id = await _scenario_with_plan(db)
    fid = await _flight(db, plan_id, F.FLYING)
    a, b = LeaseRepository(db, A, LEASE_S), LeaseRepository(db, B, LEASE_S)
    assert await a.claim_flight(fid)
    assert not await b.claim_flight(fid)  # a lives
    assert await a.claim_flight(fid)  # its own: kept
    assert await b.holder_of(fid) == (A, True)
    assert (await b.renew()).orphans == []

    dead_a = LeaseRepository(db, A, RUN_OUT)
    assert (await dead_a.renew()).flights == {fid}  # a renews, but too short
    assert [row.id for row in (await b.renew()).orphans] == [fid]
    assert await b.holder_of(fid) == (A, False)
    assert await b.claim_flight(fid)
    assert await a.holder_of(fid) == (B, True)
    assert (await a.renew()).flights == frozenset()  # a finds it taken: lets it go
    assert (await b.renew()).flights == {fid}


async def test_orphans_are_open_flights_of_dead_holders_only(db: Database) -> None:
    _, plan_id = await _scenario_with_plan(db)
    dead_a = LeaseRepository(db, A, RUN_OUT)
    ids = {state: await _flight(db, plan_id, state) for state in (F.FLYING, F.LANDED, F.CREATED)}
    for fid in ids.values():
        assert await dead_a.claim_flight(fid)
    unowned = await _flight(db, plan_id, F.INTERRUPTED)
    b = LeaseRepository(db, B, LEASE_S)
    orphans = (await b.renew()).orphans
    assert [row.id for row in orphans] == [ids[F.FLYING]]  # not ended, not unowned
    assert (await dead_a.renew()).orphans == []  # never its own
    assert await b.claim_flight(unowned)  # nobody's: anyone may take it


async def test_a_clean_stop_releases_at_once(db: Database) -> None:
    _, plan_id = await _scenario_with_plan(db)
    fid = await _flight(db, plan_id, F.PAUSED)
    a, b = LeaseRepository(db, A, LEASE_S), LeaseRepository(db, B, LEASE_S)
    assert await a.claim_flight(fid)
    await a.release()
    assert [row.id for row in (await b.renew()).orphans] == [fid]


async def test_a_job_is_claimed_once_and_a_dead_holders_job_is_interrupted(db: Database) -> None:
    sid, _ = await _scenario_with_plan(db)
    jobs = JobRepository(db)
    job = await jobs.add(JobRow(scenario_id=sid, settings={}))
    a, b = LeaseRepository(db, A, LEASE_S), LeaseRepository(db, B, LEASE_S)
    assert await a.claim_job(job.id)
    assert not await b.claim_job(job.id)
    assert not await a.claim_job(job.id)  # claimed: no longer queued for anyone
    assert (await b.renew()).interrupted_jobs == 0  # a lives
    assert (await a.renew()).jobs == 1

    other = await jobs.add(JobRow(scenario_id=sid, settings={}))
    assert await LeaseRepository(db, A, RUN_OUT).claim_job(other.id)
    assert (await b.renew()).interrupted_jobs == 1
    assert (await jobs.get(other.id)).state == JobState.INTERRUPTED
    assert (await jobs.get(job.id)).state == JobState.QUEUED


def test_of_many_services_racing_for_a_flight_one_wins(db: Database) -> None:
    """Eight holders on threads of their own claim each flight at once: one wins each."""

    async def flights() -> list[str]:
        _, plan_id = await _scenario_with_plan(db)
        return [await _flight(db, plan_id, F.FLYING) for _ in range(10)]

    ids = asyncio.run(flights())
    holders = [
        LeaseRepository(db, Holder(f"h{i}", f"http://127.0.0.1:{9000 + i}"), LEASE_S)
        for i in range(8)
    ]
    for fid in ids:
        start = threading.Barrier(len(holders))
        won: list[str] = []

        def claim(
            repository: LeaseRepository,
            flight_id: str = fid,
            start: threading.Barrier = start,
            won: list[str] = won,
        ) -> None:
            start.wait()
            if repository._claim_flight(flight_id):
                won.append(repository.holder.id)

        threads = [threading.Thread(target=claim, args=(h,)) for h in holders]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert len(won) == 1, (fid, won)


async def test_a_restart_on_a_shared_database_leaves_a_live_services_flights(
    database_url: str,
) -> None:
    """On PostgreSQL a starting service interrupts and takes only what no live service
    holds; on SQLite (one service by design) it takes every open flight, as before."""
    db = Database(database_url)
    try:
        _, plan_id = await _scenario_with_plan(db)
        live = await _flight(db, plan_id, F.FLYING)
        dead = await _flight(db, plan_id, F.FLYING)
        assert await LeaseRepository(db, A, LEASE_S).claim_flight(live)
        assert await LeaseRepository(db, B, RUN_OUT).claim_flight(dead)
        recovered = db.recover(("host:8003/c", "http://127.0.0.1:8003"), LEASE_S)
        flights = FlightRepository(db)
        shared = not database_url.startswith("sqlite")
        assert recovered["flights"] == (1 if shared else 2)
        taken: FlightRow = await flights.get(dead)
        assert (taken.state, taken.owner_id) == ("interrupted", "host:8003/c")
        kept: FlightRow = await flights.get(live)
        expected = ("flying", A.id) if shared else ("interrupted", "host:8003/c")
        assert (kept.state, kept.owner_id) == expected
    finally:
        db.close()
