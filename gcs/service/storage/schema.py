"""The schema's version: the database is brought to the newest Alembic revision this code
ships (`migrations/`) whenever the service opens it, or refused when it is newer.

Upgrading on start keeps one rule for every install: a data directory from any earlier
version, un-versioned ones included (the baseline adopts their tables), just works
after an upgrade of the package. A database that a newer version has already
migrated is not touched: this code cannot know what its tables mean.
"""

from __future__ import annotations

import functools
import logging
from pathlib import Path
from typing import Any

from alembic.config import Config
from alembic.runtime.environment import EnvironmentContext
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Connection, Engine, func, select

from gcs.service.storage.tables import Base

log = logging.getLogger("mvo_gcs")
MIGRATIONS = Path(__file__).with_name("migrations")
UPGRADE_LOCK = 0x6D766F676373  # "mvogcs"
"""PostgreSQL advisory lock held while migrating: two services starting on one database
take turns instead of both creating the tables."""


class SchemaTooNew(RuntimeError):
    """The database is at a revision this code does not know: a newer mvo-gcs made it."""


def alembic_config(connection: Connection | None = None) -> Config:
    """Alembic's configuration without an alembic.ini: the packaged migrations, run on
    `connection` (see migrations/env.py)."""
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    config.attributes["connection"] = connection
    return config


@functools.cache
def _scripts() -> ScriptDirectory:
    return ScriptDirectory.from_config(alembic_config())


def head() -> str:
    """The newest revision this code ships."""
    revision = _scripts().get_current_head()
    assert revision is not None, "no migrations shipped"
    return revision


def revisions() -> list[str]:
    """Every shipped revision, oldest first."""
    return [script.revision for script in reversed(list(_scripts().walk_revisions()))]


def current(connection: Connection) -> str | None:
    """The database's revision (None: un-versioned, empty or made before versioning)."""
    return MigrationContext.configure(connection).get_current_revision()


def upgrade(engine: Engine) -> None:
    """Bring the database to `head()` in one transaction (on PostgreSQL a migration that
    fails leaves nothing behind), or raise SchemaTooNew saying which revision it is at
    and what to do."""
    with engine.begin() as connection:
        if connection.dialect.name == "postgresql":
            connection.execute(select(func.pg_advisory_xact_lock(UPGRADE_LOCK)))
        found = current(connection)
        if found == head():
            return
        if found is not None and found not in revisions():
            raise SchemaTooNew(
                f"the database {engine.url.render_as_string(hide_password=True)} is at schema "
                f"revision {found!r}, which this mvo-gcs does not know (its newest is "
                f"{head()!r}): a newer mvo-gcs has migrated it. Run that newer mvo-gcs on it, "
                "or give this one another database (MVO_GCS_DATABASE_URL or --data-dir); "
                "nothing was changed"
            )
        log.info("upgrading the database schema from %s to %s", found or "none", head())
        _upgrade(connection)


def _upgrade(connection: Connection) -> None:
    """Alembic's `upgrade head` on the scripts loaded once per process (the command would
    load them, and env.py, again for every database opened: a test suite opens many)."""
    scripts = _scripts()

    def steps(revision: Any, _context: MigrationContext) -> Any:
        return scripts._upgrade_revs("head", revision)

    with EnvironmentContext(alembic_config(connection), scripts, fn=steps) as environment:
        environment.configure(connection=connection, target_metadata=Base.metadata)
        with environment.begin_transaction():
            environment.run_migrations()
