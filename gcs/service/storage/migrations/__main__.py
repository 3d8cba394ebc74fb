"""`python -m gcs.service.storage.migrations "what changed" [DATABASE_URL]`: a developer's
first draft of the next revision, by Alembic's autogenerate: what tables.py has that a
database at the current head (a scratch SQLite file by default) lacks. Read and edit it
before committing: autogenerate misses renames and data moves."""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

from alembic import command

from gcs.service.storage import schema
from gcs.service.storage.database import Database


def draft(message: str, url: str, version_path: Path | None = None) -> Path:
    """Write versions/NNNN_<message>.py (or into `version_path`); its path."""
    Database(url).close()  # at head, so that the draft holds only the new change
    config = schema.alembic_config()
    config.set_main_option("sqlalchemy.url", url)
    if version_path is not None:  # the tests' drafts go elsewhere
        here = schema.MIGRATIONS / "versions"
        config.set_main_option("path_separator", "os")
        config.set_main_option("version_locations", os.pathsep.join([str(here), str(version_path)]))
    script = command.revision(
        config,
        message,
        autogenerate=True,
        rev_id=f"{int(schema.head()) + 1:04d}",
        version_path=str(version_path) if version_path else None,
    )
    assert script is not None and not isinstance(script, list)
    return Path(script.path)


def main() -> None:
    parser = argparse.ArgumentParser(prog="python -m gcs.service.storage.migrations")
    parser.add_argument("message", help="what the revision changes, e.g. 'index jobs by state'")
    parser.add_argument(
        "url", nargs="?", help="a database to compare with (default: a scratch one)"
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        print(draft(args.message, args.url or f"sqlite:///{scratch}/draft.db"))


if __name__ == "__main__":
    main()
