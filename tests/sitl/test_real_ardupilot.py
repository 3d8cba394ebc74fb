"""The product flown on real ArduCopter SITL, unchanged: `mvo-gcs fly` and the service.

Run with `ARDUPILOT_SITL=/path/to/arducopter` (skipped otherwise: CI cannot reach
ArduPilot's sources). Every test starts fresh instances at the UAVs' start cells, flies
the plan end to end and measures the separation flown from the autopilots' own
positions, reported to an independent observer.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import httpx
import pytest

from planner.cases import load_case
from planner.experiments.scenario_generator import crossing_scenario
from planner.scenario import Origin, Scenario
from tests.e2e.flying import bind, online, register, wait_for
from tests.service_process import ServiceProcess
from tests.sitl.ardupilot_sitl import Instance, homes_at_starts, instances
from tests.sitl.observer import observing

pytestmark = [pytest.mark.sitl, pytest.mark.slow]
SPEEDUP = 5.0
CANBERRA = Origin(lat=-35.363262, lon=149.165237, alt_m=584.0)
CROSSING_SEED = 0  # the 10-UAV crossing of the fleet tests


def two_r(scenario: Scenario) -> float:
    return 2 * max(u.radius for u in scenario.uavs) * scenario.grid.cell_size_m


def ten_crossing() -> Scenario:
    scenario = crossing_scenario(CROSSING_SEED, uavs=10)
    return scenario.model_copy(update={"origin": CANBERRA})


def named(name: str) -> Scenario:
    return load_case(name) if name.startswith("case") else ten_crossing()


def speedup(scenario: Scenario) -> float:
    """Ten SITL instances on two cores keep real time only at a lower speed-up."""
    return SPEEDUP if len(scenario.uavs) <= 3 else 2.0


@pytest.mark.parametrize("name", ["case-6", "crossing-10"])
def test_mvo_gcs_fly_flies_real_arducopter(tmp_path: Path, name: str) -> None:
    scenario = named(name)
    source = tmp_path / "scenario.json"
    source.write_text(scenario.model_dump_json())
    homes = homes_at_starts(scenario)
    with instances(homes, tmp_path, speedup(scenario)) as sitl, observing(_ports(sitl)) as observer:
        command = [sys.executable, "-m", "gcs.cli.main", "fly", str(source)]
        command += ["--vehicles", ",".join(i.connection for i in sitl), "--connect-timeout", "60"]
        fly = subprocess.run(command, capture_output=True, text=True, timeout=1800)
        flown = observer.min_separation()
    report = fly.stdout[-3000:] + fly.stderr[-3000:]
    print(report)
    print(f"{name}: observer min separation {flown} m, 2R {two_r(scenario):.2f} m")
    assert fly.returncode == 0, report
    assert "separation flown" in fly.stdout
    assert flown is not None and flown >= two_r(scenario), (flown, report)


def all_events(client: httpx.Client, flight: str) -> list[dict[str, Any]]:
    """Every event of the flight, page by page: one page holds at most 10 000, and ten
    vehicles' Positions events fill the default 1000 long before the flight ends."""
    events: list[dict[str, Any]] = []
    while page := client.get(
        f"/flights/{flight}/events", params={"after": events[-1]["id"] if events else 0}
    ).json():
        events += page
    return events


def _ports(sitl: list[Instance]) -> list[int]:
    return [instance.port for instance in sitl]


@pytest.mark.parametrize("name", ["case-6", "crossing-10"])
def test_the_service_flies_real_arducopter(tmp_path: Path, name: str) -> None:
    scenario = named(name)
    service = ServiceProcess(tmp_path / "data")
    with instances(homes_at_starts(scenario), tmp_path, speedup(scenario)) as sitl:
        service.start()
        try:
            with service.client() as client, observing(_ports(sitl)) as observer:
                sid = client.post("/scenarios", json=scenario.model_dump(mode="json")).json()["id"]
                plan = client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30}).json()
                ids = [register(client, i.connection) for i in sitl]
                flight = bind(client, plan["id"], scenario, ids)
                wait_for(lambda: all(online(client, v) for v in ids), 60, "vehicles online")
                uploaded = client.post(f"/flights/{flight}/upload")
                assert uploaded.status_code == 200, uploaded.text
                assert all(v["ok"] for v in uploaded.json()["vehicles"]), uploaded.text
                assert client.post(f"/flights/{flight}/start").status_code == 202
                state = wait_for(
                    lambda: (
                        (s := client.get(f"/flights/{flight}").json())["state"]
                        in ("landed", "ended", "aborted", "interrupted")
                        and s
                    ),
                    1500,
                    "the flight's end",
                    every=1.0,
                )
                events = all_events(client, flight)
                flown = observer.min_separation()
        finally:
            service.stop()
    assert state["state"] == "landed", (state, [(e["kind"], e["uav_id"]) for e in events])
    ended = next((e for e in events if e["kind"] == "FlightEnded"), None)
    assert ended is not None, (state, [(e["kind"], e["uav_id"]) for e in events][-20:])
    assert ended["data"]["completed"], ended
    assert flown is not None and flown >= two_r(scenario), flown
    print(f"service flight {name}: GCS-measured {ended['data']['min_separation_m']:.2f} m, "
          f"observer {flown:.2f} m, 2R {two_r(scenario):.2f} m")  # fmt: skip
