"""Event-store lag while 20 mock vehicles fly, on SQLite and on PostgreSQL, side by side.

For each database a real `mvo-gcs serve` (uvicorn, 127.0.0.1) is started on a fresh
store (SQLite in a fresh data directory; a database of a throw-away PostgreSQL cluster
with its durable defaults, `tests/storage/postgres.py`), and `bench/service_bench.py`'s
20-UAV line (30 m apart, 150 m north each) is planned, bound to 20 mock vehicles (a
child process, at `--speedup`), uploaded, started and flown to its landing.

The lag is measured twice:

1. inside the service, for every event: `mvo_gcs_event_store_lag_seconds`, from the
   tick that recorded the event to the commit of the transaction that stored it (the
   event writer's histogram: quantiles interpolated within its buckets, as Prometheus's
   `histogram_quantile` does; the mean from its sum);
2. from outside, as a client sees it: `GET /flights/{id}/events?after=<last id>` every
   `--poll` seconds from the moment the flight flies; for each event created after the
   polling began, its `created_at` against the end of the first answer that held it (an
   upper bound: includes up to one polling period and the request) and against the
   start of the answer before (a lower bound).

Whether an event was lost or spilled: the stored events against the writer's counts
(`mvo_gcs_events_written_total`, `..._discarded_total`, `..._pending`), its failed
writes, and the events it ever appended to its spill file
(`mvo_gcs_events_spill_appends_total`); the backlog (`mvo_gcs_events_pending`,
`..._oldest_pending_seconds`) is sampled every 0.25 s during the flight.

Usage: PYTHONPATH=. .venv/bin/python bench/event_lag.py [--speedup 2] [--poll 0.1]
       [--out bench/results/event_lag.md]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import platform
import sys
import time
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from bench.api_latency import on_each_database, pg_pids, publish
from bench.service_bench import (
    FLEET,
    CpuMeter,
    api,
    fly,
    line_scenario,
    loadavg,
    until_state,
    vehicles,
)
from planner.experiments.machine import cpu_model
from tests.service_process import ServiceProcess
from tests.storage.postgres import PostgresServer

LAG = "mvo_gcs_event_store_lag_seconds"
SAMPLE_S = 0.25  # the backlog's sampling period
FLUSH_TIMEOUT_S = 30.0


@dataclass
class Seen:
    """One event as the outside poller first saw it (wall-clock seconds since the epoch)."""

    created: float
    before: float  # the previous answer was asked for then: not stored yet, or not by then
    seen: float  # the first answer that held it had been read by then


@dataclass
class Run:
    database: str
    flight: dict[str, Any] = field(default_factory=dict)
    seen: list[Seen] = field(default_factory=list)
    polls: int = 0
    poll_started: float = 0.0
    stored: int = 0  # events of the flight stored at the end
    metrics: dict[str, float] = field(default_factory=dict)  # at the end
    buckets: list[tuple[float, float]] = field(default_factory=list)  # (le, cumulative)
    most_pending: float = 0.0
    oldest_pending_s: float = 0.0
    end_state: str = ""
    fly_s: float = 0.0
    cores: dict[str, float] = field(default_factory=dict)
    load_before: str = ""
    load_after: str = ""
    problems: list[str] = field(default_factory=list)


# --- /metrics -------------------------------------------------------------------------------


def parse_metrics(text: str) -> tuple[dict[str, float], list[tuple[float, float]]]:
    """Unlabelled samples by name, and the lag histogram's cumulative buckets."""
    values: dict[str, float] = {}
    buckets = []
    for line in text.splitlines():
        if line.startswith("#") or not line.strip():
            continue
        name, value = line.rsplit(" ", 1)
        if name.startswith(f"{LAG}_bucket"):
            bound = name.split('le="')[1].split('"')[0]
            buckets.append((float("inf") if bound == "+Inf" else float(bound), float(value)))
        elif "{" not in name:
            values[name] = float(value)
    return values, sorted(buckets)


def bucket_quantile(buckets: list[tuple[float, float]], q: float) -> float:
    """Prometheus's `histogram_quantile`: linear within the bucket the rank falls in."""
    total = buckets[-1][1]
    if not total:
        return float("nan")
    rank = q * total
    lower, below = 0.0, 0.0
    for bound, count in buckets:
        if count >= rank:
            if bound == float("inf"):
                return lower
            return lower + (bound - lower) * (rank - below) / max(count - below, 1e-12)
        lower, below = bound, count
    return lower


def highest_bucket(buckets: list[tuple[float, float]]) -> float:
    """The upper bound of the highest bucket holding an event: the max is at most this."""
    previous = 0.0
    top = 0.0
    for bound, count in buckets:
        if count > previous:
            top = bound
        previous = count
    return top


async def metrics(client: httpx.AsyncClient) -> tuple[dict[str, float], list[tuple[float, float]]]:
    answer = await client.get("/metrics")
    answer.raise_for_status()
    return parse_metrics(answer.text)


# --- the flight -----------------------------------------------------------------------------


