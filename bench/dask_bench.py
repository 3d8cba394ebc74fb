"""Planning-job throughput of `mvo-gcs serve` on a Dask cluster of 1 and 2 workers,
beside the local pool's with 1 and 2 planning processes.

For each set-up a fresh service (SQLite, fresh data directory) gets JOBS plan requests
for the paper's case VI at once (`wait_s` 0: each answered 202 with a job), and the
bench polls GET /jobs every 0.1 s until every job is done. Throughput = jobs /
(first request sent .. last job seen done). A Dask worker here is `dask worker
--nthreads 1` (one planning thread per process, as the local pool's processes); the
scheduler, the workers, the service and this client all run on this machine.

The four set-ups run one after another, `--rounds` times over (so that a change in the
machine's load meets each of them); the ratio is reported per round and as the median.

Usage: PYTHONPATH=. .venv/bin/python bench/dask_bench.py [--jobs 24] [--rounds 2]
       [--out bench/results/dask.md]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import httpx

from planner.cases import load_case
from planner.experiments.machine import cpu_model
from tests.service_process import ServiceProcess, free_port

DASK = str(Path(sys.executable).with_name("dask"))
ROOT = Path(__file__).resolve().parents[1]
# The paper's flow, every iteration run: about half a second of one core per plan, so that the
# workers' compute, not the per-job overheads, is what is measured.
SETTINGS = {"objective": "paper", "population": 30, "iterations": 200, "patience": None}
REQUEST = {**SETTINGS, "time_budget_s": None, "wait_s": 0}


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


@contextmanager
def dask_cluster(workers: int, logs: Path) -> Iterator[str]:
    import distributed

    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = (logs / f"dask-{workers}.log").open("wb")
    scheduler = subprocess.Popen(
        [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
        stdout=out,
        stderr=subprocess.STDOUT,
        env=env,
    )
    worker = subprocess.Popen(
        [
            DASK,
            "worker",
            address,
            "--nworkers",
            str(workers),
            "--nthreads",
            "1",
            "--no-dashboard",
            "--host",
            "127.0.0.1",
        ],
        stdout=out,
        stderr=subprocess.STDOUT,
        env=env,
    )
    try:
        with distributed.Client(address, timeout=60) as client:
            client.wait_for_workers(workers, timeout=120)
        yield address
    finally:
        for process in (worker, scheduler):
            process.terminate()
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        out.close()


def run_jobs(client: httpx.Client, scenario: str, requests: list[dict[str, Any]]) -> None:
    """Send every request at once, then wait until each job is done."""
    ids = []
    for request in requests:
        answer = client.post(f"/scenarios/{scenario}/plans", json=request)
        assert answer.status_code in (201, 202), answer.text
        ids.append(answer.json()["id"])
    pending = set(ids)
    while pending:  # one request a look (GET /jobs), so that polling costs the cores little
        for job in client.get("/jobs", params={"limit": 200}).json():
            if job["id"] not in pending:
                continue
            if job["state"] == "done":
                pending.discard(job["id"])
            elif job["state"] in ("failed", "cancelled", "interrupted"):
                raise RuntimeError(f"job {job['id']} ended {job['state']}")
        if pending:
            time.sleep(0.1)


def throughput(service: ServiceProcess, jobs: int, workers: int) -> tuple[float, float]:
    """(jobs per second, seconds) for `jobs` requests sent at once."""
    with service.client() as client:
        sid = client.post("/scenarios", json=load_case("case-6").model_dump(mode="json"))
        scenario = sid.json()["id"]
        warm = {**REQUEST, "iterations": 20}  # every worker imports the planner first
        run_jobs(client, scenario, [warm | {"seed": seed} for seed in range(2 * workers)])
        started = time.perf_counter()
        run_jobs(client, scenario, [REQUEST | {"seed": seed} for seed in range(jobs)])
        seconds = time.perf_counter() - started
    return jobs / seconds, seconds


def measure(label: str, jobs: int, env: dict[str, str], workers: int, tmp: Path) -> dict[str, str]:
    """One set-up: a fresh service (`workers` local processes, unless `env` points it at
    a Dask cluster of `workers` workers)."""
    before = load()
    data = tmp / f"{label.replace(' ', '-')}-{time.monotonic_ns()}"
    service = ServiceProcess(data, extra_env=env, workers=workers)
    service.start(timeout=120)
    try:
        rate, seconds = throughput(service, jobs, workers)
    finally:
        service.stop()
    row = {"label": label, "rate": f"{rate:.2f}", "seconds": f"{seconds:.1f}"}
    row |= {"before": before, "after": load()}
    print(row, flush=True)
    return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=24)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--out", type=Path, default=ROOT / "bench/results/dask.md")
    args = parser.parse_args()
    started = time.perf_counter()
    first_load = load()
    rounds: list[dict[str, dict[str, str]]] = []
    with tempfile.TemporaryDirectory(prefix="mvo-gcs-dask-bench-") as name:
        tmp = Path(name)
        for _ in range(args.rounds):
            rows = {}
            for workers in (1, 2):
                label = f"local {workers}"
                rows[label] = measure(label, args.jobs, {}, workers, tmp)
                with dask_cluster(workers, tmp) as address:
                    env = {"MVO_GCS_DASK_SCHEDULER": address}
                    label = f"dask {workers}"
                    rows[label] = measure(label, args.jobs, env, workers, tmp)
            rounds.append(rows)
    one = one_plan_s()
    wall = time.perf_counter() - started
    write(args.out, rounds, args.jobs, first_load, load(), wall, one)
    return 0


def one_plan_s() -> float:
    """One plan of REQUEST's settings in this process, median of 3."""
    from planner.pipeline import PlannerSettings, plan

    scenario = load_case("case-6")
    settings = PlannerSettings(**SETTINGS, time_budget_s=None)  # type: ignore[arg-type]
    times = []
    for _ in range(3):
        started = time.perf_counter()
        plan(scenario, settings)
        times.append(time.perf_counter() - started)
    return sorted(times)[1]


