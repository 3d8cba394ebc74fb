"""The operator's commands and the event loop, measured against a real `mvo-gcs serve`.

1. Abort latency in every state a vehicle may be armed in: from the moment the abort
   request is sent to the moment every mock vehicle's own state (the simulator's truth,
   polled every millisecond) shows LAND. States: uploading (a slow link makes the upload
   last seconds), starting (arming refused "not ready" for ever), flying, paused, and
   interrupted after the service was killed and restarted mid-flight (the fleet held
   first, so that it is still up however long the restart takes).
2. The event loop's stalls while 20 mock vehicles fly and every event is stored: the
   service's own loop-lag probe (a 10 ms timer, `mvo_gcs_event_loop_lag_seconds`), read
   from /metrics before and after the flight.
3. With `--readers N` instead (issue 28, "Readers can starve the operator"): abort
   latency and the loop's lag during a case VI flight, with N concurrent readers of a
   large plan's mission files (`GET /plans/{id}/missions`, `.plan`, `.waypoints`, from a
   separate process) and without, side by side in one run; each repeat's readers ask
   for options not asked before, so that the plan is paced again while they read. The
   section is added to the report (replacing an earlier one of this mode).

Usage: PYTHONPATH=. .venv/bin/python bench/operator_bench.py [--repeats 5] [--out FILE]
       PYTHONPATH=. .venv/bin/python bench/operator_bench.py --readers 40 [--uavs 100]
"""

from __future__ import annotations

import argparse
import asyncio
import concurrent.futures
import contextlib
import multiprocessing as mp
import statistics
import tempfile
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import httpx

from bench.service_bench import homes, line_scenario, loadavg
from planner.cases import load_case
from planner.experiments.machine import describe_machine
from planner.model.scenario import Scenario
from sitl_mock import Faults, Simulator, VehicleConfig
from tests.e2e.flying import Flight, fleet_at_starts, wait_for
from tests.e2e.test_mission_readers import line as line_of_uavs
from tests.service_process import ServiceProcess

RESULTS = Path("bench/results/operator.md")
LAG_BUCKETS = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.25, 1.0)


def abort_latency(flight: Flight, at_land: Callable[[], object] = lambda: None) -> float:
    """Seconds from sending the abort to every vehicle in LAND, by the simulator's truth;
    `at_land` is called at that moment, before the abort's answer is waited for."""
    sim = flight.sim
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        sent = time.perf_counter()
        answer = pool.submit(flight.post, "abort", mode="land")
        while {sim.state(k).mode for k in sim.sysids} != {"LAND"}:
            if time.perf_counter() - sent > 60:
                raise TimeoutError(f"abort did not reach every vehicle: {flight.modes()}")
            time.sleep(0.001)
        reached = time.perf_counter() - sent
        at_land()
        response = answer.result(timeout=60)
    if response.status_code != 200:
        raise RuntimeError(f"abort answered {response.status_code}: {response.text}")
    flight.wait_state("aborted")
    return reached


def in_state(client: httpx.Client, state: str) -> float:
    """One abort in `state`, on fresh vehicles."""
    faults = Faults(latency_s=2.0) if state == "uploading" else None  # 0.1 s each way at 20x
    extra = {"estimate_delay_s": 1e6} if state == "starting" else {}
    case = load_case("case-6")
    with fleet_at_starts(case, faults=faults, **extra).running() as sim:
        flight = Flight.make(client, sim, "case-6")
        if state == "uploading":
            wait_for(lambda: all(_online(client, v) for v in flight.vehicle_ids), 30, "online")
            with concurrent.futures.ThreadPoolExecutor(1) as pool:
                pool.submit(flight.post, "upload")
                flight.wait_state("uploading")
                return abort_latency(flight)
        if state == "starting":
            flight.upload()
            flight.post("start")
            flight.wait_state("starting")
            return abort_latency(flight)
        flight.fly()
        if state == "paused":
            flight.post("pause")
        return abort_latency(flight)


