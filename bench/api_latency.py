"""API latency with 20 concurrent clients, on SQLite and on PostgreSQL, side by side.

For each database a real `mvo-gcs serve` (uvicorn, 127.0.0.1, its default 2 planning
workers) is started on a fresh store: SQLite in a fresh data directory, or a database of
a throw-away PostgreSQL cluster (`tests/storage/postgres.py`, run with PostgreSQL's own
durable defaults, since SQLite's WAL here syncs every commit too). It is seeded through
the API: SEED_SCENARIOS scenarios (the paper's six cases and copies), a plan of case VI
and of case I, and one case VI flight flown to its landing by 3 mock vehicles (so that
the flight has stored events and the vehicles are registered); the vehicles are then
stopped, so that only the API and its storage share the machine with the clients.

Then CLIENTS closed-loop clients (each its own httpx.AsyncClient and connection, one
process, one event loop), each sending its next request as soon as the last is answered,
for SECONDS after a short warm-up that is not measured, draw requests from MIX: mostly
reads (scenario list and one scenario, flight list, pages of the flight's events,
vehicles with their live state, readiness, which reads the database) and 10 % scenario
writes, every one with the bearer token. Latency is measured from just before the
request is sent to its whole answer read, in the client; the clients, the service and
the database share 2 cores, so it includes waiting for a core.

Usage: PYTHONPATH=. .venv/bin/python bench/api_latency.py [--clients 20] [--seconds 30]
       [--out bench/results/api_latency.md]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import platform
import random
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from bench.service_bench import CpuMeter, api, children, loadavg
from planner.cases import load_case
from planner.experiments.machine import cpu_model
from tests.e2e.flying import Flight, fleet_at_starts
from tests.service_process import ServiceProcess
from tests.storage.postgres import PostgresServer, binaries

SEED_SCENARIOS = 60  # the six cases, then copies under other names
EVENTS_PAGE = 20  # events per page asked for
WARM_UP_S = 3.0
MIX: dict[str, int] = {  # weight of each request, out of 100
    "GET /scenarios": 15,
    "GET /scenarios/{id}": 15,
    "GET /flights": 15,
    "GET /flights/{id}/events": 20,
    "GET /vehicles": 15,
    "GET /health/ready": 10,
    "POST /scenarios": 10,
}


@dataclass
class Seeded:
    """What the clients ask for: the ids made while seeding."""

    scenarios: list[str]
    flight: str
    event_afters: list[int]  # `after` of each page of the flight's events (0: the first)
    events: int
    scenario_body: dict[str, Any]


@dataclass
class Run:
    """One database's measurement."""

    database: str
    latencies: dict[str, list[float]] = field(default_factory=dict)  # ms, per request kind
    statuses: Counter[str] = field(default_factory=Counter)
    errors: list[str] = field(default_factory=list)
    wall_s: float = 0.0
    cores: dict[str, float] = field(default_factory=dict)
    seeded: Seeded | None = None
    load_before: str = ""
    load_after: str = ""
    problems: list[str] = field(default_factory=list)

    def all_ms(self) -> list[float]:
        return [ms for values in self.latencies.values() for ms in values]


# --- the stores -------------------------------------------------------------------------


@contextlib.contextmanager
def postgres_url() -> Iterator[tuple[str, PostgresServer]]:
    """A database of a throw-away cluster with PostgreSQL's durable defaults (fsync,
    synchronous commit), stopped by its process id afterwards."""
    bindir = binaries()
    if bindir is None:
        raise SystemExit("no PostgreSQL binaries (apt-get install postgresql, or PG_BINDIR)")
    server = PostgresServer(bindir, settings=())
    try:
        server.start()
        with server.database() as url:
            yield url, server
    finally:
        server.stop()


def pg_pids(server: PostgresServer | None) -> list[int]:
    """The postmaster and its backends (the service's pooled connections among them)."""
    if server is None or server.process is None:
        return []
    return [server.process.pid, *children(server.process.pid)]


# --- seeding ------------------------------------------------------------------------------


def seed(service: ServiceProcess) -> Seeded:
    """Scenarios, two plans and one flown case VI flight, all through the API."""
    bodies = [load_case(f"case-{k}").model_dump(mode="json") for k in range(1, 7)]
    with service.client() as client:
        ids = []
        for n in range(SEED_SCENARIOS):
            body = {**bodies[n % 6], "name": f"{bodies[n % 6]['name']} #{n}"}
            answer = client.post("/scenarios", json=body)
            answer.raise_for_status()
            ids.append(answer.json()["id"])
        case_1 = client.post(f"/scenarios/{ids[0]}/plans", json={"wait_s": 60})
        assert case_1.status_code == 201, case_1.text
        sim = fleet_at_starts(load_case("case-6"))
        with sim.running():
            flight = Flight.make(client, sim, "case-6")
            flight.fly()
            flight.wait_state("landed", "ended", timeout=300)
        events = client.get(f"/flights/{flight.id}/events", params={"limit": 10_000}).json()
    event_ids = [int(e["id"]) for e in events]
    afters = [0] + [event_ids[k - 1] for k in range(EVENTS_PAGE, len(event_ids), EVENTS_PAGE)]
    return Seeded(ids, flight.id, afters, len(events), bodies[5])


