"""A throw-away PostgreSQL server for the tests: Debian's binaries, a cluster in a temporary
directory, reachable only through a Unix socket in it (no TCP port, nothing shared with
another worker or the machine's own cluster), stopped by its process id.

PostgreSQL refuses to run as root; as root the cluster belongs to the `postgres` user.
"""

from __future__ import annotations

import contextlib
import glob
import os
import pwd
import shutil
import signal
import subprocess
import tempfile
import time
import uuid
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, BinaryIO

import psycopg

SUPERUSER = "postgres"
READY_TIMEOUT_S = 30.0
STOP_TIMEOUT_S = 30.0
FAST_SETTINGS = ("fsync=off", "synchronous_commit=off", "full_page_writes=off")
"""A cluster that dies with the test session needs no durability."""


def binaries() -> Path | None:
    """The directory of `initdb` and `postgres`: $PG_BINDIR, Debian's newest
    /usr/lib/postgresql/*/bin, or the PATH; None if there is none."""
    candidates = [os.environ.get("PG_BINDIR", "")]
    candidates += sorted(
        glob.glob("/usr/lib/postgresql/*/bin"), key=lambda p: int(Path(p).parent.name), reverse=True
    )
    found = shutil.which("initdb")
    candidates += [str(Path(found).parent)] if found else []
    for candidate in filter(None, candidates):
        if (Path(candidate) / "initdb").exists() and (Path(candidate) / "postgres").exists():
            return Path(candidate)
    return None


class PostgresServer:
    """One cluster; `database()` makes an empty database of its own for each test."""

    def __init__(self, bindir: Path, settings: Sequence[str] = FAST_SETTINGS) -> None:
        self.bindir = bindir
        self.settings = tuple(settings)  # () for PostgreSQL's own, durable defaults
        self.root = Path(tempfile.mkdtemp(prefix="mvo-pg-"))  # short: socket paths are
        self.data = self.root / "data"
        self._as: dict[str, Any] = {}
        if os.geteuid() == 0:
            owner = pwd.getpwnam(SUPERUSER)
            os.chown(self.root, owner.pw_uid, owner.pw_gid)
            self._as = {"user": owner.pw_uid, "group": owner.pw_gid, "extra_groups": []}
        self.process: subprocess.Popen[bytes] | None = None
        self._log: BinaryIO | None = None

    def start(self) -> None:
        initdb: list[str | Path] = [
            self.bindir / "initdb",
            "-D",
            self.data,
            "-U",
            SUPERUSER,
            "-A",
            "trust",
        ]
        subprocess.run(
            [*initdb, "--no-sync", "--no-instructions", "-E", "UTF8", "--locale=C"],
            cwd=self.root,
            check=True,
            capture_output=True,
            **self._as,
        )
        settings = [f"unix_socket_directories={self.root}", "listen_addresses=", *self.settings]
        self._log = (self.root / "server.log").open("wb")
        postgres: list[str | Path] = [self.bindir / "postgres", "-D", self.data]
        self.process = subprocess.Popen(
            postgres + [arg for setting in settings for arg in ("-c", setting)],
            cwd=self.root,
            stdout=subprocess.DEVNULL,
            stderr=self._log,
            **self._as,
        )
        self._wait_ready()

    def _wait_ready(self) -> None:
        """Until the server accepts a connection (it replays nothing: seconds at most)."""
        deadline = time.monotonic() + READY_TIMEOUT_S
        while True:
            assert self.process is not None
            if self.process.poll() is not None:
                raise RuntimeError(f"postgres exited: {self.log()}")
            try:
                psycopg.connect(self.dsn("postgres")).close()
                return
            except psycopg.OperationalError as exc:
                if time.monotonic() > deadline:
                    raise RuntimeError(f"not ready in {READY_TIMEOUT_S} s: {self.log()}") from exc
                time.sleep(0.02)

    def log(self) -> str:
        path = self.root / "server.log"
        return path.read_text(errors="replace")[-2000:] if path.exists() else ""

    def dsn(self, database: str) -> str:
        return f"host={self.root} user={SUPERUSER} dbname={database}"

    def url(self, database: str) -> str:
        """The SQLAlchemy URL the service takes (`MVO_GCS_DATABASE_URL`)."""
        return f"postgresql+psycopg://{SUPERUSER}@/{database}?host={self.root}"

    @contextlib.contextmanager
    def database(self) -> Iterator[str]:
        """A new empty database's URL, dropped afterwards (with whoever still uses it)."""
        name = f"t_{uuid.uuid4().hex[:16]}"
        self._admin(f'CREATE DATABASE "{name}" STRATEGY FILE_COPY')
        try:
            yield self.url(name)
        finally:
            self._admin(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')

    def _admin(self, sql: str) -> None:
        with psycopg.connect(self.dsn("postgres"), autocommit=True) as connection:
            connection.execute(sql.encode())

    def stop(self) -> None:
        """Fast shutdown by its process id (SIGINT), then the directory goes."""
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        if self._log is not None:
            self._log.close()
        shutil.rmtree(self.root, ignore_errors=True)
