"""Fleet events to storage, off the event loop, in order, in batches.

The fleet publishes events from its tick; writing each one there would stall the tick
by a storage round trip. Events are queued instead and one task writes them, many per
transaction, on the storage threads. `flush` waits until everything queued is stored.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import Any

from gcs.service.storage import FlightRepository
from gcs.service.storage.tables import EventRow

log = logging.getLogger("mvo_gcs.events")
BATCH = 200


class EventWriter:
    def __init__(self, flights: FlightRepository) -> None:
        self._flights = flights
        self._queue: asyncio.Queue[EventRow] = asyncio.Queue()
        self._task: asyncio.Task[None] | None = None
        self.written = 0

    def start(self) -> None:
        self._task = asyncio.ensure_future(self._write_forever())

    def record(
        self, flight_id: str, kind: str, data: dict[str, Any], uav_id: str | None = None
    ) -> None:
        self._queue.put_nowait(EventRow(flight_id=flight_id, kind=kind, uav_id=uav_id, data=data))

    async def flush(self) -> None:
        await self._queue.join()

    async def _write_forever(self) -> None:
        while True:
            batch = [await self._queue.get()]
            while not self._queue.empty() and len(batch) < BATCH:
                batch.append(self._queue.get_nowait())
            try:
                await self._flights.record_events(batch)
                self.written += len(batch)
            except Exception:  # a storage fault must not stop the flight; it is logged
                log.exception("could not store %d flight events", len(batch))
            finally:
                for _ in batch:
                    self._queue.task_done()

    async def close(self) -> None:
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(5.0):
                await self.flush()
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
