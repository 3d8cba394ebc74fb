"""Engine, sessions, the storage threads, and the recovery that runs when the service starts.

Opening a database upgrades its schema first (`schema.upgrade`).

Every storage call runs on the database's own threads, never on the event loop: a
SQLite write costs milliseconds and a PostgreSQL one a network round trip, either of
which would stall every vehicle link for as long. `Database.run` is the one door; the
repositories' async methods all go through it.
"""

from __future__ import annotations

import asyncio
import functools
import os
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from datetime import timedelta
from pathlib import Path
from typing import Any, TypeVar

from sqlalchemy import ColumnElement, Engine, create_engine, event, or_, select, true, update
from sqlalchemy.engine import make_url
from sqlalchemy.orm import Session, sessionmaker

from gcs.fleet.events import EventKind
from gcs.service.states import OPEN, FlightState, JobState
from gcs.service.storage import schema
from gcs.service.storage.tables import EventRow, FlightRow, JobRow, now

T = TypeVar("T")
STORAGE_THREADS = 4
SQLITE_BUSY_TIMEOUT_S = 10.0
RESTARTED = "the service restarted"


class Database:
    def __init__(self, url: str) -> None:
        is_sqlite = url.startswith("sqlite")
        if is_sqlite:
            _private_sqlite_file(url)
        self.engine: Engine = create_engine(
            url,
            connect_args={"check_same_thread": False, "timeout": SQLITE_BUSY_TIMEOUT_S}
            if is_sqlite
            else {},
        )
        if is_sqlite:
            event.listen(self.engine, "connect", _sqlite_pragmas)
        try:
            schema.upgrade(self.engine)
        except BaseException:  # SchemaTooNew (a newer mvo-gcs migrated it), or unreachable
            self.engine.dispose()
            raise
        self._sessions = sessionmaker(self.engine, expire_on_commit=False)
        self._threads = ThreadPoolExecutor(STORAGE_THREADS, thread_name_prefix="storage")

    @contextmanager
    def session(self) -> Iterator[Session]:
        """One unit of work: committed on success, rolled back on any error."""
        with self._sessions() as session, session.begin():
            yield session

    async def run(self, fn: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        """`fn(*args, **kwargs)` on a storage thread; the event loop goes on meanwhile."""
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self._threads, functools.partial(fn, *args, **kwargs))

    def recover(
        self, holder: tuple[str, str] | None = None, lease_s: float = 0.0
    ) -> dict[str, int]:
        """Mark what a previous run left unfinished, so nothing is lost silently: planning
        jobs become `interrupted` (their processes died with the service) and every open
        flight becomes `interrupted` (nobody followed it while the service was down; its
        vehicles may still be in the air, so it keeps them until they are down).

        With `holder` (this service's id and URL) the open flights become its own, under a
        lease of `lease_s`; on a database several services share (not SQLite) only what
        no live service holds is touched: rows of nobody, of this id, or whose lease ran
        out (`leases.py`)."""
        shared = holder is not None and self.engine.dialect.name != "sqlite"
        dead_job = unheld(JobRow, holder[0]) if shared and holder else true()
        dead = unheld(FlightRow, holder[0]) if shared and holder else true()
        with self.session() as s:
            jobs = rowcount(
                s.execute(
                    update(JobRow)
                    .where(
                        JobRow.state.in_([JobState.QUEUED, JobState.RUNNING]),
                        dead_job,
                    )
                    .values(
                        state=JobState.INTERRUPTED, error="the service stopped", updated_at=now()
                    )
                )
            )
            open_ids = list(
                s.scalars(select(FlightRow.id).where(FlightRow.state.in_(sorted(OPEN)), dead))
            )
            was_open = FlightRow.state.in_(sorted(OPEN - {FlightState.INTERRUPTED}))
            ids = list(s.scalars(select(FlightRow.id).where(was_open, FlightRow.id.in_(open_ids))))
            s.execute(
                update(FlightRow)
                .where(FlightRow.id.in_(ids))
                .values(state=FlightState.INTERRUPTED, note=RESTARTED)
            )
            if holder is not None:
                s.execute(
                    update(FlightRow)
                    .where(FlightRow.id.in_(open_ids))
                    .values(
                        owner_id=holder[0],
                        owner_url=holder[1],
                        lease_expires_at=now() + timedelta(seconds=lease_s),
                    )
                )
            s.add_all(_interrupted_event(flight_id) for flight_id in ids)
        return {"jobs": jobs, "flights": len(ids)}

    def close(self) -> None:
        self._threads.shutdown(wait=True, cancel_futures=False)
        self.engine.dispose()


def unheld(table: type[FlightRow] | type[JobRow], holder_id: str) -> ColumnElement[bool]:
    """Rows no live service holds: nobody's, this service id's, or past their lease."""
    return or_(
        table.owner_id.is_(None), table.owner_id == holder_id, table.lease_expires_at < now()
    )


def _interrupted_event(flight_id: str) -> EventRow:
    """The state change the flight's event history would have had, had it been made
    while the service ran (as `FlightBook.transition` records it)."""
    state = FlightState.INTERRUPTED.value
    kind = EventKind.FLIGHT_STATE
    message = {"type": "event", "kind": kind, "state": state, "note": RESTARTED}
    return EventRow(flight_id=flight_id, kind=kind, data=message)


def rowcount(result: Any) -> int:
    """How many rows a DELETE or UPDATE touched (a CursorResult's, untyped in Result)."""
    return int(result.rowcount)


def _private_sqlite_file(url: str) -> None:
    """Create the SQLite file readable by its owner only (it holds every plan and flight)."""
    database = make_url(url).database
    if not database or database == ":memory:":
        return
    path = Path(database)
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        os.close(os.open(path, os.O_WRONLY | os.O_CREAT, 0o600))


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.close()
