"""The ground station's speed on loopback against the simulated vehicles.

1. one 100-item upload (with and without the read-back verification): median ms;
2. 20 vehicles uploaded concurrently, verified: total seconds;
3. the client's CPU while it follows 20 vehicles' telemetry (the vehicles run in a
   child process, so only the client is measured).

Usage: PYTHONPATH=. .venv/bin/python bench/gcs_bench.py [--out bench/results/gcs.md] [--follow-s 20]
"""

from __future__ import annotations

import argparse
import asyncio
import multiprocessing as mp
import statistics
import sys
import time
from pathlib import Path

from gcs.mavlink import client
from gcs.mavlink.link import LinkSettings
from gcs.mavlink.mission_item import Autopilot, Command, Frame, Mission, MissionItem
from gcs.mavlink.mission_protocol import MissionClient
from planner.experiments.machine import describe_machine
from sitl_mock import Simulator, VehicleConfig

CMAC = (-35.363262, 149.165237, 584.0)
UPLOAD_RUNS = 30
FLEET_SIZE = 20


def mission(items: int) -> Mission:
    lat, lon = round(CMAC[0] * 1e7), round(CMAC[1] * 1e7)
    home = MissionItem(Command.NAV_WAYPOINT, Frame.GLOBAL, x=lat, y=lon, z=CMAC[2])
    takeoff = MissionItem(Command.NAV_TAKEOFF, x=lat, y=lon, z=10.0)
    waypoints = [
        MissionItem(Command.NAV_WAYPOINT, x=lat + 50 * k, y=lon + 30 * k, z=10.0)
        for k in range(items - 2)
    ]
    return Mission((home, takeoff, *waypoints), Autopilot.ARDUPILOT, CMAC)


def configs(n: int) -> list[VehicleConfig]:
    return [VehicleConfig(sysid=k, home=CMAC, mission_capacity=1000) for k in range(1, n + 1)]


async def single_uploads(url: str) -> tuple[float, float]:
    link = await client.connect(url)
    missions, payload = MissionClient(link), mission(100)
    try:
        bare, verified = [], []
        for _ in range(UPLOAD_RUNS):
            bare.append((await missions.upload(payload, verify=False)).seconds)
            verified.append((await missions.upload(payload)).seconds)
    finally:
        await link.close()
    return statistics.median(bare) * 1000, statistics.median(verified) * 1000


async def fleet_upload(urls: list[str]) -> float:
    links = await asyncio.gather(*(client.connect(url) for url in urls))
    try:
        payload = mission(100)
        started = time.perf_counter()
        results = await asyncio.gather(*(MissionClient(link).upload(payload) for link in links))
        assert all(r.verified for r in results)
        return time.perf_counter() - started
    finally:
        await asyncio.gather(*(link.close() for link in links))


async def follow(urls: list[str], seconds: float) -> tuple[float, int]:
    settings = LinkSettings(connect_timeout_s=10.0)
    links = await asyncio.gather(*(client.connect(url, settings=settings) for url in urls))
    received = 0

    def count(msg: object) -> None:
        nonlocal received
        received += 1

    for link in links:
        link.on_message(count)
    try:
        cpu, wall = time.process_time(), time.perf_counter()
        await asyncio.sleep(seconds)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    finally:
        await asyncio.gather(*(link.close() for link in links))
    return 100 * cpu / wall, received


def serve_vehicles(n: int, speedup: float, ports: mp.Queue, stop: mp.Event) -> None:
    sim = Simulator(configs(n), speedup=speedup)
    with sim.running():
        ports.put([sim.connection_string(k) for k in range(1, n + 1)])
        stop.wait()


def in_child(n: int, speedup: float) -> tuple[mp.Process, mp.Event, list[str]]:
    ports: mp.Queue = mp.Queue()
    stop = mp.Event()
    child = mp.Process(target=serve_vehicles, args=(n, speedup, ports, stop), daemon=True)
    child.start()
    return child, stop, ports.get(timeout=30)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench/results/gcs.md"))
    parser.add_argument("--follow-s", type=float, default=20.0)
    args = parser.parse_args(argv)

    child, stop, urls = in_child(FLEET_SIZE, speedup=1.0)
    try:
        bare_ms, verified_ms = asyncio.run(single_uploads(urls[0]))
        fleet_s = asyncio.run(fleet_upload(urls))
        cpu_pct, messages = asyncio.run(follow(urls, args.follow_s))
    finally:
        stop.set()
        child.join(10)
    rate = messages / args.follow_s
    lines = [
        "# Ground station benchmark (loopback, simulated vehicles in a separate process)",
        "",
        f"Machine: {describe_machine()}",
        "",
        f"Command: `PYTHONPATH=. .venv/bin/python {' '.join(sys.argv)}`",
        "",
        "| measure | result | target |",
        "| --- | --- | --- |",
        f"| 100-item upload, median of {UPLOAD_RUNS} | {bare_ms:.1f} ms | <= 100 ms |",
        f"| 100-item upload + read-back verification, median | {verified_ms:.1f} ms | |",
        f"| {FLEET_SIZE} vehicles x 100 items uploaded and verified concurrently | "
        f"{fleet_s * 1000:.0f} ms | <= 1 s |",
        f"| client CPU following {FLEET_SIZE} vehicles' telemetry ({args.follow_s:.0f} s, "
        f"{rate:.0f} msg/s) | {cpu_pct:.1f} % of one core | |",
        "",
    ]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
