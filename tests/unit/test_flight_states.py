"""Flight and job states: one enum each, one transition table, enforced in storage.

Every transition of the table is made on a real SQLite file and every move the table
does not allow is refused there, with a message that says what would be allowed; two
movers racing for one flight cannot both win.
"""

from __future__ import annotations

import asyncio
import itertools
from pathlib import Path

import pytest

from gcs.service.metrics import ServiceMetrics
from gcs.service.planning import PlanningService
from gcs.service.states import (
    FLIGHT_TRANSITIONS,
    JOB_TRANSITIONS,
    OPEN,
    FlightState,
    JobState,
    StateConflict,
)
from gcs.service.storage import (
    Database,
    FlightRepository,
    JobRepository,
    PlanRepository,
    ScenarioRepository,
)
from gcs.service.storage.tables import FlightRow, JobRow, PlanRow, ScenarioRow

F = FlightState
FLIGHT_PAIRS = list(itertools.product(FlightState, FlightState))
JOB_PAIRS = list(itertools.product(JobState, JobState))


@pytest.fixture
def db(tmp_path: Path):
    database = Database(f"sqlite:///{tmp_path / 'states.db'}")
    yield database
    database.close()


async def _flight_in(db: Database, state: FlightState) -> str:
    with db.session() as s:
        scenario = ScenarioRow(name="s", body={})
        s.add(scenario)
        s.flush()
        plan = PlanRow(scenario_id=scenario.id, feasible=True, body={})
        s.add(plan)
        s.flush()
        flight = FlightRow(plan_id=plan.id, bindings={}, options={}, state=state.value)
        s.add(flight)
        s.flush()
        return flight.id


@pytest.mark.parametrize(("now", "new"), FLIGHT_PAIRS, ids=lambda s: s.value)
async def test_every_flight_move_is_allowed_or_refused_by_the_table(
    db: Database, now: FlightState, new: FlightState
) -> None:
    flights = FlightRepository(db)
    flight_id = await _flight_in(db, now)
    if new in FLIGHT_TRANSITIONS[now]:
        row = await flights.transition(flight_id, new, "why")
        assert (row.state, row.note) == (new, "why")
    else:
        with pytest.raises(StateConflict, match=f"is {now.value}: it cannot become {new.value}"):
            await flights.transition(flight_id, new)
        assert (await flights.get(flight_id)).state == now


@pytest.mark.parametrize(("now", "new"), JOB_PAIRS, ids=lambda s: s.value)
async def test_every_job_move_is_allowed_or_refused_by_the_table(
    db: Database, now: JobState, new: JobState
) -> None:
    jobs = JobRepository(db)
    with db.session() as s:
        scenario = ScenarioRow(name="s", body={})
        s.add(scenario)
        s.flush()
        job = JobRow(scenario_id=scenario.id, settings={}, state=now.value)
        s.add(job)
        s.flush()
        job_id = job.id
    if new in JOB_TRANSITIONS[now]:
        assert (await jobs.transition(job_id, new)).state == new
    else:
        with pytest.raises(StateConflict):
            await jobs.transition(job_id, new)
        assert (await jobs.get(job_id)).state == now


async def test_two_movers_cannot_both_win(db: Database) -> None:
    """The follower's "landed" and an operator's abort race on a flying flight: neither
    order allows both, and exactly one of them moves it."""
    flights = FlightRepository(db)
    for _ in range(20):
        flight_id = await _flight_in(db, F.FLYING)
        results = await asyncio.gather(
            flights.transition(flight_id, F.ABORTING),
            flights.transition(flight_id, F.LANDED),
            return_exceptions=True,
        )
        won = [r for r in results if not isinstance(r, BaseException)]
        lost = [r for r in results if isinstance(r, StateConflict)]
        assert len(won) == 1 and len(lost) == 1, results
        assert (await flights.get(flight_id)).state == won[0].state


def test_a_finished_job_cannot_be_reopened_by_a_late_progress_report() -> None:
    for final in (JobState.DONE, JobState.FAILED, JobState.CANCELLED, JobState.INTERRUPTED):
        assert final.is_final
        with pytest.raises(StateConflict):
            final.check(JobState.RUNNING, "j")


def test_open_states_are_those_that_may_have_vehicles_in_the_air() -> None:
    assert F.UPLOADING in OPEN and F.INTERRUPTED in OPEN and F.ABORTING in OPEN
    assert not {F.CREATED, F.UPLOAD_FAILED, F.LANDED, F.ABORTED, F.ENDED, F.CANCELLED} & OPEN
    for state in FlightState:  # an open flight always has a way to close
        if state in OPEN:
            assert any(not t.is_open for t in _reachable(state)), state


def test_a_restart_interrupts_every_open_flight(db: Database) -> None:
    ids = {state: asyncio.run(_flight_in(db, state)) for state in FlightState}
    db.recover()
    flights = FlightRepository(db)
    for state, flight_id in ids.items():
        after = asyncio.run(flights.get(flight_id)).state
        assert after == (F.INTERRUPTED if state in OPEN else state), state


def _reachable(state: FlightState) -> set[FlightState]:
    seen, todo = set(), [state]
    while todo:
        for nxt in FLIGHT_TRANSITIONS[todo.pop()]:
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return seen


async def test_a_slow_watcher_of_a_job_misses_old_progress_never_its_end(db: Database) -> None:
    """A job's live socket reads its queue slower than progress comes: the queue keeps
    the latest states, so the end is never dropped (a full queue dropped it, and the
    socket closed without saying how the job ended)."""
    jobs = JobRepository(db)
    planning = PlanningService(ScenarioRepository(db), PlanRepository(db), jobs, ServiceMetrics())
    scenario_id = (await ScenarioRepository(db).add(ScenarioRow(name="s", body={}))).id
    job = await jobs.add(JobRow(scenario_id=scenario_id, settings={}))
    queue = planning.watch(job.id)
    for percent in range(1, 151):
        await planning._set(job.id, JobState.RUNNING, percent=percent)
    await planning._set(job.id, JobState.CANCELLED)
    seen = [queue.get_nowait() for _ in range(queue.qsize())]
    assert seen[-1].state == JobState.CANCELLED
    assert [j.percent for j in seen[:2]] == [52, 53]  # the oldest went