def after_restart(tmp: Path) -> float:
    service = ServiceProcess(tmp / "restart")
    service.start()
    try:
        with fleet_at_starts(load_case("case-6"), speedup=10.0).running() as sim:
            with service.client() as client:
                flight = Flight.make(client, sim, "case-6")
                flight.fly()
                flight.post("pause")  # still up however long the restart takes
            service.kill()
            service.start()
            with service.client() as client:
                flight.client = client
                wait_for(lambda: flight.state() == "interrupted", 30, "interrupted")
                wait_for(lambda: all(_online(client, v) for v in flight.vehicle_ids), 30, "up")
                return abort_latency(flight)
    finally:
        service.stop()


def loop_lag(client: httpx.Client) -> dict[str, float]:
    """p50, p99 (bucket upper bounds) and share under 20 ms during a 20-vehicle flight."""
    scenario = line_scenario()
    sim = Simulator(_homes(scenario), speedup=10.0, seed=1)
    with sim.running():
        sid = client.post("/scenarios", json=scenario.model_dump(mode="json")).json()["id"]
        plan = client.post(f"/scenarios/{sid}/plans", json={"wait_s": 60}).json()
        ids = [
            client.post("/vehicles", json={"connection": sim.connection_string(k)}).json()["id"]
            for k in sim.sysids
        ]
        bindings = {u.id: v for u, v in zip(scenario.uavs, ids, strict=True)}
        fid = client.post("/flights", json={"plan_id": plan["id"], "bindings": bindings}).json()
        flight = Flight(client, sim, scenario, sid, plan, ids, fid["id"])
        flight.fly()
        before = _lag_counts(client)
        flight.wait_state("landed", "ended", "interrupted", timeout=600)
        after = _lag_counts(client)
        events = len(client.get(f"/flights/{flight.id}/events?limit=10000").json())
    counts = {b: after[b] - before[b] for b in after}
    total = counts[float("inf")]
    quantile = {q: next(b for b in sorted(counts) if counts[b] >= q * total) for q in (0.5, 0.99)}
    return {
        "samples": total,
        "p50": quantile[0.5],
        "p99": quantile[0.99],
        "under_20ms": counts[0.02] / total,
        "events": events,
    }


def _lag_counts(client: httpx.Client) -> dict[float, float]:
    counts = {}
    for line in client.get("/metrics").text.splitlines():
        if line.startswith("mvo_gcs_event_loop_lag_seconds_bucket"):
            bound = line.split('le="')[1].split('"')[0]
            counts[float("inf") if bound == "+Inf" else float(bound)] = float(line.split()[-1])
    return counts


def _homes(scenario: Scenario) -> list[VehicleConfig]:
    return [VehicleConfig(sysid=k, home=h) for k, h in enumerate(homes(scenario), start=1)]


def _online(client: httpx.Client, vehicle: str) -> bool:
    return bool(client.get(f"/vehicles/{vehicle}").json()["live"]["online"])


def repeat(times: int, measure: Callable[[], float]) -> list[float]:
    return [measure() for _ in range(times)]


# --- 3: readers of a large plan's mission files during a flight ----------------------------

READERS_HEADING = "## Abort and the event loop while readers fetch a large plan's missions"
PER_ADDRESS = 20  # readers per loopback address
READER_SPEEDUP = 5.0  # case VI flies for tens of wall seconds: still flying when aborted
PHASES = {
    "none": "no readers",
    "computing": "readers, while their options are paced",
    "cached": "readers, answered from the cache",
}


def read_missions(
    url: str,
    paths: list[str],
    readers: int,
    ready: Any,
    go: Any,
    stop: Any,
    sent: Any,
    answers: Any,
) -> None:
    """In a process of its own (its threads would slow the simulator's in this one):
    `readers` concurrent clients, each fetching its path again and again from `go` until
    `stop`; `sent` counts the readers that have sent a first request, `answers` the
    answers."""

    async def reader(k: int, client: httpx.AsyncClient) -> None:
        path = paths[k % len(paths)]
        first = True
        while not stop.is_set():
            if first:
                with sent.get_lock():
                    sent.value += 1
                first = False
            response = await client.get(path)
            if response.status_code != 200:
                raise RuntimeError(f"{path}: {response.status_code} {response.text[:200]}")
            with answers.get_lock():
                answers.value += 1

    async def run() -> None:
        # the service holds at most 32 connections per address: the readers come from
        # several loopback addresses, as many clients would
        groups = [range(k, min(k + PER_ADDRESS, readers)) for k in range(0, readers, PER_ADDRESS)]
        async with contextlib.AsyncExitStack() as stack:
            tasks = []
            for n, group in enumerate(groups):
                limits = httpx.Limits(max_connections=len(group))
                transport = httpx.AsyncHTTPTransport(
                    limits=limits, local_address=f"127.0.0.{n + 2}"
                )
                client = await stack.enter_async_context(
                    httpx.AsyncClient(base_url=url, timeout=600, transport=transport)
                )
                tasks += [reader(k, client) for k in group]
            await asyncio.gather(*tasks)

    ready.set()
    go.wait()
    asyncio.run(run())


