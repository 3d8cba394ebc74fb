"""A bounded queue of one vehicle's messages that a coroutine reads at its own pace.

A subscription never blocks the receiving side: when the reader falls behind, the
oldest messages are dropped. A link fault (link lost, reboot) can be delivered to it
so that a reader blocked in `get` learns at once that its exchange is over.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Callable, Iterable
from typing import Any

from gcs.mavlink.errors import WaitTimeoutError

Predicate = Callable[[Any], bool]


class Subscription:
    def __init__(
        self,
        types: Iterable[str] | None,
        on_close: Callable[[Subscription], None],
        *,
        maxsize: int = 256,
        fail_on_fault: bool = True,
    ) -> None:
        self.types = frozenset(types) if types else None
        self.fail_on_fault = fail_on_fault
        self._queue: asyncio.Queue[Any] = asyncio.Queue(maxsize)
        self._on_close = on_close
        self._fault: BaseException | None = None

    def wants(self, msg_type: str) -> bool:
        return self.types is None or msg_type in self.types

    def put(self, msg: Any) -> None:
        if self._queue.full():
            self._queue.get_nowait()
        self._queue.put_nowait(msg)

    def fail(self, exc: BaseException) -> None:
        """Make the next `get` raise `exc` (after nothing: the fault ends the exchange)."""
        self._fault = exc
        self.put(None)

    async def get(self, timeout: float) -> Any:
        """The next message, or WaitTimeoutError after `timeout` seconds."""
        if self._fault is not None:
            raise self._fault
        try:  # asyncio.timeout, not wait_for: 3.11's wait_for can swallow a cancellation
            async with asyncio.timeout(timeout):
                msg = await self._queue.get()
        except TimeoutError:
            raise WaitTimeoutError(f"no {self._describe()} within {timeout:.2f} s") from None
        if self._fault is not None:
            raise self._fault
        return msg

    async def next_matching(self, predicate: Predicate | None, timeout: float) -> Any:
        """The next message `predicate` accepts, within `timeout` seconds overall."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        while True:
            msg = await self.get(max(0.0, deadline - loop.time()))
            if predicate is None or predicate(msg):
                return msg

    def drain(self) -> list[Any]:
        """Everything queued now, without waiting."""
        out = []
        while not self._queue.empty():
            out.append(self._queue.get_nowait())
        return [m for m in out if m is not None]

    def close(self) -> None:
        self._on_close(self)

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __aiter__(self) -> AsyncIterator[Any]:
        return self._iterate()

    async def _iterate(self) -> AsyncIterator[Any]:
        while True:
            msg = await self._queue.get()
            if self._fault is not None:
                raise self._fault
            yield msg

    def _describe(self) -> str:
        return " or ".join(sorted(self.types)) if self.types else "message"