async def events(client: httpx.AsyncClient, fid: str, **params: int) -> list[dict[str, Any]]:
    answer = await client.get(f"/flights/{fid}/events", params=params)
    answer.raise_for_status()
    page: list[dict[str, Any]] = answer.json()
    return page


async def poll_events(
    client: httpx.AsyncClient, fid: str, run: Run, stop: asyncio.Event, every: float
) -> None:
    """Every new stored event, as a client following the flight would find it."""
    after, before = 0, time.time()
    run.poll_started = before
    while True:
        asked = time.time()
        page = await events(client, fid, after=after)
        seen = time.time()
        run.polls += 1
        for event in page:
            created = datetime.fromisoformat(event["created_at"]).timestamp()
            if created >= run.poll_started:
                run.seen.append(Seen(created, before, seen))
            after = max(after, int(event["id"]))
        before = asked
        if stop.is_set() and not page:
            return
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(stop.wait(), every)


async def sample_backlog(client: httpx.AsyncClient, run: Run, stop: asyncio.Event) -> None:
    while not stop.is_set():
        values, _ = await metrics(client)
        run.most_pending = max(run.most_pending, values.get("mvo_gcs_events_pending", 0.0))
        oldest = values.get("mvo_gcs_events_oldest_pending_seconds", 0.0)
        run.oldest_pending_s = max(run.oldest_pending_s, oldest)
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(stop.wait(), SAMPLE_S)


async def flush(client: httpx.AsyncClient) -> None:
    """Until the writer has nothing left to store."""
    deadline = time.monotonic() + FLUSH_TIMEOUT_S
    while (await metrics(client))[0].get("mvo_gcs_events_pending", 0.0):
        if time.monotonic() > deadline:
            raise TimeoutError("events still pending")
        await asyncio.sleep(0.1)


async def fly_and_watch(
    service: ServiceProcess, run: Run, args: argparse.Namespace, pg: PostgresServer | None
) -> None:
    scenario = line_scenario()
    with vehicles(scenario, args.speedup) as (links, sim_pid):
        run.flight = await fly(service, scenario, links)  # back once the flight flies
        fid = str(run.flight["id"])
        pids = {"service": [service.pid], "vehicles": [sim_pid], "postgres": pg_pids(pg)}
        async with api(service.url) as client:
            stop = asyncio.Event()
            watchers = [
                asyncio.ensure_future(poll_events(client, fid, run, stop, args.poll)),
                asyncio.ensure_future(sample_backlog(client, run, stop)),
            ]
            with CpuMeter(pids) as meter:
                started = time.perf_counter()
                run.end_state = await until_state(client, fid, "landed", "ended")
                run.fly_s = time.perf_counter() - started
            await flush(client)
            stop.set()
            await asyncio.gather(*watchers)
            run.cores = meter.cores
            run.metrics, run.buckets = await metrics(client)
            run.stored = len(await events(client, fid, limit=10_000))


def measure(
    database: str, tmp: Path, args: argparse.Namespace, pg: tuple[str, PostgresServer] | None
) -> Run:
    run = Run(database, load_before=loadavg())
    env = {"MVO_GCS_DATABASE_URL": pg[0]} if pg else {}
    service = ServiceProcess(tmp / database, extra_env=env, workers=2)
    service.start(timeout=120)
    try:
        asyncio.run(fly_and_watch(service, run, args, pg[1] if pg else None))
    except BaseException:
        print(f"failed; the service's log: {service.log}", file=sys.stderr)
        raise
    finally:
        service.stop()
        run.problems = service.problems()
        run.load_after = loadavg()
    print(f"{database}: {run.stored} events, {len(run.seen)} seen while polling", flush=True)
    return run


# --- report ---------------------------------------------------------------------------------


def ms(values: list[float], q: float) -> str:
    return f"{1000 * float(np.percentile(values, q)):.1f}" if values else "n/a"


