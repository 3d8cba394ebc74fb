"""The product flown on real ArduCopter SITL, unchanged: `mvo-gcs fly` and the service.

Run with `ARDUPILOT_SITL=/path/to/arducopter` (skipped otherwise: CI cannot reach
ArduPilot's sources). Every test starts fresh instances at the UAVs' start cells, flies
the plan end to end and measures the separation flown from the autopilots' own
positions, reported to an independent observer; one also puts the operator's commands
to them mid-flight.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
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
from tests.sitl.observer import Observer, observing

pytestmark = [pytest.mark.sitl, pytest.mark.slow]
SPEEDUP = 5.0
CANBERRA = Origin(lat=-35.363262, lon=149.165237, alt_m=584.0)
CROSSING_SEED = 0  # the 10-UAV crossing of the fleet tests
STILL_M_S = 0.1  # standing, by the autopilot's own ground speed
HELD_S = 20.0  # of the vehicles' own time, paused
LAND_DRIFT_M = 3.0  # from 1 m/s, a stop and a descent in place


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


@contextmanager
def service_flight(
    tmp_path: Path, scenario: Scenario
) -> Iterator[tuple[httpx.Client, str, Observer]]:
    """Fresh instances at the UAVs' starts and the service, with a flight of `scenario`
    planned, uploaded (verified by read-back) and started."""
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
                yield client, flight, observer
        finally:
            service.stop()


def final_state(client: httpx.Client, flight: str, bound_s: float = 1500) -> dict[str, Any]:
    final = ("landed", "ended", "aborted", "interrupted")
    state: dict[str, Any] = wait_for(
        lambda: (s := client.get(f"/flights/{flight}").json())["state"] in final and s,
        bound_s,
        "the flight's end",
        every=1.0,
    )
    return state


@pytest.mark.parametrize("name", ["case-6", "crossing-10"])
def test_the_service_flies_real_arducopter(tmp_path: Path, name: str) -> None:
    scenario = named(name)
    with service_flight(tmp_path, scenario) as (client, flight, observer):
        state = final_state(client, flight)
        events = all_events(client, flight)
        flown = observer.min_separation()
    assert state["state"] == "landed", (state, [(e["kind"], e["uav_id"]) for e in events])
    ended = next((e for e in events if e["kind"] == "FlightEnded"), None)
    assert ended is not None, (state, [(e["kind"], e["uav_id"]) for e in events][-20:])
    assert ended["data"]["completed"], ended
    assert flown is not None and flown >= two_r(scenario), flown
    print(f"service flight {name}: GCS-measured {ended['data']['min_separation_m']:.2f} m, "
          f"observer {flown:.2f} m, 2R {two_r(scenario):.2f} m")  # fmt: skip


def test_the_operator_pauses_continues_and_lands_real_arducopter(tmp_path: Path) -> None:
    """Case VI through the service, the operator's commands on real autopilots: pause
    mid-flight (every vehicle stops, by its own velocity, and stays stopped), continue
    (they go on), hold one vehicle while it comes down to land (ArduCopter will not
    pause that: it brakes) and continue it, abort with LAND (each comes down where it is
    and disarms; the flight ends `aborted`)."""
    scenario = load_case("case-6")
    with service_flight(tmp_path, scenario) as (client, flight, observer):
        wait_for(lambda: under_way(client, flight), 600, "every vehicle on its way", every=0.5)
        paused = client.post(f"/flights/{flight}/pause")
        assert paused.json()["flight"]["state"] == "paused", paused.text
        wait_for(lambda: max(observer.speeds()) < STILL_M_S, 120, "every vehicle stopped")
        stopped = observer.latest()
        wait_for(lambda: observer.seconds_since(stopped) > HELD_S, 300, f"{HELD_S} s held")
        assert client.get(f"/flights/{flight}").json()["state"] == "paused"
        assert max(observer.moved_since(stopped)) < 0.5, observer.moved_since(stopped)

        going_on = client.post(f"/flights/{flight}/continue")
        assert going_on.json()["flight"]["state"] == "flying", going_on.text
        wait_for(lambda: max(observer.speeds()) > 0.3, 120, "moving again")

        landings = {u.id: landing_seq(client, flight, u.id) for u in scenario.uavs}
        uav, vehicle = wait_for(lambda: coming_down(client, flight, landings), 600, "a descent")
        k = [u.id for u in scenario.uavs].index(uav)
        held = client.post(f"/vehicles/{vehicle}/hold").json()
        assert held["ok"] and "holding in BRAKE" in held["detail"], held
        at_hold = observer.latest()
        wait_for(lambda: observer.seconds_since(at_hold) > 5.0, 120, "5 s to brake")
        braked = observer.latest()
        wait_for(lambda: observer.seconds_since(braked) > 10.0, 120, "10 s braked")
        still = observer.latest()[k]
        assert abs(still.alt - braked[k].alt) < 0.3 and still.alt > 3.0, (braked[k], still)
        assert observer.moved_since(braked)[k] < 0.5, observer.moved_since(braked)
        assert client.post(f"/vehicles/{vehicle}/continue").json()["ok"]
        wait_for(lambda: observer.latest()[k].alt < still.alt - 1.0, 120, f"{uav} landing")

        aborted = client.post(f"/flights/{flight}/abort", json={"mode": "land"})
        assert aborted.status_code == 200, aborted.text
        at_abort = observer.latest()
        state = final_state(client, flight, 600)
        down = observer.latest()
        armed = [track.armed for track in observer.tracks.values()]
        drift = observer.moved_since(at_abort)
    assert state["state"] == "aborted", state
    assert all(mark.alt < 0.3 for mark in down), down
    assert not any(armed), armed
    assert max(drift) < LAND_DRIFT_M, drift  # landed where it was, not at home
    print(f"operator: fleet held {HELD_S} s; {uav} braked coming down ({held['detail']});"
          f" landed within {max(drift):.2f} m of where aborted")  # fmt: skip


def under_way(client: httpx.Client, flight: str) -> bool:
    """Flying, and every vehicle past its first waypoint and short of its last."""
    live = client.get(f"/flights/{flight}/live-state").json()
    progress = [v.get("progress") for v in live["vehicles"]]
    return live["state"] == "flying" and all(
        p is not None and 1 <= p["reached"] < p["items"] - 1 for p in progress
    )


def landing_seq(client: httpx.Client, flight: str, uav: str) -> int:
    """The seq of NAV_LAND (21) in the mission the flight uploaded for `uav`."""
    waypoints = client.get(f"/flights/{flight}/missions/{uav}.waypoints").text
    rows = [line.split("\t") for line in waypoints.splitlines()[1:]]
    return next(int(row[0]) for row in rows if int(row[3]) == 21)


def coming_down(
    client: httpx.Client, flight: str, landings: dict[str, int]
) -> tuple[str, str] | None:
    """(uav, vehicle id) of a vehicle descending on its NAV_LAND, 5 to 15 m up (it flies
    at 20 m)."""
    for v in client.get(f"/flights/{flight}/live-state").json()["vehicles"]:
        p = v.get("progress")
        if p and p["current_seq"] == landings[v["uav_id"]] and 5.0 < (p["alt_m"] or 0.0) < 15.0:
            return v["uav_id"], v["vehicle_id"]
    return None
