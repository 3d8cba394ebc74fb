"""No event lost to a slow consumer, in a flight through the in-process service on the
virtual clock: a store whose writes wait until the test lets them go still gets every
flight event, in order, while the flight flies on and lands; a live WebSocket client
that does not read is told how many messages it missed, and the metrics count them.

Each burst publishes more events in one tick than any bound holds (a listener's queue,
the writer's memory, a batch); nothing sleeps on the wall clock."""

from __future__ import annotations

import asyncio
import contextlib
import re
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest
from httpx_ws import AsyncWebSocketSession, WebSocketDisconnect, aconnect_ws
from httpx_ws.transport import ASGIWebSocketTransport
from starlette.types import Message, Receive, Scope, Send

from gcs.fleet.events import EventKind, FleetEvent
from gcs.fleet.fleet import Fleet
from gcs.service.api.deps import Services
from gcs.service.flights.active import LISTENER_QUEUE
from gcs.service.storage import FlightRepository
from gcs.service.storage.tables import EventRow
from planner.cases import load_case
from tests.inprocess.flying import Flight
from tests.inprocess.service import BASE_URL, InProcessService
from tests.inprocess.vehicles import SimulatedVehicles

pytestmark = [pytest.mark.virtual_clock]

MEMORY_ROWS = 50


@dataclass(frozen=True)
class Burst(FleetEvent):
    """A test's event, numbered, published many at once as a busy tick would; of a kind
    no flight makes any more (the API serves the kinds of `EventKind` only)."""

    kind = EventKind.PAUSED
    n: int


class SlowStore(FlightRepository):
    """The service's flight storage, but a write of events waits until `gate` is set."""

    def __init__(self, real: FlightRepository) -> None:
        super().__init__(real.db)
        self.gate = asyncio.Event()
        self.waited = 0

    async def record_events(self, rows: list[EventRow]) -> None:
        self.waited += 1
        await self.gate.wait()
        await super().record_events(rows)


@pytest.fixture
async def gcs(tmp_path: Path, vehicles: SimulatedVehicles) -> AsyncIterator[InProcessService]:
    service = InProcessService(tmp_path / "data", vehicles, event_memory_rows=MEMORY_ROWS)
    await service.start()
    yield service
    await service.stop()


def services(gcs: InProcessService) -> Services:
    assert gcs.app is not None
    found: Services = gcs.app.state.services
    return found


def fleet_of(gcs: InProcessService, flight_id: str) -> Fleet:
    return services(gcs).flights.book.active[flight_id].fleet


def burst(fleet: Fleet, first: int, count: int) -> None:
    """`count` events in one go: no other task runs until the last is published."""
    for n in range(first, first + count):
        fleet.crew.bus.publish(Burst(n))


async def metrics(gcs: InProcessService) -> dict[str, float]:
    text = (await gcs.client.get("/metrics")).text
    return {
        name: float(value)
        for name, value in re.findall(r"^(mvo_gcs_[a-z_]+) ([0-9.e+-]+)$", text, re.MULTILINE)
    }