# --- the load -----------------------------------------------------------------------------


def request_for(kind: str, seeded: Seeded, rng: random.Random, n: int) -> tuple[str, str, Any]:
    """(method, path, JSON body) of one request of `kind`."""
    if kind == "GET /scenarios":
        return "GET", "/scenarios", None
    if kind == "GET /scenarios/{id}":
        return "GET", f"/scenarios/{rng.choice(seeded.scenarios)}", None
    if kind == "GET /flights":
        return "GET", "/flights", None
    if kind == "GET /flights/{id}/events":
        after = rng.choice(seeded.event_afters)
        return "GET", f"/flights/{seeded.flight}/events?after={after}&limit={EVENTS_PAGE}", None
    if kind == "GET /vehicles":
        return "GET", "/vehicles", None
    if kind == "GET /health/ready":
        return "GET", "/health/ready", None
    body = {**seeded.scenario_body, "name": f"written under load #{n}"}
    return "POST", "/scenarios", body


EXPECTED = {"POST": 201, "GET": 200}


async def client_loop(
    url: str, seeded: Seeded, run: Run | None, until: float, number: int, seed: int
) -> None:
    """One closed-loop client on its own connection; `run` None: warm-up, not recorded."""
    rng = random.Random(seed * 1000 + number)
    kinds, weights = list(MIX), list(MIX.values())
    sent = 0
    async with api(url, timeout=60, connections=1) as client:
        while time.perf_counter() < until:
            kind = rng.choices(kinds, weights)[0]
            method, path, body = request_for(kind, seeded, rng, number * 1_000_000 + sent)
            sent += 1
            started = time.perf_counter()
            try:
                answer = await client.request(method, path, json=body)
                await answer.aread()
            except httpx.HTTPError as exc:
                if run is not None:
                    run.statuses[f"{kind}: {type(exc).__name__}"] += 1
                    run.errors.append(f"{kind}: {type(exc).__name__}: {exc}"[:200])
                continue
            ms = 1000 * (time.perf_counter() - started)
            if run is None:
                continue
            run.latencies.setdefault(kind, []).append(ms)
            if answer.status_code != EXPECTED[method]:
                run.statuses[f"{kind}: {answer.status_code}"] += 1
                if len(run.errors) < 5:
                    run.errors.append(f"{kind}: {answer.status_code} {answer.text[:200]}")


async def load(
    service: ServiceProcess,
    seeded: Seeded,
    run: Run,
    clients: int,
    seconds: float,
    pg: PostgresServer | None,
    seed: int,
) -> None:
    warm_until = time.perf_counter() + WARM_UP_S
    await asyncio.gather(
        *(client_loop(service.url, seeded, None, warm_until, k, seed) for k in range(clients))
    )
    pids = {
        "service": [service.pid, *children(service.pid)],
        "postgres": pg_pids(pg),
    }
    until = time.perf_counter() + seconds
    with CpuMeter(pids) as meter:
        started = time.perf_counter()
        await asyncio.gather(
            *(client_loop(service.url, seeded, run, until, k, seed + 1) for k in range(clients))
        )
        run.wall_s = time.perf_counter() - started
    run.cores = meter.cores


def measure(
    database: str, tmp: Path, args: argparse.Namespace, pg: tuple[str, PostgresServer] | None
) -> Run:
    run = Run(database, load_before=loadavg())
    env = {"MVO_GCS_DATABASE_URL": pg[0]} if pg else {}
    service = ServiceProcess(tmp / database, extra_env=env, workers=2)
    service.start(timeout=120)
    try:
        run.seeded = seed(service)
        asyncio.run(
            load(service, run.seeded, run, args.clients, args.seconds, pg[1] if pg else None, 1)
        )
    except BaseException:
        print(f"failed; the service's log: {service.log}", file=sys.stderr)
        raise
    finally:
        service.stop()
        run.problems = service.problems()
        run.load_after = loadavg()
    total = len(run.all_ms())
    print(f"{database}: {total} requests, {total / run.wall_s:.0f}/s", flush=True)
    return run


# --- report -------------------------------------------------------------------------------


