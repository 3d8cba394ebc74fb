"""Limits on HTTP connections that uvicorn leaves open: how long a client may take to send
a request's headers, and how many connections one address may hold.

uvicorn times out an idle keep-alive connection, but any byte resets that timer and
nothing bounds a connection that never finishes its headers: 300 half-sent requests were
held for a minute, and with the descriptors gone the API (the abort included) stopped
answering. `GuardedH11Protocol` closes a connection whose headers are not complete
`header_timeout_s` after it opened (or after its previous response), and refuses a
connection from an address that already holds `per_client` of them. `limit_concurrency`
(uvicorn's own, answered 503) bounds the total. One program on this machine can still
open connections from several loopback addresses; these limits make each cost little
and last briefly, they do not make the service unreachable-proof.
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any

import uvicorn
from uvicorn.protocols.http.h11_impl import H11Protocol

from gcs.service.settings import Settings

log = logging.getLogger("mvo_gcs.http")


class GuardedH11Protocol(H11Protocol):
    header_timeout_s = 10.0
    per_client = 32

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._header_timer: asyncio.TimerHandle | None = None

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        host = self.client[0] if self.client else None
        held = sum(1 for c in self.connections if _host(c) == host)
        if host is not None and held > self.per_client:
            log.warning("refused a connection from %s: it holds %d already", host, held - 1)
            transport.close()
            return
        self._expect_headers()

    def handle_events(self) -> None:
        before = self.cycle
        super().handle_events()
        if self.cycle is not before:  # a request's headers are in: the app has it now
            self._stop_waiting()

    def handle_websocket_upgrade(self, event: Any) -> None:
        self._stop_waiting()  # the WebSocket protocol takes the connection over
        super().handle_websocket_upgrade(event)

    def on_response_complete(self) -> None:
        super().on_response_complete()
        if not self.transport.is_closing():
            self._expect_headers()

    def connection_lost(self, exc: Exception | None) -> None:
        self._stop_waiting()
        super().connection_lost(exc)

    def _expect_headers(self) -> None:
        self._stop_waiting()
        self._header_timer = self.loop.call_later(self.header_timeout_s, self._headers_late)

    def _stop_waiting(self) -> None:
        if self._header_timer is not None:
            self._header_timer.cancel()
            self._header_timer = None

    def _headers_late(self) -> None:
        self._header_timer = None
        if not self.transport.is_closing():
            self.transport.close()


def _host(protocol: object) -> str | None:
    client = getattr(protocol, "client", None)
    return client[0] if client else None


def server_config(app: Any, settings: Settings, **options: Any) -> uvicorn.Config:
    """uvicorn's configuration for the service: its limits on connections and messages."""
    protocol = type(
        "ServiceH11Protocol",
        (GuardedH11Protocol,),
        {
            "header_timeout_s": settings.http_header_timeout_s,
            "per_client": settings.max_connections_per_client,
        },
    )
    return uvicorn.Config(
        app,
        host=settings.host,
        port=settings.port,
        http=protocol,
        limit_concurrency=settings.max_connections,
        ws_max_size=settings.max_ws_message_bytes,  # uvicorn's default parks 16 MB a socket
        **options,
    )
