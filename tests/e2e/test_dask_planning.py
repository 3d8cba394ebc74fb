"""Planning on a real Dask cluster: `mvo-gcs serve` with `MVO_GCS_DASK_SCHEDULER` set,
beside a `dask scheduler` and a `dask worker` (one process, one thread) that this module
starts on loopback ports and stops by process id.

The service runs under uvicorn, as deployed: its Dask client is the asynchronous one,
made in the lifespan on uvicorn's loop. Every wait polls a condition with a bound; the
cancellation is counted in optimizer iterations, not seconds.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest

from planner.cases import load_case
from tests.e2e.flying import wait_for
from tests.inprocess.flying import LONG_PLAN
from tests.inprocess.service import InProcessService
from tests.inprocess.vehicles import SimulatedVehicles
from tests.service_process import ServiceProcess, free_port

distributed = pytest.importorskip("distributed")

DASK = str(Path(sys.executable).with_name("dask"))
ROOT = Path(__file__).resolve().parents[2]
# the scheduler and the worker unpickle this module's helpers (and mvo-gcs's planner)
ENV = {
    **os.environ,
    "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
}
CASE_VI = load_case("case-6").model_dump(mode="json")
FINAL = {"done", "failed", "cancelled", "interrupted"}


@dataclass
class Cluster:
    address: str
    scheduler: subprocess.Popen[bytes]
    worker: subprocess.Popen[bytes]  # the nanny: it starts the worker process again
    client: Any  # the test's own (blocking) client, to look at the cluster

    def worker_pids(self) -> dict[str, int]:
        pids: dict[str, int] = self.client.run(os.getpid)
        return pids

    def scheduler_knows(self, key: str) -> bool:
        return bool(self.client.run_on_scheduler(_knows, key=key))

    def jobs_started(self) -> set[str]:
        """The jobs a worker said it started (the service's Dask events)."""
        events: dict[str, list[tuple[float, Any]]] = self.client.get_events()
        return {
            message[1]
            for topic, logged in events.items()
            if topic.startswith("mvo-gcs-progress-")
            for _, message in logged
            if message[0] == "started"
        }


def _knows(key: str, dask_scheduler: Any = None) -> bool:
    return key in dask_scheduler.tasks


def _stop(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is None:
        os.kill(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.kill(process.pid, signal.SIGKILL)
            process.wait(timeout=5)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    logs = tmp_path_factory.mktemp("dask")
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    with (logs / "scheduler.log").open("wb") as log:
        scheduler = subprocess.Popen(
            [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            stdout=log,
            stderr=subprocess.STDOUT,
            env=ENV,
        )
    with (logs / "worker.log").open("wb") as log:
        worker = subprocess.Popen(
            [
                DASK,
                "worker",
                address,
                "--nworkers",
                "1",
                "--nthreads",
                "1",
                "--no-dashboard",
                "--host",
                "127.0.0.1",
            ],
            stdout=log,
            stderr=subprocess.STDOUT,
            env=ENV,
        )
    try:
        with distributed.Client(address, timeout=30, set_as_default=False) as client:
            client.wait_for_workers(1, timeout=60)
            yield Cluster(address, scheduler, worker, client)
    finally:
        _stop(worker)
        _stop(scheduler)


@pytest.fixture(scope="module")
def service(cluster: Cluster, tmp_path_factory: pytest.TempPathFactory) -> Iterator[httpx.Client]:
    process = ServiceProcess(
        tmp_path_factory.mktemp("gcs") / "data",
        extra_env={"MVO_GCS_DASK_SCHEDULER": cluster.address},
    )
    process.start()
    try:
        with process.client() as client:
            yield client
    finally:
        process.stop()


@pytest.fixture(scope="module")
def scenario_id(service: httpx.Client) -> str:
    answer = service.post("/scenarios", json=CASE_VI)
    assert answer.status_code == 201, answer.text
    return str(answer.json()["id"])


def _job(service: httpx.Client, job_id: str) -> dict[str, Any]:
    answer = service.get(f"/jobs/{job_id}")
    assert answer.status_code == 200, answer.text
    job: dict[str, Any] = answer.json()
    return job


def _start_long_job(service: httpx.Client, scenario_id: str) -> tuple[str, dict[str, Any]]:
    """A long job, once its worker's progress reports have reached the service."""
    answer = service.post(f"/scenarios/{scenario_id}/plans", json=LONG_PLAN | {"wait_s": 0})
    assert answer.status_code == 202, answer.text
    job_id = answer.json()["id"]

    def progressing() -> dict[str, Any] | None:
        job = _job(service, job_id)
        assert job["state"] not in FINAL, job
        return job if job["state"] == "running" and job["percent"] > 0 else None

    return job_id, wait_for(progressing, 60, "the job's first progress report")


def _final(service: httpx.Client, job_id: str) -> dict[str, Any]:
    def ended() -> dict[str, Any] | None:
        job = _job(service, job_id)
        return job if job["state"] in FINAL else None

    return wait_for(ended, 30, "the job to end")


async def test_a_plan_on_the_cluster_is_the_local_plan_for_the_same_seed(
    service: httpx.Client,
    scenario_id: str,
    cluster: Cluster,
    tmp_path: Path,
    vehicles: SimulatedVehicles,
) -> None:
    request = {"seed": 11, "iterations": 150, "time_budget_s": None, "wait_s": 60}
    answer = service.post(f"/scenarios/{scenario_id}/plans", json=request)
    assert answer.status_code == 201, answer.text
    on_dask = answer.json()
    assert service.get(f"/plans/{on_dask['id']}").json() == on_dask  # stored
    (job,) = [job for job in service.get("/jobs").json() if job["plan_id"] == on_dask["id"]]
    assert job["id"] in cluster.jobs_started()  # it ran on the cluster
    local = InProcessService(tmp_path / "local", vehicles)  # plans in this process
    await local.start()
    try:
        sid = (await local.client.post("/scenarios", json=CASE_VI)).json()["id"]
        here = await local.client.post(f"/scenarios/{sid}/plans", json=request)
        assert here.status_code == 201, here.text
    finally:
        await local.stop()
    mine, theirs = here.json()["plan"], on_dask["plan"]
    assert theirs["feasible"] and theirs["seed"] == 11
    assert theirs["uavs"] == mine["uavs"]
    assert theirs["conflicts"] == mine["conflicts"]


def test_a_job_on_the_cluster_reports_progress_and_stops_within_an_iteration(
    service: httpx.Client, scenario_id: str
) -> None:
    job_id, running = _start_long_job(service, scenario_id)
    assert 0 < running["percent"] < 100 and running["best_cost"] is not None
    assert service.post(f"/jobs/{job_id}/cancel").status_code == 202
    job = _final(service, job_id)
    assert job["state"] == "cancelled" and job["plan_id"] is None, job
    stopped = re.search(r"worker stopped (\d+) optimizer iteration", job["error"] or "")
    assert stopped is not None, job
    assert int(stopped[1]) <= 1, job


def test_a_worker_killed_mid_job_fails_the_job_which_is_not_run_again(
    service: httpx.Client, scenario_id: str, cluster: Cluster
) -> None:
    job_id, _ = _start_long_job(service, scenario_id)
    (pid,) = cluster.worker_pids().values()
    os.kill(pid, signal.SIGKILL)
    job = _final(service, job_id)
    assert job["state"] == "failed", job
    assert "WorkerLost" in job["error"] and "not re-run" in job["error"], job
    # cancelled on the scheduler: not run again when the nanny's new worker comes up
    wait_for(lambda: not cluster.scheduler_knows(f"mvo-gcs-plan-{job_id}"), 30, "the task gone")
