"""FlightControl (gcs/service/flights/control.py) on real storage, SQLite and PostgreSQL,
with the flight service, the operator and the registry reduced to what it calls: a
request for another live service's flight is refused naming it; once that service's
lease has run out the request takes the flight over (a flight in the air becomes
`interrupted`, an aborting one is owed its abort again); a service whose flight was
taken while it was frozen lets it go at its next renewal, commanding nothing. The real
processes do all of it in tests/storage/test_two_services.py."""

from __future__ import annotations

import asyncio
from collections.abc import Iterable, Iterator, Mapping
from typing import Any, cast

import pytest

from gcs.fleet.crew import Fallback
from gcs.service.flights.book import FlightBook
from gcs.service.flights.control import ControlledElsewhere, FlightControl
from gcs.service.flights.operator import OperatorCommands
from gcs.service.flights.service import FlightService
from gcs.service.states import FlightState
from gcs.service.storage import Database, FlightRepository, VehicleRepository
from gcs.service.storage.leases import Holder, LeaseRepository
from gcs.service.vehicle_registry import VehicleRegistry
from tests.storage.test_repositories import _flight, _scenario_with_plan

F = FlightState
A = Holder("a", "http://127.0.0.1:8001")
B = Holder("b", "http://127.0.0.1:8002")
LEASE_S = 60.0
RUN_OUT = -1.0


class Events:
    def __init__(self) -> None:
        self.kinds: list[str] = []

    def record(self, _flight_id: str, kind: str, _data: Any, _uav: Any = None) -> None:
        self.kinds.append(kind)


class Flights:
    """FlightService as FlightControl uses it: its book and `to_interrupted`."""

    def __init__(self, book: FlightBook) -> None:
        self.book = book

    async def to_interrupted(self, flight_id: str, note: str) -> None:
        await self.book.transition(flight_id, F.INTERRUPTED, note)


class Operator:
    def __init__(self) -> None:
        self.watched: set[str] = set()
        self.owed: dict[str, Fallback] = {}
        self.stopped: set[str] = set()
        self.unfollowed: dict[str, dict[str, str]] = {}

    def watch_until_down(self, flight_id: str) -> None:
        self.watched.add(flight_id)

    def owe_abort(self, flight_id: str, fallback: Fallback, _ids: Iterable[str]) -> None:
        self.owed[flight_id] = fallback

    def pause_unfollowed(self, flight_id: str, bindings: Mapping[str, str]) -> None:
        self.unfollowed[flight_id] = dict(bindings)
        self.watched.add(flight_id)

    def stop_watching(self, flight_id: str) -> None:
        self.stopped.add(flight_id)


class Registry:
    def __init__(self) -> None:
        self.registering = asyncio.Lock()

    def knows(self, _vehicle_id: str) -> bool:
        return True

    def known(self) -> set[str]:
        return set()


class Fleet:
    closed = False

    def close(self) -> None:
        self.closed = True


class Active:
    def __init__(self) -> None:
        self.fleet = Fleet()


@pytest.fixture
def db(database_url: str) -> Iterator[Database]:
    database = Database(database_url)
    yield database
    database.close()


def control(db: Database, holder: Holder, lease_s: float = LEASE_S) -> FlightControl:
    book = FlightBook(FlightRepository(db), cast(Any, Events()))
    return FlightControl(
        LeaseRepository(db, holder, lease_s),
        cast(FlightService, Flights(book)),
        cast(OperatorCommands, Operator()),
        VehicleRepository(db),
        cast(VehicleRegistry, Registry()),
        renew_s=1.0,
    )


async def test_a_request_is_refused_naming_the_live_holder_then_takes_over(db: Database) -> None:
    _, plan_id = await _scenario_with_plan(db)
    fid = await _flight(db, plan_id, F.FLYING)
    on_a, on_b = control(db, A), control(db, B)
    await on_a.claim_for_upload(fid)
    await on_a.require(fid)  # its own
    with pytest.raises(
        ControlledElsewhere, match=r"controlled by service a at http://127\.0\.0\.1:8001"
    ):
        await on_b.require(fid)

    await control(db, A, RUN_OUT).leases.renew()  # a's last renewal, too short: a is dead
    await on_b.require(fid)  # the request takes it over at once
    row = await on_b.flights.book.flights.get(fid)
    assert (row.state, row.owner_id) == ("interrupted", "b")
    assert row.note.startswith("taken over by service b at http://127.0.0.1:8002 from a:")
    assert cast(Any, on_b.flights.book.events).kinds == ["TakenOver", "FlightState"]
    assert fid in cast(Operator, on_b.operator).watched
    assert cast(Operator, on_b.operator).unfollowed == {fid: row.bindings}  # to be paused
    with pytest.raises(ControlledElsewhere, match="service b at"):
        await on_a.require(fid)


async def test_an_aborting_flight_is_owed_its_abort(db: Database) -> None:
    _, plan_id = await _scenario_with_plan(db)
    fid = await _flight(db, plan_id, F.ABORTING)
    await FlightRepository(db).update(fid, note="rtl by the operator")
    assert await control(db, A, RUN_OUT).leases.claim_flight(fid)
    on_b = control(db, B)
    await on_b.tick()
    assert (await FlightRepository(db).get(fid)).state == "aborting"
    assert cast(Operator, on_b.operator).owed == {fid: Fallback.RTL}


async def test_a_frozen_service_lets_its_flight_go(db: Database) -> None:
    _, plan_id = await _scenario_with_plan(db)
    fid = await _flight(db, plan_id, F.FLYING)
    frozen = control(db, A, RUN_OUT)  # every lease it takes has run out: it froze
    await frozen.claim_for_upload(fid)
    active = Active()
    frozen.flights.book.active[fid] = cast(Any, active)
    on_b = control(db, B)
    await on_b.tick()  # b takes it over
    assert (await FlightRepository(db).get(fid)).owner_id == "b"

    await frozen.tick()  # a wakes: its renewal no longer holds the flight
    assert fid not in frozen.flights.book.active
    assert active.fleet.closed
    assert fid in cast(Operator, frozen.operator).stopped
    assert (await FlightRepository(db).get(fid)).owner_id == "b"  # nothing taken back