async def test_a_slow_store_gets_every_event_in_order_and_the_flight_flies_on(
    gcs: InProcessService, monkeypatch: pytest.MonkeyPatch
) -> None:
    sim = await gcs.vehicles.at_starts(load_case("case-1"))
    flight = await Flight.make(gcs.client, sim)
    await flight.upload()
    published: list[dict[str, Any]] = []  # what the fleet published, every event
    fleet = fleet_of(gcs, flight.id)
    publish = fleet.crew.bus.publish

    def noted(event: FleetEvent) -> None:
        publish(event)
        published.append({"kind": event.kind, "at": event.at})

    monkeypatch.setattr(fleet.crew.bus, "publish", noted)
    store = SlowStore(services(gcs).events.store)
    services(gcs).events.store = store

    await flight.post("start")  # from now on storage takes nothing
    await flight.wait_state("flying", timeout=120, every=0.1)
    size = 3 * LISTENER_QUEUE  # beyond a listener's queue, the memory, a batch
    burst(fleet, 0, size)
    during = await metrics(gcs)
    assert during["mvo_gcs_events_pending"] > size
    assert during["mvo_gcs_events_spilled"] >= size - MEMORY_ROWS
    assert len(services(gcs).events._memory) <= MEMORY_ROWS

    await flight.wait_state("landed", timeout=600)  # the tick never waited for storage
    assert store.waited >= 1
    landed = await metrics(gcs)
    assert landed["mvo_gcs_events_oldest_pending_seconds"] > 10.0
    assert landed["mvo_gcs_events_written_total"] == during["mvo_gcs_events_written_total"]

    store.gate.set()
    await services(gcs).events.flush()
    stored = await flight.events()
    fleet_events = [e for e in stored if e["kind"] not in ("FlightState", "Positions")]
    kept = [p for p in published if p["kind"] != "Progress"]
    assert [(e["kind"], e["data"]["at"]) for e in fleet_events[-len(kept) :]] == [
        (p["kind"], p["at"]) for p in kept
    ]
    assert [e["data"]["n"] for e in stored if e["kind"] == "Paused"] == list(range(size))
    assert [e["id"] for e in stored] == sorted(e["id"] for e in stored)
    states = [e["data"]["state"] for e in stored if e["kind"] == "FlightState"]
    assert states[-2:] == ["flying", "landed"]
    after = await metrics(gcs)
    assert after["mvo_gcs_events_pending"] == 0 and after["mvo_gcs_events_spilled"] == 0
    assert after["mvo_gcs_events_written_total"] == len(stored)
    assert after["mvo_gcs_event_store_failures_total"] == 0


@contextlib.asynccontextmanager
async def slow_websocket(
    gcs: InProcessService, path: str, gate: asyncio.Event
) -> AsyncIterator[AsyncWebSocketSession]:
    """A client that does not read: nothing the service sends it goes out until `gate` is
    set (as a socket's send waits once a client leaves its TCP window full)."""
    assert gcs.app is not None
    app = gcs.app

    async def held(scope: Scope, receive: Receive, send: Send) -> None:
        async def send_when_read(message: Message) -> None:
            if message["type"] == "websocket.send":
                await gate.wait()
            await send(message)

        await app(scope, receive, send_when_read)

    transport = ASGIWebSocketTransport(held)
    async with (
        httpx.AsyncClient(transport=transport, base_url=BASE_URL) as client,
        aconnect_ws(path, client, session_class=AsyncWebSocketSession) as ws,
    ):
        yield ws


async def read_to_the_end(ws: AsyncWebSocketSession) -> list[dict[str, Any]]:
    messages: list[dict[str, Any]] = []
    with contextlib.suppress(WebSocketDisconnect):
        while True:
            messages.append(await ws.receive_json())
    return messages


async def test_a_slow_live_client_is_told_how_many_messages_it_missed_and_they_are_counted(
    gcs: InProcessService,
) -> None:
    sim = await gcs.vehicles.at_starts(load_case("case-1"))
    flight = await Flight.make(gcs.client, sim)
    await flight.upload()
    gate = asyncio.Event()
    live = f"/flights/{flight.id}/live"
    async with gcs.websocket(live) as fast, slow_websocket(gcs, live, gate) as slow:
        reading = asyncio.ensure_future(read_to_the_end(fast))
        await flight.post("start")
        await flight.wait_state("flying", timeout=120, every=0.1)
        burst(fleet_of(gcs, flight.id), 0, LISTENER_QUEUE - 100)  # the fast one keeps up
        await flight.wait_state("landed", timeout=600)
        told = [m for m in await reading if m["type"] != "state"]
        gate.set()
        missed = [m for m in await read_to_the_end(slow) if m["type"] != "state"]

    assert not [m for m in told if m["type"] == "dropped"]
    notices = [m for m in missed if m["type"] == "dropped"]
    assert notices == [{"type": "dropped", "count": len(told) - LISTENER_QUEUE}]
    assert missed[0] == notices[0]  # before the first message it got after the gap
    assert missed[1:] == told[-LISTENER_QUEUE:]
    assert (await metrics(gcs))["mvo_gcs_live_messages_dropped_total"] == notices[0]["count"]
