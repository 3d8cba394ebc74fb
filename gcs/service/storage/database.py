"""Engine, sessions and the recovery that runs when the service starts."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from sqlalchemy import Engine, create_engine, event, update
from sqlalchemy.orm import Session, sessionmaker

from gcs.service.storage.tables import Base, FlightRow, JobRow, now

UNFINISHED_JOB_STATES = ("queued", "running")
AIRBORNE_FLIGHT_STATES = ("uploading", "starting", "flying", "paused")


class Database:
    def __init__(self, url: str) -> None:
        is_sqlite = url.startswith("sqlite")
        self.engine: Engine = create_engine(
            url, connect_args={"check_same_thread": False} if is_sqlite else {}
        )
        if is_sqlite:
            event.listen(self.engine, "connect", _sqlite_pragmas)
        Base.metadata.create_all(self.engine)
        self._sessions = sessionmaker(self.engine, expire_on_commit=False)

    @contextmanager
    def session(self) -> Iterator[Session]:
        """One unit of work: committed on success, rolled back on any error."""
        with self._sessions() as session, session.begin():
            yield session

    def recover(self) -> dict[str, int]:
        """Mark what a previous run left unfinished, so nothing is lost silently: planning
        jobs become `interrupted` (their processes died with the service) and flights
        in the air become `interrupted` (nobody followed them while the service was down)."""
        with self.session() as s:
            jobs = rowcount(
                s.execute(
                    update(JobRow)
                    .where(JobRow.state.in_(UNFINISHED_JOB_STATES))
                    .values(state="interrupted", error="the service stopped", updated_at=now())
                )
            )
            flights = rowcount(
                s.execute(
                    update(FlightRow)
                    .where(FlightRow.state.in_(AIRBORNE_FLIGHT_STATES))
                    .values(state="interrupted")
                )
            )
        return {"jobs": jobs, "flights": flights}

    def close(self) -> None:
        self.engine.dispose()


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.close()


def rowcount(result: Any) -> int:
    """How many rows a DELETE or UPDATE touched (a CursorResult's, untyped in Result)."""
    return int(result.rowcount)
