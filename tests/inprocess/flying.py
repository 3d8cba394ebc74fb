"""Flying through the in-process service: a flight made, uploaded, started and waited on.

Every wait is for a condition, bounded in the loop's virtual seconds; nothing sleeps to
"let things settle", and nothing depends on how busy the machine is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import httpx

from gcs.mission.geodesy import GridFrame
from planner.cases import load_case
from planner.model.scenario import Scenario
from sitl_mock import Simulator
from tests.inprocess.service import until

LONG_PLAN = {
    "objective": "paper",
    "iterations": 20_000,
    "population": 60,
    "time_budget_s": None,
    "patience": None,
}
"""The paper's flow with every iteration run: minutes of work, so a job is still running
whenever a test looks (the anytime default ends case VI within a tenth of a second)."""


async def plan_scenario(client: httpx.AsyncClient, scenario: Scenario) -> dict[str, Any]:
    """POST the scenario and plan it (within 30 s); the feasible plan as the API gives it."""
    answer = await client.post("/scenarios", json=scenario.model_dump(mode="json"))
    assert answer.status_code == 201, answer.text
    sid = answer.json()["id"]
    planned = await client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30})
    assert planned.status_code == 201, planned.text
    plan: dict[str, Any] = planned.json()
    assert plan["plan"]["feasible"], plan
    return plan


@dataclass
class Flight:
    """A flight of a scenario bound to the vehicles of `sim`, made through the API."""

    client: httpx.AsyncClient
    sim: Simulator
    scenario: Scenario
    scenario_id: str
    plan: dict[str, Any]
    vehicle_ids: list[str]
    id: str

    @classmethod
    async def make(
        cls, client: httpx.AsyncClient, sim: Simulator, case: str | Scenario = "case-1"
    ) -> Flight:
        scenario = load_case(case) if isinstance(case, str) else case
        plan = await plan_scenario(client, scenario)
        ids = [await register(client, sim.connection_string(s)) for s in sim.sysids]
        flight = await bind(client, plan["id"], scenario, ids)
        return cls(client, sim, scenario, plan["scenario_id"], plan, ids, flight)

    async def state(self) -> str:
        return str((await self.client.get(f"/flights/{self.id}")).json()["state"])

    async def post(self, action: str, **body: Any) -> httpx.Response:
        return await self.client.post(f"/flights/{self.id}/{action}", json=body or None)

    async def online(self) -> bool:
        return all([await online(self.client, v) for v in self.vehicle_ids])

    async def upload(self) -> dict[str, Any]:
        """Upload once every vehicle is online (registration connects in the background)."""
        await until(self.online, 30, "every vehicle online")
        answer = await self.post("upload")
        assert answer.status_code == 200, answer.text
        body: dict[str, Any] = answer.json()
        assert body["flight"]["state"] == "uploaded", body
        return body

    async def fly(self) -> None:
        """Upload and start; back once the flight is flying."""
        await self.upload()
        answer = await self.post("start")
        assert answer.status_code == 202, answer.text
        await self.wait_state("flying", timeout=120, every=0.1)

    async def wait_state(self, *states: str, timeout: float = 600, every: float = 1.0) -> str:
        """The first of `states` the flight is in, looked at every `every` simulated
        seconds: each look is a request and a database read, and ten a second took a
        sixth of the flight tests' time (test_resume and a paused-fleet test: 18.7 s at
        0.1 s, 15.4 s at 1 s)."""

        async def reached() -> str | None:
            state = await self.state()
            return state if state in states else None

        try:
            return await until(reached, timeout, f"flight {self.id} {states}", every=every)
        except AssertionError as exc:  # say where the flight is stuck
            live = (await self.client.get(f"/flights/{self.id}/live-state")).json()
            events = await self.events()
            kinds = [(e["kind"], e["uav_id"]) for e in events][-20:]
            raise AssertionError(f"{exc}; live state {live}; last events {kinds}") from None

    async def events(self) -> list[dict[str, Any]]:
        """Every stored event, page by page."""
        events: list[dict[str, Any]] = []
        while True:
            params: dict[str, Any] = {"limit": 1000}
            if events:
                params["after"] = events[-1]["id"]
            page = (await self.client.get(f"/flights/{self.id}/events", params=params)).json()
            events += page
            if len(page) < 1000:
                return events

    def modes(self) -> set[str]:
        return {self.sim.state(k).mode for k in self.sim.sysids}

    def airborne(self) -> bool:
        return any(self.sim.state(k).alt > 1.0 for k in self.sim.sysids)


async def register(client: httpx.AsyncClient, connection: str) -> str:
    answer = await client.post("/vehicles", json={"connection": connection})
    assert answer.status_code == 201, answer.text
    return str(answer.json()["id"])


async def bind(
    client: httpx.AsyncClient, plan_id: str, scenario: Scenario, vehicle_ids: list[str]
) -> str:
    bindings = {u.id: v for u, v in zip(scenario.uavs, vehicle_ids, strict=True)}
    answer = await client.post("/flights", json={"plan_id": plan_id, "bindings": bindings})
    assert answer.status_code == 201, answer.text
    return str(answer.json()["id"])


async def upload_once_online(client: httpx.AsyncClient, flight_id: str) -> dict[str, Any]:
    """Upload as soon as every vehicle is online (registration connects in the background:
    until then the upload is 409); the answer."""

    async def uploaded() -> dict[str, Any] | None:
        answer = await client.post(f"/flights/{flight_id}/upload")
        if answer.status_code == 409:
            return None
        assert answer.status_code == 200, answer.text
        body: dict[str, Any] = answer.json()
        return body

    return await until(uploaded, 20, "an upload to vehicles online")


async def live(client: httpx.AsyncClient, vehicle_id: str) -> dict[str, Any]:
    body: dict[str, Any] = (await client.get(f"/vehicles/{vehicle_id}")).json()["live"]
    return body


async def online(client: httpx.AsyncClient, vehicle_id: str) -> bool:
    return bool((await live(client, vehicle_id)).get("online"))


def assert_down_apart_at_the_goals(sim: Simulator, scenario: Scenario) -> None:
    """By the simulator's truth: no two vehicles ever closer than 2R, and every one
    disarmed within 2.5 m of its goal."""
    cell = scenario.grid.cell_size_m
    needed = 2 * max(u.radius for u in scenario.uavs) * cell
    separation = sim.min_separation()
    assert separation is not None and separation.distance_m >= needed, separation
    frame = GridFrame.of(scenario)
    for sysid, spec in enumerate(scenario.uavs, start=1):
        final = sim.final_position(sysid)
        assert final is not None and not final.armed, final
        x, y = frame.to_cells(final.lat, final.lon)
        assert abs(x - spec.goal[0]) * cell < 2.5 and abs(y - spec.goal[1]) * cell < 2.5


def ground_speed(sim: Simulator, sysid: int) -> float:
    north, east, _ = sim.state(sysid).velocity_ned
    return math.hypot(north, east)
