"""Property-based tests of the whole API from its own OpenAPI schema (schemathesis's
command line, which runs its examples, coverage, fuzzing and stateful phases): no 5xx,
every status code documented, every answer matching its schema, invalid data refused."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tests.service_process import TOKEN, ServiceProcess

# `positive_data_acceptance` is left out on purpose: a scenario can be valid by its JSON
# schema and still be refused (422) by rules a schema cannot state (cells inside the grid,
# reachable goals, the evaluation budget of a plan request).
CHECKS_LEFT_OUT = "positive_data_acceptance"


def test_schemathesis_finds_no_server_error_and_no_schema_violation(tmp_path: Path) -> None:
    service = ServiceProcess(
        tmp_path / "data",
        {"MVO_GCS_MAX_PLAN_EVALUATIONS": "20000", "MVO_GCS_INLINE_PLAN_WAIT_S": "0"},
    )
    service.start()
    try:
        run = subprocess.run(
            [
                sys.executable,
                "-m",
                "schemathesis.cli",
                "run",
                f"{service.url}/openapi.json",
                "--header",
                f"Authorization: Bearer {TOKEN}",
                "--checks",
                "all",
                "--exclude-checks",
                CHECKS_LEFT_OUT,
                "--max-examples",
                "30",
                "--seed",
                "1",
                "--workers",
                "1",
                "--request-timeout",
                "60",
            ],
            capture_output=True,
            text=True,
            timeout=400,
            cwd=tmp_path,
        )
    finally:
        service.stop()
    assert run.returncode == 0, run.stdout[-6000:] + run.stderr[-2000:]
    assert " passed" in run.stdout and "failure" not in run.stdout.split("SUMMARY")[-1]
