"""The service's helper processes end when the service does.

Its own module, importing nothing else of the product: it is the first thing a spawned
helper process (the planning pool's manager and workers) imports, so it must be cheap."""

from __future__ import annotations

import os
import threading
import time


def exit_with_parent(owner_pid: int) -> None:
    """In each helper process: end it if the service dies without cleaning up (a crash,
    SIGKILL), rather than leave an orphan planning for nobody."""

    def watch() -> None:
        while os.getppid() == owner_pid:
            time.sleep(1.0)
        os._exit(0)

    threading.Thread(target=watch, daemon=True, name="exit-with-parent").start()
