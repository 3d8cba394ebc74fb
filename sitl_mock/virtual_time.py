"""An asyncio event loop on a virtual clock: the one clock of a simulated flight.

The ground station (`gcs`) and the simulated vehicles read time only from the running
event loop (`loop.time()`, `asyncio.sleep`, `asyncio.timeout`). On this loop that time
is virtual: when every task waits, the clock jumps straight to the next timer instead
of sleeping, so a ten-minute flight runs as fast as the processor allows, and the same
seed replays the same flight, whatever else the machine is doing.

Work handed to threads (`run_in_executor`, `asyncio.to_thread`: storage, planning)
takes no virtual time: while any is outstanding the clock stands still and the loop
waits for it in real time. Sockets are not simulated: a flight on this loop talks over
in-memory links (`Simulator.memory_port`), because a packet still in the kernel would
be overtaken by the jumping clock.
"""

from __future__ import annotations

import asyncio
import selectors
from collections.abc import Callable, Coroutine
from concurrent.futures import Executor
from typing import Any, TypeVar, TypeVarTuple

T = TypeVar("T")
Ts = TypeVarTuple("Ts")

OUTSIDE_WAIT_S = 5.0
"""Real seconds one wait for threads lasts before the loop looks round again."""


class _VirtualSelector(selectors.DefaultSelector):
    """Polls the real file descriptors without blocking, and lets virtual time pass
    instead of blocking when nothing outside the loop is pending."""

    def __init__(self) -> None:
        super().__init__()
        self.loop: VirtualTimeLoop | None = None

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        ready = super().select(0)
        if ready or timeout == 0:
            return ready
        loop = self.loop
        assert loop is not None
        if loop.outside:
            # Threads are working: their answers arrive through the loop's self-pipe, in
            # real time, while the clock stands still.
            return super().select(OUTSIDE_WAIT_S)
        if timeout is None:  # nothing scheduled: only another thread can wake the loop
            return super().select(None)
        loop.advance(timeout)
        return []


class VirtualTimeLoop(asyncio.SelectorEventLoop):
    """`loop.time()` starts at `start` and moves only when every task waits."""

    def __init__(self, start: float = 0.0) -> None:
        selector = _VirtualSelector()
        super().__init__(selector)
        selector.loop = self
        self._now = start
        self.outside = 0
        """Executor jobs not yet finished: virtual time stands still while any is."""

    def time(self) -> float:
        return self._now

    def advance(self, seconds: float) -> None:
        if seconds > 0:
            self._now += seconds

    def run_in_executor(
        self, executor: Executor | None, func: Callable[[*Ts], T], *args: *Ts
    ) -> asyncio.Future[T]:
        future = super().run_in_executor(executor, func, *args)
        self.outside += 1
        future.add_done_callback(self._back_inside)
        return future

    def _back_inside(self, _: asyncio.Future[Any]) -> None:
        self.outside -= 1


def run_virtual(main: Coroutine[Any, Any, T], start: float = 0.0) -> T:
    """Run `main` to completion on a fresh virtual-time loop (as `asyncio.run` does)."""
    with asyncio.Runner(loop_factory=lambda: VirtualTimeLoop(start)) as runner:
        return runner.run(main)