class HealthProbe:
    """`GET /health/live` again and again in a thread: how long each answer took."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.seconds: list[float] = []
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._probe, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._done.set()
        if self._thread.is_alive():
            self._thread.join(timeout=600)

    def _probe(self) -> None:
        with httpx.Client(base_url=self.url, timeout=600) as client:
            while not self._done.is_set() or not self.seconds:
                asked = time.perf_counter()
                client.get("/health/live").raise_for_status()
                self.seconds.append(time.perf_counter() - asked)


def lag_snapshot(client: httpx.Client) -> dict[str, float]:
    """The loop-lag histogram's buckets, sum and count."""
    found = {}
    for line in client.get("/metrics").text.splitlines():
        if line.startswith("mvo_gcs_event_loop_lag_seconds_"):
            name, value = line.rsplit(" ", 1)
            found[name] = float(value)
    return found


def metric(client: httpx.Client, name: str) -> float | None:
    for line in client.get("/metrics").text.splitlines():
        if line.startswith(name + " "):
            return float(line.split()[-1])
    return None


def with_readers(
    client: httpx.Client, url: str, plan_id: str, readers: int, altitude_m: float, phase: str
) -> dict[str, float]:
    """One abort of a fresh case VI flight, with the lag the loop took from just before
    the readers started to the abort's answer. `phase`: "none" (nobody reading),
    "computing" (sent while the readers' options are being paced: options not asked
    before) or "cached" (sent once every reader has had an answer from the cache)."""
    case = load_case("case-6")
    with fleet_at_starts(case, speedup=READER_SPEEDUP).running() as sim:
        flight = Flight.make(client, sim, "case-6")
        flight.fly()
        query = f"?altitude_m={altitude_m:g}"
        paths = [
            f"/plans/{plan_id}/missions{query}",
            f"/plans/{plan_id}/missions/uav1.plan{query}",
            f"/plans/{plan_id}/missions/uav2.waypoints{query}",
        ]
        context = mp.get_context("spawn")
        ready, go, stop = context.Event(), context.Event(), context.Event()
        sent, answers = context.Value("i", 0), context.Value("i", 0)
        process = context.Process(
            target=read_missions, args=(url, paths, readers, ready, go, stop, sent, answers)
        )
        if phase != "none":
            process.start()  # its imports take seconds of CPU: before the measurement
            wait_for(lambda: ready.is_set() or process.exitcode is not None, 600, "readers")
        health = HealthProbe(url)
        snapshots: list[dict[str, float]] = []  # the lag when every vehicle is in LAND
        windows: list[float] = []  # and the seconds since the readers started
        served: list[int] = []  # and the answers they have had
        before = lag_snapshot(client)
        began = time.perf_counter()
        health.start()
        if phase != "none":
            go.set()

            def under_way() -> bool:
                if process.exitcode is not None:
                    return True  # failed: said below
                if phase == "cached":
                    return bool(answers.value >= readers)
                running = metric(client, "mvo_gcs_mission_computations_running")
                return bool(sent.value >= readers and (running is None or running >= 1))

            wait_for(under_way, 600, f"{readers} readers ({phase})", every=0.01)
        try:
            state = flight.state()
            with httpx.Client(base_url=url, timeout=600) as metrics:

                def at_land() -> None:
                    snapshots.append(lag_snapshot(metrics))
                    windows.append(time.perf_counter() - began)
                    served.append(answers.value)
                    health.stop()

                reached = abort_latency(flight, at_land)
        finally:
            health.stop()
            stop.set()
            go.set()
            if phase != "none":
                process.join(timeout=600)
        after, window = snapshots[0], windows[0]
        if phase != "none" and process.exitcode != 0:
            raise RuntimeError(f"the readers failed (exit {process.exitcode})")
    lag = {k: after[k] - before.get(k, 0.0) for k in after}
    wakeups = lag["mvo_gcs_event_loop_lag_seconds_count"]
    buckets = sorted(
        (float(k.split('le="')[1].split('"')[0]), v) for k, v in lag.items() if 'le="' in k
    )
    p99 = next(bound for bound, count in buckets if count >= 0.99 * wakeups)
    return {
        "flying": 1.0 if state == "flying" else 0.0,
        "land_s": reached,
        "health_max_s": max(health.seconds),
        "health_median_s": statistics.median(health.seconds),
        "window_s": window,
        "lag_s": lag["mvo_gcs_event_loop_lag_seconds_sum"],
        "p99_s": p99,
        "answers": float(served[0]),
    }


