"""Live replanning through the service's API, in process on one virtual clock: an object
dropped mid-flight on one UAV's remaining path changes only the UAVs it touches, and the
fleet still lands separated."""

from __future__ import annotations

import httpx
import numpy as np
import pytest

from gcs.mission.geodesy import GridFrame
from planner.cases import load_case
from planner.model.trajectory import Trajectory
from tests.inprocess.flying import bind, register
from tests.inprocess.service import InProcessService, until

pytestmark = [pytest.mark.virtual_clock]


async def _plan_clock(client: httpx.AsyncClient, fid: str) -> float:
    """Where the fleet is on the plan, in the plan's own seconds (the flight is slowed)."""
    state = (await client.get(f"/flights/{fid}/live-state")).json()
    clocks = [v["progress"]["clock_s"] for v in state["vehicles"] if "progress" in v]
    return float(max(clocks, default=0.0) / state["pace_factor"])


async def test_an_object_on_one_path_replans_only_that_uav(gcs: InProcessService) -> None:
    scenario = load_case("case-6")
    sim = await gcs.vehicles.at_starts(scenario)
    client = gcs.client
    sid = (await client.post("/scenarios", json=scenario.model_dump(mode="json"))).json()["id"]
    planned = await client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30})
    assert planned.status_code == 201, planned.text
    plan = planned.json()
    ids = [await register(client, sim.connection_string(s)) for s in sim.sysids]
    fid = await bind(client, plan["id"], scenario, ids)

    async def uploaded() -> bool:
        return (await client.post(f"/flights/{fid}/upload")).status_code == 200

    await until(uploaded, 20, "upload")
    before = {s: list(sim.mission(s)) for s in sim.sysids}
    assert (await client.post(f"/flights/{fid}/start")).json()["state"] == "starting"

    # uav3 flies north along x = 7; put a bird a few cells ahead of it.
    async def under_way() -> float | None:
        clock = await _plan_clock(client, fid)
        return clock if clock > 0.5 else None

    now = await until(under_way, 120, "the flight under way")
    assert now is not None
    uav3 = next(u for u in plan["plan"]["uavs"] if u["id"] == "uav3")
    ahead = Trajectory(np.array(uav3["trajectory"])).at([now + 2.0])[0]
    cell = [round(float(ahead[0])), round(float(ahead[1]))]
    reported_at = sim.sim_time
    answer = await client.post(f"/flights/{fid}/objects", json={"cell": cell})
    assert answer.status_code == 200, answer.text
    replan = answer.json()
    assert replan["touched"] == ["uav3"], replan
    assert replan["changed"] == ["uav3"] and replan["feasible"], replan
    assert [u["ok"] for u in replan["uploads"]] == [True]

    after = {s: list(sim.mission(s)) for s in sim.sysids}
    assert after[1] == before[1] and after[2] == before[2]
    assert after[3] != before[3]

    async def ended() -> str | None:
        state = str((await client.get(f"/flights/{fid}")).json()["state"])
        return state if state in ("landed", "ended", "aborted") else None

    assert await until(ended, 600, "landing", every=1.0) == "landed"
    kinds = [e["kind"] for e in (await client.get(f"/flights/{fid}/events")).json()]
    assert "ObjectReported" in kinds

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
