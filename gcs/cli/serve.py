"""`mvo-gcs serve`: the planning service alone, for real vehicles."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import uvicorn

from gcs.cli.main import StorageRefused
from gcs.service.api.app import create_app
from gcs.service.http_limits import server_config
from gcs.service.settings import Settings
from gcs.service.storage import Database
from gcs.service.storage.schema import SchemaTooNew


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host", default=None, help="bind address (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=None, help="TCP port (default 8000)")
    parser.add_argument(
        "--data-dir",
        type=Path,
        default=None,
        help="where the SQLite file and the token live (default ./mvo-gcs-data)",
    )
    parser.add_argument("--workers", type=int, default=None, help="planning processes (default 2)")


def settings_from(args: argparse.Namespace) -> Settings:
    """Flags override `MVO_GCS_*` environment variables, which override defaults."""
    given = {
        "host": args.host,
        "port": args.port,
        "data_dir": args.data_dir,
        "plan_workers": args.workers,
    }
    return Settings(**{k: v for k, v in given.items() if v is not None})


def run(args: argparse.Namespace) -> int:
    os.umask(0o077)  # the database's journal files too: the owner's only
    settings = settings_from(args)
    upgrade_storage(settings)
    serve(settings)
    return 0


def upgrade_storage(settings: Settings) -> None:
    """Bring the database to this version's schema before serving, so that one a newer
    mvo-gcs has migrated is refused in one line (exit 2), not by a traceback from the
    server's start-up."""
    try:
        Database(settings.resolved_database_url).close()
    except SchemaTooNew as exc:
        raise StorageRefused(str(exc)) from exc


def serve(settings: Settings) -> None:
    server = uvicorn.Server(server_config(create_app(settings), settings, log_level="info"))
    server.run()
