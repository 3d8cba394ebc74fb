"""MAVProxy (PyPI `MAVProxy`) as a subprocess driven over its standard input, headless.

`--non-interactive` would ignore standard input, and `--cmd` runs before a vehicle is
seen (a `wp load` then goes to nobody), so commands are written to stdin once MAVProxy
says what they need. Its output is read on a thread; every wait is bounded; it is
stopped by its process id (SIGTERM, which MAVProxy handles by shutting down cleanly).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

STOP_S = 10.0
SIGNAL_WAIT_S = 1.0  # after each signal, before the next
POLL_S = 0.05


def mavproxy_executable() -> str:
    """mavproxy.py beside this Python (the test extra installs it)."""
    beside = Path(sys.executable).parent / "mavproxy.py"
    found = str(beside) if beside.exists() else shutil.which("mavproxy.py")
    assert found, "MAVProxy is a test dependency: pip install -e '.[test]'"
    return found


class MavProxy:
    """One MAVProxy process; its working directory and HOME are `workdir` (logs, params)."""

    def __init__(self, master: str, workdir: Path) -> None:
        env = {**os.environ, "HOME": str(workdir), "PYTHONUNBUFFERED": "1"}
        env.pop("DISPLAY", None)
        self._proc = subprocess.Popen(
            [mavproxy_executable(), f"--master={master}"],
            cwd=workdir,
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        self._lines: list[str] = []
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self._proc.stdout is not None
        for line in self._proc.stdout:
            with self._lock:
                self._lines.append(line.rstrip("\n"))

    @property
    def output(self) -> list[str]:
        with self._lock:
            return list(self._lines)

    def wait_for(self, text: str, timeout: float, after: int = 0) -> int | None:
        """Index of the first output line from `after` on that contains `text`, or None."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            lines = self.output
            for index in range(after, len(lines)):
                if text in lines[index]:
                    return index
            if self._proc.poll() is not None:
                return None
            time.sleep(POLL_S)
        return None

    def command(self, line: str) -> int:
        """Type a command; returns how many output lines there were before it."""
        before = len(self.output)
        assert self._proc.stdin is not None
        self._proc.stdin.write(line + "\n")
        self._proc.stdin.flush()
        return before

    def stop(self) -> None:
        """By process id: SIGTERM asks MAVProxy to shut down, a second one forces it (its
        own handler says so), SIGKILL if even that is not over in time; bounded waits."""
        for signal_it in (self._proc.terminate, self._proc.terminate, self._proc.kill):
            if self._proc.poll() is not None:
                break
            signal_it()
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._proc.wait(timeout=SIGNAL_WAIT_S)
        self._proc.wait(timeout=STOP_S)
        self._reader.join(timeout=STOP_S)
        if self._proc.stdin is not None:
            self._proc.stdin.close()
