"""No event lost: the fleet's sinks see every event, a listener that lags counts what it
loses, a slow live client is told how many messages it missed, and the event writer
keeps every event for a slow, failing or stopped store, in order, with memory bounded.

Every store here is deliberately slow: its writes wait on an `asyncio.Event` the test
sets, on the virtual clock; nothing sleeps on the wall clock."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, cast

import pytest

from gcs.fleet.events import EventBus, EventKind, FleetEvent
from gcs.service.flights.event_spill import EventSpill, PendingEvent
from gcs.service.flights.event_writer import CATCH_UP_BATCH, CLOSE_WAIT_S, EventWriter
from gcs.service.flights.live_queue import LiveQueue
from gcs.service.metrics import ServiceMetrics
from gcs.service.storage import FlightRepository
from gcs.service.storage.tables import EventRow

pytestmark = [pytest.mark.virtual_clock]

KIND = EventKind.POSITIONS
"""The kind of the events written below: any stored kind, the writer never reads it."""


@dataclass(frozen=True)
class Tick(FleetEvent):
    n: int


class SlowStore:
    """A store whose writes wait until `gate` is set, and fail while `failures` last;
    `flights` are the flights it knows (events of any other cannot be stored)."""

    def __init__(self, flights: set[str] | None = None) -> None:
        self.gate = asyncio.Event()
        self.gate.set()
        self.failures = 0
        self.flights = flights or {"f1"}
        self.rows: list[tuple[str, int]] = []
        self.writes = 0

    async def record_events(self, rows: list[EventRow]) -> None:
        await self.gate.wait()
        self.writes += 1
        if self.failures:
            self.failures -= 1
            raise OSError("database is locked")
        if any(row.flight_id not in self.flights for row in rows):
            raise OSError("FOREIGN KEY constraint failed")
        self.rows += [(row.flight_id, row.data["n"]) for row in rows]

    async def get(self, flight_id: str) -> Any:
        await self.gate.wait()
        if flight_id not in self.flights:
            raise LookupError(flight_id)
        return flight_id


def writer(store: SlowStore, tmp_path: Path, memory_rows: int = 10) -> EventWriter:
    spill = EventSpill(tmp_path / "event-spill.jsonl")
    return EventWriter(cast(FlightRepository, store), spill, ServiceMetrics(), memory_rows)


def metric(metrics: ServiceMetrics, name: str) -> float:
    value = metrics.registry.get_sample_value(name)
    assert value is not None, name
    return value


async def test_a_sink_gets_every_event_in_order_and_a_lagging_listener_counts_its_losses() -> None:
    bus = EventBus(maxsize=10)
    seen: list[int] = []
    bus.sink(lambda event: seen.append(cast(Tick, event).n))
    lagging = bus.listen()
    for n in range(25):  # in one tick: nobody reads in between
        bus.publish(Tick(n))
    bus.close()
    assert seen == list(range(25))
    assert lagging.dropped == 16  # 15 events, then one more for the closing mark
    assert bus.dropped == 16
    assert [cast(Tick, e).n for e in [e async for e in lagging]] == list(range(16, 25))


async def test_a_failing_sink_does_not_stop_the_tick_nor_the_other_sinks() -> None:
    bus = EventBus()
    seen: list[FleetEvent] = []

    def broken(event: FleetEvent) -> None:
        raise RuntimeError("a bug in a sink")

    bus.sink(broken)
    bus.sink(seen.append)
    bus.publish(Tick(1))
    assert len(seen) == 1


async def test_a_slow_live_client_is_told_how_many_messages_it_lost() -> None:
    dropped: list[int] = []
    queue = LiveQueue(3, lambda: dropped.append(1))
    queue.put({"n": 0})
    assert await queue.get() == {"n": 0}
    for n in range(1, 8):
        queue.put({"n": n})
    assert len(dropped) == queue.dropped == 4
    got = [await queue.get() for _ in range(4)]
    assert got == [{"type": "dropped", "count": 4}, {"n": 5}, {"n": 6}, {"n": 7}]
    assert queue.empty()


async def test_a_slow_store_gets_every_event_in_order_with_memory_bounded(tmp_path: Path) -> None:
    loop = asyncio.get_running_loop()
    store = SlowStore()
    events = writer(store, tmp_path, memory_rows=10)
    events.start()
    store.gate.clear()
    burst = CATCH_UP_BATCH + 3000  # beyond memory, a batch, and a catch-up batch
    for n in range(burst):
        events.record("f1", KIND, {"n": n})  # never waits: the tick calls it
    assert len(events._memory) <= 10 and events.spill.unread >= burst - 10 - 200
    metrics = events.metrics
    assert metric(metrics, "mvo_gcs_events_pending") == burst
    assert metric(metrics, "mvo_gcs_events_spilled") == events.spill.unread
    await asyncio.sleep(30.0)
    assert metric(metrics, "mvo_gcs_events_oldest_pending_seconds") == pytest.approx(30.0)
    late = loop.time()

    store.gate.set()
    await events.flush()
    assert store.rows == [("f1", n) for n in range(burst)]
    assert store.writes < burst / 200  # behind, it wrote bigger batches
    assert metric(metrics, "mvo_gcs_events_pending") == 0
    assert metric(metrics, "mvo_gcs_events_spilled") == 0
    assert metric(metrics, "mvo_gcs_events_written_total") == burst
    assert metric(metrics, "mvo_gcs_events_oldest_pending_seconds") == 0
    assert not events.spill.path.exists()
    assert loop.time() - late < 1.0

    events.record("f1", KIND, {"n": burst})  # caught up: memory again, no spill
    await events.flush()
    assert store.rows[-1] == ("f1", burst) and not events.spill.path.exists()
    await events.close()


async def test_each_stored_event_s_wait_is_measured_and_each_spilled_one_counted(
    tmp_path: Path,
) -> None:
    store = SlowStore()
    events = writer(store, tmp_path, memory_rows=10)
    events.start()
    events.record("f1", KIND, {"n": 0})
    await events.flush()  # storage keeps up: stored on the spot (the virtual clock stands)
    store.gate.clear()
    for n in range(1, 26):  # 10 in memory, 15 spilled
        events.record("f1", KIND, {"n": n})
    await asyncio.sleep(2.0)
    store.gate.set()
    await events.flush()
    metrics = events.metrics

    def lag(sample: str, le: str | None = None) -> float:
        labels = {"le": le} if le is not None else {}
        value = metrics.registry.get_sample_value(
            f"mvo_gcs_event_store_lag_seconds_{sample}", labels
        )
        assert value is not None, sample
        return value

    assert lag("count") == 26
    assert lag("sum") == pytest.approx(25 * 2.0)
    assert lag("bucket", "0.001") == 1  # the one stored at once
    assert lag("bucket", "1.0") == 1 and lag("bucket", "2.5") == 26
    assert metric(metrics, "mvo_gcs_events_spill_appends_total") == 15
    assert store.rows == [("f1", n) for n in range(26)]
    await events.close()


async def test_a_failing_store_is_asked_again_until_it_takes_the_events(tmp_path: Path) -> None:
    store = SlowStore()
    store.failures = 4
    events = writer(store, tmp_path)
    events.start()
    for n in range(50):
        events.record("f1", KIND, {"n": n})
    await events.flush()
    assert store.rows == [("f1", n) for n in range(50)]
    assert metric(events.metrics, "mvo_gcs_event_store_failures_total") == 4
    await events.close()


async def test_the_events_of_a_flight_deleted_meanwhile_are_left_out_and_counted(
    tmp_path: Path,
) -> None:
    store = SlowStore({"f1", "f2"})
    events = writer(store, tmp_path)
    events.start()
    store.gate.clear()
    for n in range(6):
        events.record("f1" if n % 2 else "f2", KIND, {"n": n})
    store.flights.discard("f2")  # deleted with its events before they were stored
    store.gate.set()
    await events.flush()
    assert store.rows == [("f1", 1), ("f1", 3), ("f1", 5)]
    assert metric(events.metrics, "mvo_gcs_events_discarded_total") == 3
    assert metric(events.metrics, "mvo_gcs_events_written_total") == 3
    await events.close()


async def test_events_storage_did_not_take_before_shutdown_are_stored_at_the_next_start(
    tmp_path: Path,
) -> None:
    loop = asyncio.get_running_loop()
    store = SlowStore()
    first = writer(store, tmp_path, memory_rows=10)
    first.start()
    store.gate.clear()
    for n in range(40):
        first.record("f1", KIND, {"n": n})
    closing = loop.time()
    await first.close()
    assert loop.time() - closing == pytest.approx(CLOSE_WAIT_S)
    assert store.rows == [] and first.spill.path.exists()

    store = SlowStore()
    second = writer(store, tmp_path, memory_rows=10)
    second.start()
    second.record("f1", KIND, {"n": 40})  # new events come after the old ones
    await second.flush()
    assert store.rows == [("f1", n) for n in range(41)]
    assert not second.spill.path.exists()
    await second.close()


async def test_a_spilled_event_cut_short_by_a_crash_is_left_out_and_the_rest_kept(
    tmp_path: Path,
) -> None:
    events = writer(SlowStore(), tmp_path)
    path = events.spill.path
    text = "".join(_line(n) for n in range(3))
    path.write_text(text + _line(3)[:20])  # the process died mid-append
    store = cast(SlowStore, events.store)
    events.start()
    events.record("f1", KIND, {"n": 4})
    await events.flush()
    assert store.rows == [("f1", 0), ("f1", 1), ("f1", 2), ("f1", 4)]
    await events.close()


def _line(n: int) -> str:
    return PendingEvent(0.0, "f1", KIND, None, {"n": n}, datetime.now(UTC)).line()