def write(
    out: Path,
    rounds: list[dict[str, dict[str, str]]],
    jobs: int,
    before: str,
    after: str,
    wall: float,
    one: float,
) -> None:
    def ratio(rows: dict[str, dict[str, str]], kind: str) -> float:
        return float(rows[f"{kind} 2"]["rate"]) / float(rows[f"{kind} 1"]["rate"])

    lines = [
        "# Planning-job throughput: a Dask cluster of 1 and 2 workers, the local pool beside it",
        "",
        f"- date: {datetime.now(UTC):%Y-%m-%d %H:%M} UTC",
        f"- machine: {cpu_model()}, {os.cpu_count()} cores, {platform.system()} "
        f"{platform.release()}, Python {platform.python_version()}",
        f"- load average before / after the whole run: {before} / {after}",
        f"- command: `PYTHONPATH=. .venv/bin/python bench/dask_bench.py --jobs {jobs} "
        f"--rounds {len(rounds)}`",
        f"- wall time of the whole script: {wall:.0f} s",
        f"- jobs: {jobs} plan requests for case VI at once, MVO, the paper's flow "
        "(objective `paper`), population 30, 200 iterations, no patience, no time budget, "
        "seeds 0..; each answered 202, then all polled by one GET /jobs every 0.1 s. "
        "One plan in this process: "
        f"{one:.2f} s (median of 3). Before each measurement, 2 short jobs per worker "
        "(every worker has imported the planner)",
        "- Dask: `dask scheduler` and `dask worker --nworkers N --nthreads 1` on 127.0.0.1, "
        "the service with `MVO_GCS_DASK_SCHEDULER`; local: `mvo-gcs serve --workers N`; "
        "a fresh service (SQLite) and cluster for each measurement",
        "",
        "| round | set-up | workers | jobs/s | seconds | load average before | after |",
        "| ---: | --- | ---: | ---: | ---: | --- | --- |",
    ]
    for number, rows in enumerate(rounds, 1):
        for key, row in rows.items():
            kind, workers = key.split()
            lines.append(
                f"| {number} | {kind} | {workers} | {row['rate']} | {row['seconds']} | "
                f"{row['before']} | {row['after']} |"
            )
    lines.append("")
    for kind, name in (("dask", "Dask"), ("local", "local pool")):
        ratios = [ratio(rows, kind) for rows in rounds]
        each = ", ".join(f"{r:.2f}x" for r in ratios)
        lines.append(
            f"- 2 workers against 1, {name}: {each} (median {statistics.median(ratios):.2f}x)"
        )
    lines.append("")
    out.write_text("\n".join(lines))
    print(out.read_text())


if __name__ == "__main__":
    sys.exit(main())
