"""A real `mvo-gcs serve` in a subprocess on a loopback port, for the end-to-end tests."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx

TOKEN = "test-token-0123456789"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ServiceProcess:
    """Start, stop and restart the service on one data directory."""

    def __init__(
        self, data_dir: Path, extra_env: dict[str, str] | None = None, workers: int = 1
    ) -> None:
        self.data_dir = data_dir
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.env = {
            **os.environ,
            "MVO_GCS_TOKEN": TOKEN,
            "MVO_GCS_DISCOVERY_URL": "",  # several services at once: no shared 14550
            **(extra_env or {}),
        }
        self.workers = workers
        self.process: subprocess.Popen[str] | None = None
        self.log = data_dir / "service.log"

    def start(self, timeout: float = 90.0) -> None:
        """Start `mvo-gcs serve` and wait until it is ready: 12-17 s were measured on a
        2-core machine at load 8 (imports, migrations, the planning pool), so the bound
        is generous; a service that dies fails at once."""
        self.data_dir.mkdir(parents=True, exist_ok=True)
        command = [
            sys.executable,
            "-m",
            "gcs.cli",
            "serve",
            "--port",
            str(self.port),
            "--data-dir",
            str(self.data_dir),
            "--workers",
            str(self.workers),
        ]
        with self.log.open("a") as log:
            self.process = subprocess.Popen(
                command, env=self.env, stdout=log, stderr=subprocess.STDOUT, text=True
            )
        deadline = time.monotonic() + timeout
        # One client for all the probes: each new one loads the certificate store, 25 ms
        # of CPU that added up to half a minute of the suite.
        with httpx.Client(timeout=1) as probe:
            while time.monotonic() < deadline:
                if self.process.poll() is not None:
                    raise RuntimeError(f"the service exited: {self.log.read_text()[-2000:]}")
                try:
                    if probe.get(f"{self.url}/health/ready").status_code == 200:
                        return
                except httpx.TransportError:
                    pass
                time.sleep(0.2)
        self.stop()
        raise TimeoutError(f"the service did not get ready: {self.log.read_text()[-2000:]}")

    @property
    def pid(self) -> int:
        assert self.process is not None, "not started"
        return self.process.pid

    def problems(self) -> list[str]:
        """Log lines that say something went wrong (errors, tracebacks, 5xx answers)."""
        marks = ("ERROR", "Traceback", '" 500', '" 502', '" 503')
        lines = self.log.read_text(errors="replace").splitlines()
        return [line for line in lines if any(m in line for m in marks)]

    def stop(self) -> None:
        if self.process is None:
            return
        self.process.terminate()
        try:
            self.process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(timeout=5)
        self.process = None

    def kill(self) -> None:
        """Die without cleaning up, as a crash or power cut would."""
        if self.process is not None:
            self.process.kill()
            self.process.wait(timeout=5)
            self.process = None

    def client(self, token: str | None = TOKEN) -> httpx.Client:
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        return httpx.Client(base_url=self.url, headers=headers, timeout=60)
