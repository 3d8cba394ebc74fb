"""An asyncio event loop on a virtual clock: the one clock of a simulated flight.

The ground station (`gcs`) and the simulated vehicles read time only from the running
event loop (`loop.time()`, `asyncio.sleep`, `asyncio.timeout`). On this loop that time
is virtual: when every task waits, the clock jumps straight to the next timer instead
of sleeping, so a ten-minute flight runs as fast as the processor allows, and the same
seed replays the same flight, whatever else the machine is doing.

Work handed to threads (`run_in_executor`, `asyncio.to_thread`: storage, planning) runs
at once on the loop's own thread, and its result arrives `executor_delay()` virtual
seconds later (a simulated disk: 2 ms by default, or drawn from a seeded generator), so
that concurrent requests interleave with storage as they would on a real machine, but at
the same points every time: with real threads, whether a storage write finished before
or after a concurrent request went on would depend on the machine's load. (Work that
waits for the loop itself must not be handed to an executor on this loop.)
Sockets are not simulated either: a flight on this loop talks over in-memory links
(`Simulator.memory_port`), because a packet still in the kernel would be overtaken by the
jumping clock.
"""

from __future__ import annotations

import asyncio
import selectors
from collections.abc import Callable, Coroutine
from concurrent.futures import Executor
from typing import Any, TypeVar, TypeVarTuple

T = TypeVar("T")
Ts = TypeVarTuple("Ts")


class _VirtualSelector(selectors.DefaultSelector):
    """Polls the real file descriptors without blocking, and lets virtual time pass
    instead of blocking."""

    def __init__(self) -> None:
        super().__init__()
        self.loop: VirtualTimeLoop | None = None

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        ready = super().select(0)
        if ready or timeout == 0:
            return ready
        if timeout is None:  # nothing scheduled: only another thread can wake the loop
            return super().select(None)
        assert self.loop is not None
        self.loop.advance(timeout)
        return []


EXECUTOR_DELAY_S = 0.002
"""Virtual seconds a job handed to an executor takes by default (a SQLite commit's order)."""


class VirtualTimeLoop(asyncio.SelectorEventLoop):
    """`loop.time()` starts at `start` and moves only when every task waits."""

    def __init__(
        self, start: float = 0.0, executor_delay: Callable[[], float] | None = None
    ) -> None:
        selector = _VirtualSelector()
        super().__init__(selector)
        selector.loop = self
        self._now = start
        self._executor_delay = executor_delay or (lambda: EXECUTOR_DELAY_S)

    def time(self) -> float:
        return self._now

    def advance(self, seconds: float) -> None:
        if seconds > 0:
            self._now += seconds

    def run_in_executor(
        self, executor: Executor | None, func: Callable[[*Ts], T], *args: *Ts
    ) -> asyncio.Future[T]:
        """`func(*args)` now, on this thread; its outcome arrives after the executor delay,
        as a thread's would."""
        future: asyncio.Future[T] = self.create_future()
        try:
            outcome: tuple[Callable[[Any], None], Any] = (future.set_result, func(*args))
        except Exception as exc:  # the awaiting task receives it, as from a thread
            outcome = (future.set_exception, exc)
        self.call_later(max(0.0, self._executor_delay()), _settle, future, *outcome)
        return future


def _settle(future: asyncio.Future[Any], settle: Callable[[Any], None], value: Any) -> None:
    if not future.cancelled():
        settle(value)


def run_virtual(main: Coroutine[Any, Any, T], start: float = 0.0) -> T:
    """Run `main` to completion on a fresh virtual-time loop (as `asyncio.run` does)."""
    with asyncio.Runner(loop_factory=lambda: VirtualTimeLoop(start)) as runner:
        return runner.run(main)