def lag_rows(runs: list[Run]) -> list[str]:
    rows = [
        "| database | events | inside: median ms | p95 ms | max ms (bucket bound) | mean ms | "
        "outside: events | median ms | p95 ms | max ms | lower bound median / p95 / max ms |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in runs:
        m, b = r.metrics, r.buckets
        count = m.get(f"{LAG}_count", 0.0)
        mean = 1000 * m.get(f"{LAG}_sum", 0.0) / count if count else float("nan")
        upper = [s.seen - s.created for s in r.seen]
        lower = [max(s.before - s.created, 0.0) for s in r.seen]
        rows.append(
            f"| {r.database} | {count:.0f} | {1000 * bucket_quantile(b, 0.5):.1f} | "
            f"{1000 * bucket_quantile(b, 0.95):.1f} | <= {1000 * highest_bucket(b):g} | "
            f"{mean:.1f} | {len(upper)} | {ms(upper, 50)} | {ms(upper, 95)} | {ms(upper, 100)} "
            f"| {ms(lower, 50)} / {ms(lower, 95)} / {ms(lower, 100)} |"
        )
    return rows


def loss_rows(runs: list[Run]) -> list[str]:
    rows = [
        "| database | stored (GET events) | written | discarded | pending at the end | "
        "failed writes | spilled (ever) | most pending seen | oldest pending, most seen |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in runs:
        m = r.metrics
        rows.append(
            f"| {r.database} | {r.stored} | {m.get('mvo_gcs_events_written_total', 0):.0f} | "
            f"{m.get('mvo_gcs_events_discarded_total', 0):.0f} | "
            f"{m.get('mvo_gcs_events_pending', 0):.0f} | "
            f"{m.get('mvo_gcs_event_store_failures_total', 0):.0f} | "
            f"{m.get('mvo_gcs_events_spill_appends_total', 0):.0f} | {r.most_pending:.0f} | "
            f"{1000 * r.oldest_pending_s:.0f} ms |"
        )
    return rows


def cpu_rows(runs: list[Run]) -> list[str]:
    rows = [
        "| database | flight (flying to landed) | service | vehicles | PostgreSQL | "
        "bench (pollers) | other | load average before / after |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in runs:
        c = r.cores
        rows.append(
            f"| {r.database} | {r.fly_s:.1f} s, {r.end_state} | {c['service']:.2f} | "
            f"{c['vehicles']:.2f} | {c['postgres']:.2f} | {c['bench']:.2f} | {c['other']:.2f} "
            f"| {r.load_before} / {r.load_after} |"
        )
    return rows


def verdict(r: Run) -> str:
    m = r.metrics
    written = m.get("mvo_gcs_events_written_total", 0.0)
    lost = (
        r.stored != written
        or m.get("mvo_gcs_events_discarded_total", 0.0)
        or m.get("mvo_gcs_events_pending", 0.0)
    )
    spilled = m.get("mvo_gcs_events_spill_appends_total", 0.0)
    return (
        f"- {r.database}: "
        + (
            "an event is missing"
            if lost
            else "no event dropped (stored = written, none discarded, none pending)"
        )
        + ("; " + f"{spilled:.0f} spilled" if spilled else "; none spilled")
        + f"; upload {r.flight.get('upload_s', 0):.1f} s, start {r.flight.get('start_s', 0):.1f} s"
        + f"; {r.polls} polls; service log lines with errors or 5xx: {len(r.problems)}"
        + (f" (first: `{r.problems[0][:160]}`)" if r.problems else "")
        + "."
    )


def report(args: argparse.Namespace, runs: list[Run], meta: dict[str, Any]) -> str:
    lines = [
        f"# Event-store lag while {FLEET} mock vehicles fly: SQLite and PostgreSQL",
        "",
        f"- date: {meta['date']}; commit {meta['commit']}",
        f"- machine: {cpu_model()}, `nproc` {os.cpu_count()}, {platform.system()} "
        f"{platform.release()}, Python {platform.python_version()}",
        f"- load average before the run / after it: {meta['load_before']} / {loadavg()}",
        f"- command: `{meta['command']}`",
        f"- wall time of the whole script: {meta['wall_s']:.0f} s",
        "- service: `mvo-gcs serve` (uvicorn) on 127.0.0.1, `MVO_GCS_TOKEN` set, default "
        "settings; SQLite: a fresh data directory (WAL); PostgreSQL: "
        f"{meta['pg']}, a throw-away cluster on a Unix socket, default (durable) settings",
        f"- flight: {FLEET} UAVs on a line 30 m apart, each 150 m north, 5 m/s, mock vehicles "
        f"(ArduCopter flavour) in a child process at {args.speedup:g}x; the outside poller "
        f"asks every {args.poll:g} s from the moment the flight flies",
        "",
        "Lag from an event's recording to its being stored. Inside: every event of the run "
        "(upload, start and flight), from the service's histogram (median and p95 "
        "interpolated within its buckets of 1, 2, 5, 7.5, 10, 15, 20, 30, 50, 75, 100 ms "
        "...; max: the bound of the highest bucket used). Outside: the events created after "
        "the poller began, `created_at` to the end of the first answer holding it; the lower "
        "bound, to the start of the answer before it:",
        "",
        *lag_rows(runs),
        "",
        "Dropped or spilled:",
        "",
        *loss_rows(runs),
        "",
        *[verdict(r) for r in runs],
        "",
        "CPU in cores (1.00 = one core busy) while the fleet flew; `other` is the rest of "
        "the machine:",
        "",
        *cpu_rows(runs),
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speedup", type=float, default=2.0)
    parser.add_argument("--poll", type=float, default=0.1, help="seconds between GETs")
    parser.add_argument("--out", type=Path, default=Path("bench/results/event_lag.md"))
    parser.add_argument("--no-postgres", action="store_true", help="SQLite only")
    args = parser.parse_args(argv)
    runs, meta = on_each_database(args, "mvo-event-lag-", measure)
    return publish(args.out, report(args, runs, meta))


if __name__ == "__main__":
    sys.exit(main())
