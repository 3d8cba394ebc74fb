"""Case VI end to end over real HTTP and a real WebSocket, flown by mock vehicles:
scenario → plan → (service restart) → vehicles → flight → upload → start → live stream
until every vehicle has landed; then the separation the simulator measured and the
stored events."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from websockets.sync.client import ClientConnection, connect

from gcs.mission.geodesy import GridFrame
from planner.cases import load_case
from planner.scenario import Scenario
from sitl_mock import Simulator, VehicleConfig
from tests.service_process import ServiceProcess

SPEEDUP = 20.0


def fleet_at_starts(scenario: Scenario, speedup: float = SPEEDUP) -> Simulator:
    frame = GridFrame.of(scenario)
    configs = []
    for sysid, uav in enumerate(scenario.uavs, start=1):
        lat, lon = frame.to_geodetic(*uav.start)
        home = (float(lat), float(lon), frame.alt0)
        configs.append(VehicleConfig(sysid=sysid, port=0, home=home))
    return Simulator(configs, speedup=speedup, seed=1)


@pytest.fixture
def vehicles() -> Iterator[Simulator]:
    sim = fleet_at_starts(load_case("case-6"))
    with sim.running():
        yield sim


def test_case_vi_is_planned_uploaded_flown_and_recorded(
    tmp_path: Path, vehicles: Simulator
) -> None:
    scenario = load_case("case-6")
    service = ServiceProcess(tmp_path / "data")
    service.start()
    try:
        with service.client() as client:
            sid = client.post("/scenarios", json=scenario.model_dump(mode="json")).json()["id"]
            plan = client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30}).json()
            assert plan["plan"]["feasible"]
        service.stop()  # a restart between planning and flying loses nothing
        service.start()
        with service.client() as client:
            ids = []
            for sysid in vehicles.sysids:
                answer = client.post(
                    "/vehicles", json={"connection": vehicles.connection_string(sysid)}
                )
                assert answer.status_code == 201, answer.text
                ids.append(answer.json()["id"])
            bindings = {u.id: v for u, v in zip(scenario.uavs, ids, strict=True)}
            flight = client.post("/flights", json={"plan_id": plan["id"], "bindings": bindings})
            assert flight.status_code == 201, flight.text
            fid = flight.json()["id"]

            early = client.post(f"/flights/{fid}/start")
            assert early.status_code == 409 and "upload" in early.json()["detail"]

            uploaded = _when_online(client, fid)
            assert uploaded["flight"]["state"] == "uploaded", uploaded
            assert all(v["ok"] for v in uploaded["vehicles"])
            for uav in ("uav1", "uav3"):  # the files users download are the missions flown
                for kind in ("plan", "waypoints"):
                    flown = client.get(f"/flights/{fid}/missions/{uav}.{kind}")
                    offered = client.get(f"/plans/{plan['id']}/missions/{uav}.{kind}")
                    assert flown.status_code == offered.status_code == 200
                    assert flown.text == offered.text, (uav, kind)

            ws_url = service.url.replace("http", "ws") + f"/flights/{fid}/live"
            with connect(ws_url, open_timeout=10) as ws:
                started = client.post(f"/flights/{fid}/start")
                assert started.status_code == 202, started.text
                assert started.json()["state"] == "starting", started.text
                messages = _read_until_ended(ws)
            kinds = {m["kind"] for m in messages if m["type"] == "event"}
            assert {"ItemReached", "VehicleFinished", "FlightEnded"} <= kinds
            states = [m for m in messages if m["type"] == "state"]
            assert states and states[-1]["state"] == "landed"
            assert all(v["lat"] is not None for v in states[-1]["vehicles"])

            stored = client.get(f"/flights/{fid}/events").json()
            stored_kinds = [e["kind"] for e in stored]
            streamed = [
                m["kind"]
                for m in messages
                if m["type"] == "event" and m["kind"] not in ("Progress", "FlightState")
            ]
            for kind in set(streamed):
                assert stored_kinds.count(kind) >= streamed.count(kind), kind
            assert client.get(f"/flights/{fid}").json()["state"] == "landed"
    finally:
        service.stop()

    cell = scenario.grid.cell_size_m
    needed = 2 * max(u.radius for u in scenario.uavs) * cell
    flown = vehicles.min_separation()
    assert flown is not None and flown.distance_m >= needed, flown
    frame = GridFrame.of(scenario)
    for sysid, uav in enumerate(scenario.uavs, start=1):
        final = vehicles.final_position(sysid)
        x, y = frame.to_cells(final.lat, final.lon)
        assert abs(x - uav.goal[0]) * cell < 2.5 and abs(y - uav.goal[1]) * cell < 2.5
        assert not final.armed


def _when_online(client: httpx.Client, fid: str) -> dict:
    deadline = time.monotonic() + 20
    while True:
        answer = client.post(f"/flights/{fid}/upload")
        if answer.status_code != 409 or time.monotonic() > deadline:
            assert answer.status_code == 200, answer.text
            return answer.json()
        time.sleep(0.2)


def _read_until_ended(ws: ClientConnection) -> list[dict]:
    messages = []
    while True:
        raw = ws.recv(timeout=120)
        message = json.loads(raw)
        messages.append(message)
        if message["type"] == "state" and message["state"] in ("landed", "ended", "aborted"):
            return messages
