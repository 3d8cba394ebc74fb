"""Fleet events to storage, off the event loop, in order, in batches, none dropped.

The fleet records events from its tick, which must never wait: writing each one there
would stall the tick by a storage round trip, and a tick cannot be made to wait for a
slow database (back-pressure would hold the vehicles' passing order up). So `record`
never waits: it keeps the event in memory, and one task writes them, many per
transaction, on the storage threads. When storage is slow the backlog grows; past
`memory_rows` events every further one is spilled to a file (`event_spill.py`) until
the writer has caught up, so memory stays bounded and nothing is dropped. Behind, the
writer stores bigger batches (a slow database is mostly slow per transaction).

A failed write is retried, with growing pauses, until storage takes it: a store that is
down delays events, never loses them. Only the events of a flight deleted before they
were stored (they would have been deleted with it) and a spilled line cut short by a
crash are left out, and counted.
`mvo_gcs_events_pending`, `..._spilled`, `..._oldest_pending_seconds`,
`..._written_total`, `mvo_gcs_event_store_lag_seconds` (recording to commit, per event),
`mvo_gcs_events_spill_appends_total`, `mvo_gcs_event_store_failures_total` and
`mvo_gcs_events_discarded_total` show how far behind it is. At shutdown what is still
unstored (after `CLOSE_WAIT_S`) goes to the spill file and is stored at the next start;
a batch cut off mid-write then may be stored twice, never lost.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections import deque
from collections.abc import Iterator
from typing import Any

from gcs.fleet.events import EventKind
from gcs.service.flights.event_spill import EventSpill, PendingEvent
from gcs.service.metrics import ServiceMetrics
from gcs.service.storage import FlightRepository
from gcs.service.storage.tables import now

log = logging.getLogger("mvo_gcs.events")
BATCH = 200  # events per transaction while storage keeps up
CATCH_UP_BATCH = 2000  # per transaction once more than this are waiting
RETRY_FIRST_S, RETRY_MOST_S = 0.5, 5.0  # pauses between attempts at a failed write
CLOSE_WAIT_S = 5.0  # how long a stopping service waits for storage to catch up


class EventWriter:
    def __init__(
        self,
        store: FlightRepository,
        spill: EventSpill,
        metrics: ServiceMetrics | None = None,
        memory_rows: int = 10_000,
    ) -> None:
        self.store = store
        self.spill = spill
        self.memory_rows = memory_rows
        self.metrics = metrics or ServiceMetrics()
        self.recorded = 0  # events given to `record` (and left over from the last run)
        self.done = 0  # of them stored or discarded, always the oldest
        self._memory: deque[PendingEvent] = deque()
        self._batch: list[PendingEvent] = []  # being written now
        self._wake = asyncio.Event()
        self._progress = asyncio.Condition()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._task: asyncio.Task[None] | None = None
        self.metrics.events_pending.set_function(lambda: self.pending)
        self.metrics.events_spilled.set_function(lambda: self.spill.unread)
        self.metrics.events_oldest_pending.set_function(self.oldest_pending_s)

    @property
    def pending(self) -> int:
        """Events recorded and not yet stored: in memory, being written or spilled."""
        return self.recorded - self.done

    def oldest_pending_s(self) -> float:
        """How long ago the oldest event not yet stored was recorded (0: none waits)."""
        head = next(iter(self._waiting()), None)
        t = head.t if head is not None else self.spill.head_t
        return 0.0 if t is None or self._loop is None else max(self._loop.time() - t, 0.0)

    def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        left = self.spill.open(self._loop.time())
        if left:
            log.warning("%d flight events left unstored by the last run are stored first", left)
            self.recorded += left
        self._task = asyncio.ensure_future(self._write_forever())
        self._wake.set()

    def record(
        self, flight_id: str, kind: EventKind, data: dict[str, Any], uav_id: str | None = None
    ) -> None:
        """Keep one event for storage; never waits (the flight's tick calls it)."""
        t = self._loop.time() if self._loop is not None else 0.0
        event = PendingEvent(t, flight_id, kind, uav_id, data, now())
        if self.spill.unread or len(self._memory) >= self.memory_rows:
            self.spill.append(event)  # behind the spilled ones, in order
            self.metrics.events_spill_appends.inc()
        else:
            self._memory.append(event)
        self.recorded += 1
        self._wake.set()

    async def flush(self) -> None:
        """Wait until every event recorded before this call is stored."""
        target = self.recorded
        async with self._progress:
            await self._progress.wait_for(lambda: self.done >= target)

    async def close(self) -> None:
        """Store what storage takes within `CLOSE_WAIT_S`; keep the rest for the next start."""
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(CLOSE_WAIT_S):
                await self.flush()
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        earlier = list(self._waiting())
        if earlier or self.spill.unread:
            log.warning(
                "storage did not take %d flight events in time: kept in %s for the next start",
                self.pending,
                self.spill.path,
            )
        self.spill.keep(earlier)

    def _waiting(self) -> Iterator[PendingEvent]:
        """The unstored events held in memory, oldest first (the spilled ones follow)."""
        yield from self._batch
        yield from self._memory

    def _next_batch(self) -> list[PendingEvent]:
        most = CATCH_UP_BATCH if self.pending > CATCH_UP_BATCH else BATCH
        batch = [self._memory.popleft() for _ in range(min(most, len(self._memory)))]
        if len(batch) < most:  # the memory is empty: the spilled ones are next
            batch += self.spill.read(most - len(batch))
        return batch

    async def _write_forever(self) -> None:
        while True:
            unreadable = self.spill.unreadable
            self._batch = self._next_batch()
            cut_short = self.spill.unreadable - unreadable
            if not self._batch and not cut_short:
                self._wake.clear()
                await self._wake.wait()
                continue
            stored = await self._store(self._batch)
            left_out = len(self._batch) - stored + cut_short
            self.metrics.events_written.inc(stored)
            self.metrics.events_discarded.inc(left_out)
            self.done += stored + left_out
            self._batch = []
            async with self._progress:
                self._progress.notify_all()

    async def _store(self, batch: list[PendingEvent]) -> int:
        """Write `batch` in one transaction, trying again until storage takes it; how
        many were stored (those of a flight deleted meanwhile are not)."""
        pause = RETRY_FIRST_S
        while batch:
            try:
                await self.store.record_events([event.row() for event in batch])
                self._observe_lag(batch)
                return len(batch)
            except Exception:
                self.metrics.event_store_failures.inc()
                log.exception("could not store %d flight events; again in %.1fs", len(batch), pause)
            await asyncio.sleep(pause)
            pause = min(2 * pause, RETRY_MOST_S)
            with contextlib.suppress(Exception):  # storage down: ask again next time
                batch = await self._without_deleted_flights(batch)
        return 0

    def _observe_lag(self, stored: list[PendingEvent]) -> None:
        """How long each stored event waited, from `record` to its transaction's commit
        (one left by the last run: from this start)."""
        if self._loop is None:
            return
        t = self._loop.time()
        for event in stored:
            self.metrics.event_store_lag.observe(max(t - event.t, 0.0))

    async def _without_deleted_flights(self, batch: list[PendingEvent]) -> list[PendingEvent]:
        gone = set()
        for flight_id in {event.flight_id for event in batch}:
            try:
                await self.store.get(flight_id)
            except LookupError:
                gone.add(flight_id)
        if gone:
            log.warning("flights %s were deleted before their events were stored", sorted(gone))
        return [event for event in batch if event.flight_id not in gone]
