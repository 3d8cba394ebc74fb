"""`python -m gcs.cli` and the `mvo-gcs` script: the command line, imported when run.

The service's planning processes are spawned, and a spawned process imports its parent's
main module again. This module is that main module and imports nothing heavy, so a
spawned process starts in a fraction of a second instead of importing the whole CLI
(the planner, pydantic models, geodesy) only to throw it away."""

from __future__ import annotations

import sys


def run() -> int:
    from gcs.cli.main import main

    return main()


if __name__ == "__main__":
    sys.exit(run())
