"""Every storage test runs twice: on a SQLite file and on a database of its own in a
PostgreSQL server that this session starts (one per xdist worker, so workers share
nothing). Without PostgreSQL's binaries the PostgreSQL runs skip, saying so."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.storage.postgres import PostgresServer, binaries

NO_POSTGRES = (
    "PostgreSQL's server binaries (initdb, postgres) were not found: install Debian's "
    "`postgresql` (.ci/run does) or set PG_BINDIR"
)


@pytest.fixture(scope="session")
def postgres() -> Iterator[PostgresServer]:
    bindir = binaries()
    if bindir is None:
        pytest.skip(NO_POSTGRES)
    server = PostgresServer(bindir)
    try:
        server.start()
        yield server
    finally:
        server.stop()


@pytest.fixture(params=["sqlite", "postgresql"])
def database_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """An empty database's SQLAlchemy URL, on each kind in turn."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'gcs.db'}"
        return
    server: PostgresServer = request.getfixturevalue("postgres")
    with server.database() as url:
        yield url
