"""A TCP relay between the service and one SITL instance that can drop everything for a
while: a link loss, both ways, on a real autopilot (its own second port, which the
observer listens on, is untouched)."""

from __future__ import annotations

import contextlib
import selectors
import socket
import threading
import time


class Relay:
    """Forwards one TCP connection at a time to `target_port`; `cut(seconds)` drops
    what either side sends for that long (wall seconds)."""

    def __init__(self, target_port: int) -> None:
        self.target_port = target_port
        self._server = socket.create_server(("127.0.0.1", 0))
        self.port: int = self._server.getsockname()[1]
        self._cut_until = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    @property
    def connection(self) -> str:
        return f"tcp:127.0.0.1:{self.port}"

    def cut(self, seconds: float) -> None:
        self._cut_until = time.monotonic() + seconds

    def _serve(self) -> None:
        self._server.settimeout(0.2)
        while not self._stop.is_set():
            try:
                client, _ = self._server.accept()
            except TimeoutError:
                continue
            with client, socket.create_connection(("127.0.0.1", self.target_port)) as vehicle:
                self._forward(client, vehicle)

    def _forward(self, a: socket.socket, b: socket.socket) -> None:
        with selectors.DefaultSelector() as selector:
            selector.register(a, selectors.EVENT_READ, b)
            selector.register(b, selectors.EVENT_READ, a)
            while not self._stop.is_set():
                for key, _ in selector.select(timeout=0.2):
                    source, sink = key.fileobj, key.data
                    assert isinstance(source, socket.socket)
                    try:
                        data = source.recv(65536)
                    except OSError:
                        return
                    if not data:
                        return  # one side closed: wait for the next connection
                    if time.monotonic() >= self._cut_until:
                        with contextlib.suppress(OSError):
                            sink.sendall(data)

    def __enter__(self) -> Relay:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self._server.close()
