"""The live WebSockets (a flight's, a planning job's) send and never listen: a client that
speaks is closed, and only so many may be open, overall and per flight or job.

Each open socket costs the service a queue and a loop task, and whatever its client
parks in a frame (uvicorn's `ws_max_size` bounds that, `serve.py`), so an
unauthenticated client must not be able to open them without end nor fill them.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections import Counter
from collections.abc import AsyncIterator, Awaitable

from starlette.websockets import WebSocket, WebSocketDisconnect

SPOKE = 1008  # policy violation: these sockets only send
FULL = 1013  # try again later


class LiveSockets:
    """How many live sockets are open, overall and per flight or job."""

    def __init__(self, most: int, most_per_subject: int) -> None:
        self.most, self.most_per_subject = most, most_per_subject
        self.open: Counter[str] = Counter()

    @contextlib.asynccontextmanager
    async def admitted(self, websocket: WebSocket, subject: str) -> AsyncIterator[bool]:
        """Accept `websocket` and yield True, or close it (1013, saying which cap) and
        yield False when the caps are reached. Its place is taken before the accept is
        awaited: checked after it, two sockets opened one after the other could both be
        let in under load."""
        full = self._full(subject)
        if full is not None:
            await websocket.accept()
            await websocket.close(code=FULL, reason=full)
            yield False
            return
        self.open[subject] += 1
        try:
            await websocket.accept()
            yield True
        finally:
            self.open[subject] -= 1
            if not self.open[subject]:
                del self.open[subject]

    def _full(self, subject: str) -> str | None:
        if self.open.total() >= self.most:
            return f"{self.most} live sockets are open: the service's limit"
        if self.open[subject] >= self.most_per_subject:
            return f"{self.most_per_subject} live sockets are open on {subject}: the limit"
        return None


async def send_until_done(websocket: WebSocket, sending: Awaitable[None]) -> None:
    """Run `sending` (which closes the socket when it is done) while reading what the
    client sends: a message closes the socket (1008), a disconnect ends it quietly."""
    sender = asyncio.ensure_future(sending)
    listener = asyncio.ensure_future(_close_if_spoken_to(websocket))
    try:
        await asyncio.wait({sender, listener}, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for task in (sender, listener):
            task.cancel()
        for task in (sender, listener):
            with contextlib.suppress(asyncio.CancelledError, WebSocketDisconnect, RuntimeError):
                await task


async def _close_if_spoken_to(websocket: WebSocket) -> None:
    message = await websocket.receive()
    if message["type"] == "websocket.receive":
        await websocket.close(code=SPOKE, reason="this socket only sends")
