"""Alembic's entry point: the migrations run on the connection that
`gcs.service.storage.schema` hands over (the service's own engine, inside its
transaction), or on `sqlalchemy.url` when a developer runs Alembic by hand."""

from __future__ import annotations

from alembic import context
from sqlalchemy import Connection, create_engine

from gcs.service.storage.tables import Base


def _migrate(connection: Connection) -> None:
    context.configure(connection=connection, target_metadata=Base.metadata, compare_type=True)
    with context.begin_transaction():
        context.run_migrations()


_given: Connection | None = context.config.attributes.get("connection")
if _given is not None:
    _migrate(_given)
else:
    _engine = create_engine(context.config.get_main_option("sqlalchemy.url") or "")
    with _engine.connect() as _connection:
        _migrate(_connection)
    _engine.dispose()
