"""Live replanning over real HTTP: an object dropped mid-flight on one UAV's remaining
path changes only the UAVs it touches, and the fleet still lands separated."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from gcs.mission.geodesy import GridFrame
from planner.cases import load_case
from planner.trajectory import Trajectory
from tests.e2e.test_case_vi_flight import fleet_at_starts
from tests.service_process import ServiceProcess


def _wait(predicate: Callable[[], Any], timeout: float, what: str) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def _plan_clock(client: httpx.Client, fid: str) -> float:
    """Where the fleet is on the plan, in the plan's own seconds (the flight is slowed)."""
    state = client.get(f"/flights/{fid}/live-state").json()
    clocks = [v["progress"]["clock_s"] for v in state["vehicles"] if "progress" in v]
    return max(clocks, default=0.0) / state["pace_factor"]


def test_an_object_on_one_path_replans_only_that_uav(tmp_path: Path) -> None:
    scenario = load_case("case-6")
    sim = fleet_at_starts(scenario, speedup=8.0)
    service = ServiceProcess(tmp_path / "data")
    with sim.running():
        service.start()
        try:
            with service.client() as client:
                sid = client.post("/scenarios", json=scenario.model_dump(mode="json")).json()["id"]
                plan = client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30}).json()
                ids = [
                    client.post("/vehicles", json={"connection": sim.connection_string(s)}).json()[
                        "id"
                    ]
                    for s in sim.sysids
                ]
                bindings = {u.id: v for u, v in zip(scenario.uavs, ids, strict=True)}
                fid = client.post(
                    "/flights", json={"plan_id": plan["id"], "bindings": bindings}
                ).json()["id"]
                _wait(
                    lambda: client.post(f"/flights/{fid}/upload").status_code == 200, 20, "upload"
                )
                before = {s: list(sim.mission(s)) for s in sim.sysids}
                assert client.post(f"/flights/{fid}/start").json()["state"] == "starting"

                # uav3 flies north along x = 7; put a bird a few cells ahead of it.
                now = _wait(lambda: (c := _plan_clock(client, fid)) > 0.5 and c, 60, "flight")
                uav3 = next(u for u in plan["plan"]["uavs"] if u["id"] == "uav3")
                ahead = Trajectory(np.array(uav3["trajectory"])).at([now + 2.0])[0]
                cell = [round(float(ahead[0])), round(float(ahead[1]))]
                reported_at = sim.sim_time
                answer = client.post(f"/flights/{fid}/objects", json={"cell": cell})
                assert answer.status_code == 200, answer.text
                replan = answer.json()
                assert replan["touched"] == ["uav3"], replan
                assert replan["changed"] == ["uav3"] and replan["feasible"], replan
                assert [u["ok"] for u in replan["uploads"]] == [True]

                after = {s: list(sim.mission(s)) for s in sim.sysids}
                assert after[1] == before[1] and after[2] == before[2]
                assert after[3] != before[3]

                _wait(
                    lambda: (
                        client.get(f"/flights/{fid}").json()["state"]
                        in ("landed", "ended", "aborted")
                    ),
                    120,
                    "landing",
                )
                assert client.get(f"/flights/{fid}").json()["state"] == "landed"
                kinds = [e["kind"] for e in client.get(f"/flights/{fid}/events").json()]
                assert "ObjectReported" in kinds
        finally:
            service.stop()

    cell_m = scenario.grid.cell_size_m
    flown = sim.min_separation()
    assert flown is not None and flown.distance_m >= 2 * 0.3 * cell_m, flown
    frame = GridFrame.of(scenario)
    track = [p for p in sim.track(3) if p.alt > 1.0]
    x, y = frame.to_cells([p.lat for p in track], [p.lon for p in track])
    radius = 0.3
    inside = (np.abs(x - cell[0]) < 0.5 + radius) & (np.abs(y - cell[1]) < 0.5 + radius)
    times = np.array([p.t for p in track])
    assert not inside[times > reported_at].any(), "uav3 flew through the bird's cell"