def readers_main(args: argparse.Namespace) -> None:
    load_before = loadavg()
    scenario = line_of_uavs(args.uavs)
    runs: dict[str, list[dict[str, float]]] = {phase: [] for phase in PHASES}
    with tempfile.TemporaryDirectory() as tmp:
        service = ServiceProcess(Path(tmp) / "data")
        service.start()
        try:
            with service.client() as client:
                body = scenario.model_dump(mode="json")
                sid = client.post("/scenarios", json=body).json()["id"]
                planned = client.post(f"/scenarios/{sid}/plans", json={"wait_s": 60})
                if planned.status_code != 201 or not planned.json()["plan"]["feasible"]:
                    raise RuntimeError(f"the {args.uavs}-UAV plan: {planned.text[:300]}")
                plan_id = planned.json()["id"]
                paced = time.perf_counter()
                first = client.get(f"/plans/{plan_id}/missions", timeout=600)
                pacing_s = time.perf_counter() - paced
                if first.status_code != 200:
                    raise RuntimeError(f"missions: {first.status_code} {first.text[:300]}")
                for k in range(args.repeats):  # in turn, so that all see the same machine
                    for phase in PHASES:
                        altitude = 21.0 + k  # options not asked before: paced again
                        run = with_readers(
                            client, service.url, plan_id, args.readers, altitude, phase
                        )
                        print(phase, {n: round(v, 3) for n, v in run.items()}, flush=True)
                        runs[phase].append(run)
        finally:
            service.stop()
    section = readers_report(args, runs, pacing_s, load_before, loadavg())
    text = args.out.read_text() if args.out.exists() else ""
    if READERS_HEADING in text:
        text = text[: text.index(READERS_HEADING)].rstrip("\n") + "\n"
    args.out.write_text(text.rstrip("\n") + "\n\n" + section)
    print(f"added to {args.out}")


