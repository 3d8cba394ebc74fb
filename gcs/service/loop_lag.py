"""A probe of the event loop's stalls: how late a short timer fires.

Every vehicle link, every WebSocket and every HTTP request shares the one loop, so a
stall (a blocking call, a long computation) delays them all by as much. The probe
sleeps `period_s` again and again and records by how much each wake-up came late.
"""

from __future__ import annotations

import asyncio
from collections import deque

from prometheus_client import Histogram

PERIOD_S = 0.05
"""Twenty wake-ups a second: enough to catch a stall, few enough to cost nothing."""


class LoopLagProbe:
    def __init__(self, histogram: Histogram | None = None, keep: int = 10_000) -> None:
        self._histogram = histogram
        self.lags: deque[float] = deque(maxlen=keep)  # seconds late, most recent last
        self._task: asyncio.Task[None] | None = None

    def start(self, period_s: float = PERIOD_S) -> None:
        self._task = asyncio.ensure_future(self._probe(period_s))

    async def _probe(self, period_s: float) -> None:
        loop = asyncio.get_running_loop()
        while True:
            before = loop.time()
            await asyncio.sleep(period_s)
            lag = max(0.0, loop.time() - before - period_s)
            self.lags.append(lag)
            if self._histogram is not None:
                self._histogram.observe(lag)

    def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