def pct(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


def cells(values: list[float], wall_s: float) -> str:
    return (
        f"{len(values)} | {len(values) / wall_s:.0f} | {pct(values, 50):.1f} | "
        f"{pct(values, 95):.1f} | {pct(values, 99):.1f} | {max(values, default=0):.1f}"
    )


def table(runs: list[Run]) -> list[str]:
    head = "| request | share | " + " | ".join(
        f"{r.database} n | req/s | p50 ms | p95 ms | p99 ms | max ms" for r in runs
    )
    rule = "| --- | ---: | " + " | ".join("---: | ---: | ---: | ---: | ---: | ---:" for _ in runs)
    rows = [head + " |", rule + " |"]
    every = " | ".join(cells(r.all_ms(), r.wall_s) for r in runs)
    rows.append(f"| **all** | 100 % | {every} |")
    for kind, weight in MIX.items():
        per = " | ".join(cells(r.latencies.get(kind, []), r.wall_s) for r in runs)
        rows.append(f"| `{kind}` | {weight} % | {per} |")
    return rows


def cpu_rows(runs: list[Run]) -> list[str]:
    rows = [
        "| database | service (and its workers) | PostgreSQL | clients (this process) | "
        "other | load average before / after |",
        "| --- | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in runs:
        c = r.cores
        rows.append(
            f"| {r.database} | {c['service']:.2f} | {c['postgres']:.2f} | {c['bench']:.2f} | "
            f"{c['other']:.2f} | {r.load_before} / {r.load_after} |"
        )
    return rows


def pg_version(bindir: Path | None) -> str:
    if bindir is None:
        return "none"
    out = subprocess.run([bindir / "postgres", "--version"], capture_output=True, text=True)
    return out.stdout.strip()


def report(args: argparse.Namespace, runs: list[Run], meta: dict[str, Any]) -> str:
    seeded = runs[0].seeded
    assert seeded is not None
    bad = [f"{r.database}: {dict(r.statuses)}" for r in runs if r.statuses]
    problems = [f"{r.database}: {len(r.problems)}" for r in runs]
    lines = [
        f"# API latency with {args.clients} concurrent clients: SQLite and PostgreSQL",
        "",
        f"- date: {meta['date']}; commit {meta['commit']}",
        f"- machine: {cpu_model()}, `nproc` {os.cpu_count()}, {platform.system()} "
        f"{platform.release()}, Python {platform.python_version()}",
        f"- load average before the run / after it: {meta['load_before']} / {loadavg()}",
        f"- command: `{meta['command']}`",
        f"- wall time of the whole script: {meta['wall_s']:.0f} s",
        "- service: `mvo-gcs serve` (uvicorn) on 127.0.0.1, `MVO_GCS_TOKEN` set, default 2 "
        "planning workers, no taskset; SQLite: a fresh data directory (WAL); PostgreSQL: "
        f"{meta['pg']}, a throw-away cluster on a Unix socket with its default (durable) "
        "settings, `MVO_GCS_DATABASE_URL=postgresql+psycopg://...`",
        f"- seeded through the API, the same for both: {SEED_SCENARIOS} scenarios (the six "
        "cases and copies), plans of case I and case VI, one case VI flight flown to its "
        f"landing by 3 mock vehicles at 20x ({seeded.events} stored events; the vehicles "
        "stopped afterwards, so `/vehicles` shows them with their last state)",
        f"- load: {args.clients} closed-loop clients (one connection each, no pause between "
        f"requests), {WARM_UP_S:g} s warm-up not measured, then {args.seconds:g} s measured; "
        f"events in pages of {EVENTS_PAGE} (`?after=` a page boundary, at random); every "
        "request carries the bearer token; `POST /scenarios` stores case VI under a new name",
        "",
        *table(runs),
        "",
        "req/s: answers in the measured window / its wall time. CPU in cores (1.00 = one "
        "core busy) over the measured window; `other` is the rest of the machine:",
        "",
        *cpu_rows(runs),
        "",
        "Answers other than 200 (GET) / 201 (POST), or failed requests: "
        + ("; ".join(bad) if bad else "none")
        + ". Service log lines with errors or 5xx: "
        + ", ".join(problems)
        + ".",
        "",
        *[f"- `{e}`" for r in runs for e in r.errors],
        "",
    ]
    return "\n".join(lines)


def commit() -> str:
    out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    dirty = subprocess.run(["git", "status", "--porcelain", "--", "gcs"], capture_output=True)
    return out.stdout.strip() + (" (gcs/ with uncommitted changes)" if dirty.stdout else "")


def on_each_database(
    args: argparse.Namespace, prefix: str, measure: Callable[..., Any]
) -> tuple[list[Any], dict[str, Any]]:
    """`measure(name, tmp, args, pg)` on SQLite, then (unless `--no-postgres`) on a
    throw-away PostgreSQL cluster, one after the other; the runs and the run's metadata."""
    meta: dict[str, Any] = {
        "date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "load_before": loadavg(),
        "command": "PYTHONPATH=. .venv/bin/python " + " ".join(sys.argv),
        "commit": commit(),
        "pg": pg_version(binaries()),
    }
    started = time.perf_counter()
    runs = []
    with tempfile.TemporaryDirectory(prefix=prefix) as name:
        tmp = Path(name)
        runs.append(measure("SQLite", tmp, args, None))
        if not args.no_postgres:
            with postgres_url() as pg:
                runs.append(measure("PostgreSQL", tmp, args, pg))
    meta["wall_s"] = time.perf_counter() - started
    return runs, meta


def publish(out: Path, text: str) -> int:
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    print(text)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clients", type=int, default=20)
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--out", type=Path, default=Path("bench/results/api_latency.md"))
    parser.add_argument("--no-postgres", action="store_true", help="SQLite only")
    args = parser.parse_args(argv)
    runs, meta = on_each_database(args, "mvo-api-latency-", measure)
    return publish(args.out, report(args, runs, meta))


if __name__ == "__main__":
    sys.exit(main())
