"""`create_app()` in the test's process: an HTTP client on its ASGI interface, the live
WebSockets through httpx-ws, and simulated vehicles in memory."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Awaitable, Callable
from pathlib import Path
from typing import Any, Literal, TypeVar, overload

import httpx
from fastapi import FastAPI
from httpx_ws import AsyncWebSocketSession, aconnect_ws
from httpx_ws.transport import ASGIWebSocketTransport

from gcs.service.api.app import create_app
from gcs.service.settings import Settings
from tests.inprocess.vehicles import SimulatedVehicles

TOKEN = "test-token-0123456789"
BASE_URL = "http://127.0.0.1"
T = TypeVar("T")


def test_settings(data_dir: Path, **overrides: Any) -> Settings:
    """No discovery port (nothing shared between tests), plans in a thread (the clock
    stands still while it plans), the test's token."""
    values: dict[str, Any] = {
        "data_dir": data_dir,
        "token": TOKEN,
        "discovery_url": "",
        "plan_workers": 0,
        **overrides,
    }
    return Settings(**values)


class InProcessService:
    """One service instance; `restart()` stops it cleanly and starts another on the same
    data directory, as `mvo-gcs serve` would be restarted."""

    def __init__(self, data_dir: Path, vehicles: SimulatedVehicles, **settings: Any) -> None:
        self.settings = test_settings(data_dir, **settings)
        self.vehicles = vehicles
        self.app: FastAPI | None = None
        self.client: httpx.AsyncClient
        self._stack: contextlib.AsyncExitStack | None = None

    async def start(self) -> None:
        stack = contextlib.AsyncExitStack()
        app = create_app(self.settings, opener=self.vehicles.open)
        await stack.enter_async_context(app.router.lifespan_context(app))
        self.app, self._stack = app, stack
        self.client = await stack.enter_async_context(self.anonymous(TOKEN))

    async def stop(self) -> None:
        if self._stack is not None:
            await self._stack.aclose()
            self._stack, self.app = None, None

    async def restart(self) -> None:
        await self.stop()
        await self.start()

    def anonymous(self, token: str | None = None) -> httpx.AsyncClient:
        """Another client of the same app: without a token, or with `token`."""
        assert self.app is not None
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        return httpx.AsyncClient(
            transport=httpx.ASGITransport(self.app), base_url=BASE_URL, headers=headers
        )

    @contextlib.asynccontextmanager
    async def websocket(
        self, path: str, headers: dict[str, str] | None = None
    ) -> AsyncIterator[AsyncWebSocketSession]:
        """A live WebSocket (its transport runs a task group: enter and leave it in one
        task, as a test body does)."""
        assert self.app is not None
        transport = ASGIWebSocketTransport(self.app)
        async with (
            httpx.AsyncClient(transport=transport, base_url=BASE_URL) as client,
            aconnect_ws(
                path,
                client,
                headers=dict(headers or {}),
                session_class=AsyncWebSocketSession,
            ) as ws,
        ):
            yield ws


# A condition's False or None is waited past, so it is no part of the value's type.
@overload
async def until(
    condition: Callable[[], Awaitable[T | Literal[False] | None]],
    timeout: float,
    what: str,
    every: float = 0.1,
) -> T: ...


@overload
async def until(
    condition: Callable[[], T | Literal[False] | None],
    timeout: float,
    what: str,
    every: float = 0.1,
) -> T: ...


async def until(condition: Callable[[], Any], timeout: float, what: str, every: float = 0.1) -> Any:
    """The first truthy value of `condition()`, looked at every `every` seconds of the
    loop's (virtual) clock; AssertionError after `timeout` of them."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while True:
        value = condition()
        if asyncio.iscoroutine(value) or isinstance(value, asyncio.Future):
            value = await value
        if value:
            return value
        if loop.time() > deadline:
            raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}")
        await asyncio.sleep(every)
