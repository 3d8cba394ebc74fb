"""One live client's messages about a flight, in a bounded queue that says what it drops.

A client too slow to take the flight's messages must not hold up the flight nor grow
the service's memory, so its queue keeps the newest `maxsize` messages and drops the
oldest. It is never silent about it: each drop is counted (`on_drop`, the metrics), and
the next message the client gets is `{"type": "dropped", "count": N}`, N being the
messages lost between the one it got before and the one after.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

Message = dict[str, Any]


class LiveQueue:
    def __init__(self, maxsize: int, on_drop: Callable[[], None] = lambda: None) -> None:
        self._queue: asyncio.Queue[Message] = asyncio.Queue(maxsize)
        self._on_drop = on_drop
        self._untold = 0  # dropped since the client was last told
        self.dropped = 0

    def put(self, message: Message) -> None:
        """Never waits: when full, the oldest message makes room and is counted."""
        if self._queue.full():
            self._queue.get_nowait()
            self._untold += 1
            self.dropped += 1
            self._on_drop()
        self._queue.put_nowait(message)

    async def get(self) -> Message:
        """The next message; a `dropped` notice first when some were dropped before it."""
        if self._untold:
            count, self._untold = self._untold, 0
            return {"type": "dropped", "count": count}
        return await self._queue.get()

    def empty(self) -> bool:
        return self._queue.empty() and not self._untold