def readers_report(
    args: argparse.Namespace,
    runs: dict[str, list[dict[str, float]]],
    pacing_s: float,
    load_before: str,
    load_after: str,
) -> str:
    def row(phase: str) -> str:
        xs = runs[phase]

        def stat(key: str, scale: float = 1000.0) -> str:
            values = [x[key] * scale for x in xs]
            return f"{statistics.median(values):.0f} / {max(values):.0f}"

        per_s = [x["lag_s"] / x["window_s"] for x in xs]
        flying = sum(int(x["flying"]) for x in xs)
        answers = [x["answers"] for x in xs]
        return (
            f"| {PHASES[phase]} | {stat('land_s')} | {stat('health_median_s')} | "
            f"{stat('health_max_s')} | "
            f"{statistics.median(per_s):.3f} / {max(per_s):.3f} | {stat('p99_s')} | "
            f"{statistics.median(answers):.0f} | {flying}/{len(xs)} |"
        )

    return "\n".join(
        [
            READERS_HEADING,
            "",
            f"Run {datetime.now(UTC):%Y-%m-%d %H:%M} UTC on {describe_machine()}; load "
            f"average {load_before} before, {load_after} after.",
            "",
            "```",
            "PYTHONPATH=. .venv/bin/python bench/operator_bench.py "
            f"--readers {args.readers} --uavs {args.uavs} --repeats {args.repeats}",
            "```",
            "",
            f"A case VI flight (3 mock vehicles at {READER_SPEEDUP:g}x) aborted with LAND: "
            f"without readers, and while {args.readers} clients (a process of their own) "
            f"fetch the missions of a {args.uavs}-UAV plan over and over (`/missions`, "
            "`uav1.plan`, `uav2.waypoints`); in turn, in one run, a fresh flight each. "
            "Each repeat's readers ask for options not asked before: the abort is sent "
            "either while the plan is paced for them (the service's "
            "`mvo_gcs_mission_computations_running` is 1; the first pacing of this plan "
            f"took {pacing_s:.1f} s), or once every reader has had an answer from the "
            "cache. Abort: from the request to every vehicle in LAND (the simulator's "
            "truth). From just before the readers start to that moment: `/health/live` "
            "asked again and again (its answer time, median and the worst), and the "
            "service's own loop-lag probe (seconds late per second, and the p99 bucket "
            "bound of its wake-ups).",
            "",
            "| | abort to LAND, median / max ms | /health/live median, median / max ms "
            "| /health/live worst, median / max ms | loop lag s per s, median / max "
            "| p99 wake-up lag, median / max ms "
            "| answers to readers by then (median) | flying when aborted |",
            "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
            *(row(phase) for phase in PHASES),
            "",
        ]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", type=Path, default=RESULTS)
    parser.add_argument(
        "--readers", type=int, default=0, help="measure only abort and lag with N readers"
    )
    parser.add_argument("--uavs", type=int, default=100, help="the readers' plan's fleet")
    args = parser.parse_args()
    if args.readers:
        readers_main(args)
        return
    load_before = loadavg()
    with tempfile.TemporaryDirectory() as tmp:
        service = ServiceProcess(Path(tmp) / "data")
        service.start()
        try:
            with service.client() as client:
                latencies = {
                    state: repeat(args.repeats, lambda s=state: in_state(client, s))
                    for state in ("uploading", "starting", "flying", "paused")
                }
                lag = loop_lag(client)
        finally:
            service.stop()
        latencies["interrupted (after a restart)"] = repeat(
            args.repeats, lambda: after_restart(Path(tmp))
        )
    args.out.write_text(report(args, latencies, lag, load_before, loadavg()))
    print(f"wrote {args.out}")


def report(
    args: argparse.Namespace,
    latencies: dict[str, list[float]],
    lag: dict[str, float],
    load_before: str,
    load_after: str,
) -> str:
    rows = [
        f"| {state} | {statistics.median(xs) * 1000:.0f} | {max(xs) * 1000:.0f} | {len(xs)} |"
        for state, xs in latencies.items()
    ]
    return "\n".join(
        [
            "# The operator's commands and the event loop",
            "",
            f"Run {datetime.now(UTC):%Y-%m-%d %H:%M} UTC on {describe_machine()}; load "
            f"average {load_before} before, {load_after} after.",
            "",
            "```",
            f"PYTHONPATH=. .venv/bin/python bench/operator_bench.py --repeats {args.repeats}",
            "```",
            "",
            "## Abort: from the request to every vehicle in LAND (case VI, 3 mock vehicles)",
            "",
            "Measured on the vehicles' side (the simulator's own state, polled every "
            "millisecond); the target is 1 s. Uploading runs over a link with 0.1 s of delay "
            "each way (so that the upload lasts seconds), which the abort's command crosses "
            "too: there the figure includes that 0.1 s.",
            "",
            "| state | median ms | max ms | runs |",
            "| --- | ---: | ---: | ---: |",
            *rows,
            "",
            "## Event-loop stalls while 20 vehicles fly",
            "",
            f"A 20-UAV flight at 10x, every fleet event stored ({lag['events']:.0f} events); "
            f"{lag['samples']:.0f} wake-ups of the service's 10 ms probe timer. The probe's "
            "histogram gives bucket bounds: p50 <= "
            f"{lag['p50'] * 1000:g} ms, p99 <= {lag['p99'] * 1000:g} ms; "
            f"{lag['under_20ms'] * 100:.2f} % of wake-ups under 20 ms late (target: p99 "
            "<= 20 ms).",
            "",
        ]
    )


if __name__ == "__main__":
    main()
