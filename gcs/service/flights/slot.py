"""One flight's operations: one at a time, and the operator's interventions pre-empt.

Upload, start, pause, continue and object reports on one flight take turns (`serial`).
Each runs as a task of its own (`run`), not as part of the HTTP request that asked
for it, so a client that hangs up does not leave half an operation behind. The long
work a start sets going (arming, take-off, following the flight) is the flight's
*runner*, which holds no turn: the operator can pause or abort while it runs.
`preempt` cancels whatever operation and runner are going, so that an abort never
waits behind them, and no runner may start after it: a start still on its way (between
its state change and its runner) finds the flight pre-empted and arms nothing.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Coroutine
from typing import Any, TypeVar

T = TypeVar("T")
UNWIND_TIMEOUT_S = 2.0


class Preempted(Exception):
    """The operation was cancelled by an intervention (an abort) before it finished."""


class FlightSlot:
    def __init__(self, flight_id: str) -> None:
        self.flight_id = flight_id
        self._turn = asyncio.Lock()
        self._interventions = asyncio.Lock()
        self._operation: asyncio.Task[Any] | None = None
        self.runner: asyncio.Task[Any] | None = None
        self.preempted = False
        """An intervention cancelled this flight's work: it never starts a runner again
        (every intervention leaves the flight in a state that cannot start)."""

    @contextlib.asynccontextmanager
    async def serial(self) -> AsyncIterator[None]:
        """This flight's turn for one operation."""
        async with self._turn:
            yield

    @contextlib.asynccontextmanager
    async def intervention(self) -> AsyncIterator[None]:
        """Interventions take turns among themselves, never behind an operation."""
        async with self._interventions:
            yield

    async def run(self, coro: Coroutine[Any, Any, T]) -> T:
        """Run `coro` as this flight's operation; Preempted if an intervention cancels it.

        The caller going away (its request cancelled) does not cancel the operation."""
        task = asyncio.ensure_future(coro)
        self._operation = task
        try:
            await asyncio.wait({task})
        finally:
            if self._operation is task and task.done():
                self._operation = None
        if task.cancelled():
            raise Preempted(f"flight {self.flight_id}: the operation was pre-empted")
        return task.result()

    def start_runner(self, coro: Coroutine[Any, Any, Any]) -> asyncio.Task[Any]:
        """Run the flight's runner; Preempted (and nothing runs) after an intervention."""
        if self.preempted:
            coro.close()
            raise Preempted(f"flight {self.flight_id} was held or aborted while it started")
        self.runner = asyncio.ensure_future(coro)
        return self.runner

    def take_up_again(self) -> None:
        """The operator resumes the flight: a runner may start again, unless another
        intervention comes before it does."""
        self.preempted = False

    @property
    def busy(self) -> bool:
        return any(t is not None and not t.done() for t in (self._operation, self.runner))

    async def preempt(self) -> None:
        """Cancel the operation and the runner, and wait (bounded) until they unwind."""
        self.preempted = True
        tasks = [t for t in (self._operation, self.runner) if t is not None and not t.done()]
        for task in tasks:
            task.cancel()
        if tasks:
            await asyncio.wait(tasks, timeout=UNWIND_TIMEOUT_S)
