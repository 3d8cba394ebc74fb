"""Flying through the real service: vehicles at a case's starts, a flight made and waited on.

Every wait here is for a condition, bounded by a generous wall-clock limit (a loaded
machine is slow, never wrong); nothing sleeps to "let things settle".
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal, TypeVar

import httpx

from gcs.mission.geodesy import GridFrame
from planner.cases import load_case
from planner.model.scenario import Scenario
from sitl_mock import Faults, Simulator, VehicleConfig

SPEEDUP = 20.0
T = TypeVar("T")


def fleet_at_starts(
    scenario: Scenario,
    speedup: float = SPEEDUP,
    faults: Faults | None = None,
    **config: Any,
) -> Simulator:
    """One mock vehicle per UAV, at its start cell."""
    frame = GridFrame.of(scenario)
    configs = []
    for sysid, uav in enumerate(scenario.uavs, start=1):
        lat, lon = frame.to_geodetic(*uav.start)
        home = (float(lat), float(lon), frame.alt0)
        configs.append(
            VehicleConfig(sysid=sysid, port=0, home=home, faults=faults or Faults(), **config)
        )
    return Simulator(configs, speedup=speedup, seed=1)


def wait_for(
    condition: Callable[[], T | Literal[False] | None],
    timeout: float,
    what: str,
    every: float = 0.2,
) -> T:
    """The first truthy value of `condition()`, polled; AssertionError after `timeout`.
    (A condition's False or None is waited past, so it is no part of the value's type.)
    Most conditions are requests to a service that flies a fleet meanwhile, on the same
    two cores: five a second are plenty."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}")
        time.sleep(every)


@dataclass
class Flight:
    """A flight of `case` bound to the vehicles of `sim`, made through the API."""

    client: httpx.Client
    sim: Simulator
    scenario: Scenario
    scenario_id: str
    plan: dict[str, Any]
    vehicle_ids: list[str]
    id: str

    @classmethod
    def make(cls, client: httpx.Client, sim: Simulator, case: str = "case-1") -> Flight:
        scenario = load_case(case)
        answer = client.post("/scenarios", json=scenario.model_dump(mode="json"))
        assert answer.status_code == 201, answer.text
        sid = answer.json()["id"]
        plan = client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30}).json()
        assert plan["plan"]["feasible"], plan
        ids = [register(client, sim.connection_string(s)) for s in sim.sysids]
        flight = bind(client, plan["id"], scenario, ids)
        return cls(client, sim, scenario, sid, plan, ids, flight)

    def state(self) -> str:
        return str(self.client.get(f"/flights/{self.id}").json()["state"])

    def post(self, action: str, **body: Any) -> httpx.Response:
        return self.client.post(f"/flights/{self.id}/{action}", json=body or None)

    def upload(self) -> dict[str, Any]:
        """Upload once every vehicle is online (registration connects in the background)."""
        wait_for(lambda: all(online(self.client, v) for v in self.vehicle_ids), 30, "vehicles")
        answer = self.post("upload")
        assert answer.status_code == 200, answer.text
        body: dict[str, Any] = answer.json()
        assert body["flight"]["state"] == "uploaded", body
        return body

    def fly(self) -> None:
        """Upload and start; back once the flight is flying."""
        self.upload()
        answer = self.post("start")
        assert answer.status_code == 202, answer.text
        self.wait_state("flying", timeout=90)

    def wait_state(self, *states: str, timeout: float = 120) -> str:
        try:
            return wait_for(lambda: (s := self.state()) in states and s, timeout, f"{states}")
        except AssertionError as exc:  # say where the flight is stuck
            live = self.client.get(f"/flights/{self.id}/live-state").json()
            events = self.client.get(f"/flights/{self.id}/events").json()
            kinds = [(e["kind"], e["uav_id"]) for e in events][-20:]
            raise AssertionError(f"{exc}; live state {live}; last events {kinds}") from None

    def modes(self) -> set[str]:
        return {self.sim.state(k).mode for k in self.sim.sysids}

    def airborne(self) -> bool:
        return any(self.sim.state(k).alt > 1.0 for k in self.sim.sysids)


def register(client: httpx.Client, connection: str) -> str:
    answer = client.post("/vehicles", json={"connection": connection})
    assert answer.status_code == 201, answer.text
    return str(answer.json()["id"])


def bind(client: httpx.Client, plan_id: str, scenario: Scenario, vehicle_ids: list[str]) -> str:
    bindings = {u.id: v for u, v in zip(scenario.uavs, vehicle_ids, strict=True)}
    answer = client.post("/flights", json={"plan_id": plan_id, "bindings": bindings})
    assert answer.status_code == 201, answer.text
    return str(answer.json()["id"])


def online(client: httpx.Client, vehicle_id: str) -> bool:
    return bool(client.get(f"/vehicles/{vehicle_id}").json()["live"]["online"])


def ground_speed(sim: Simulator, sysid: int) -> float:
    north, east, _ = sim.state(sysid).velocity_ned
    return math.hypot(north, east)
