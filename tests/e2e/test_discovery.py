"""Vehicles that announce themselves (issue 15): mock vehicles send to the service's UDP
port as `mvo-gcs sitl --out` (and MAVProxy's outputs) do; the service lists each by its
system id, and one registered from that list flies on the same link."""

from __future__ import annotations

import socket
from pathlib import Path

from planner.cases import load_case
from sitl_mock import Simulator, VehicleConfig
from tests.e2e.flying import wait_for
from tests.service_process import ServiceProcess
from tests.sitl.ardupilot_sitl import homes_at_starts


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_the_service_discovers_vehicles_that_send_to_its_port(tmp_path: Path) -> None:
    port = free_udp_port()
    listen = f"udpin:127.0.0.1:{port}"
    scenario = load_case("case-6")
    configs = [
        VehicleConfig(sysid=k, home=home, transport="tcp", outputs=(f"udp:127.0.0.1:{port}",))
        for k, home in enumerate(homes_at_starts(scenario), start=1)
    ]
    service = ServiceProcess(tmp_path / "data", {"MVO_GCS_DISCOVERY_URL": listen})
    with Simulator(configs, speedup=20.0, seed=1).running():
        service.start()
        try:
            with service.client() as client:
                found = wait_for(
                    lambda: len(seen := client.get("/vehicles/discovered").json()) == 3 and seen,
                    30,
                    "three vehicles heard",
                )
                assert [v["sysid"] for v in found] == [1, 2, 3]
                assert {v["connection"] for v in found} == {listen}
                assert all(v["vehicle_id"] is None for v in found)
                assert all(v["live"]["autopilot"] == "ardupilot" for v in found)
                wait_for(
                    lambda: all(
                        v["live"]["lat"] is not None
                        for v in client.get("/vehicles/discovered").json()
                    ),
                    30,
                    "their positions",
                )
                second = client.post("/vehicles", json={"connection": listen, "sysid": 2})
                assert second.status_code == 201, second.text
                vid = second.json()["id"]
                wait_for(
                    lambda: client.get(f"/vehicles/{vid}").json()["live"]["online"], 30, "online"
                )
                assert client.get(f"/vehicles/{vid}").json()["live"]["sysid"] == 2
                listed = {
                    v["sysid"]: v["vehicle_id"] for v in client.get("/vehicles/discovered").json()
                }
                assert listed == {1: None, 2: vid, 3: None}
                again = client.post("/vehicles", json={"connection": listen, "sysid": 2})
                assert again.status_code == 409
                held = client.post(f"/vehicles/{vid}/hold")  # commands reach vehicle 2 only
                assert held.status_code == 200, held.text
        finally:
            service.stop()


def test_one_vehicle_reached_on_its_port_and_on_the_listening_port_is_registered_once(
    tmp_path: Path,
) -> None:
    """As SITL behind MAVProxy serves it: each vehicle on its own TCP port and on the
    service's listening port. Whichever way comes second is refused, naming the first,
    because the vehicle says which board it is (AUTOPILOT_VERSION), not its address."""
    port = free_udp_port()
    listen = f"udpin:127.0.0.1:{port}"
    configs = [
        VehicleConfig(sysid=k, home=home, transport="tcp", outputs=(f"udp:127.0.0.1:{port}",))
        for k, home in enumerate(homes_at_starts(load_case("case-1")), start=1)
    ]
    service = ServiceProcess(tmp_path / "data", {"MVO_GCS_DISCOVERY_URL": listen})
    with Simulator(configs, speedup=20.0, seed=1).running() as sim:
        service.start()
        try:
            with service.client() as client:

                def registered_and_identified(body: dict[str, object]) -> str:
                    answer = client.post("/vehicles", json=body)
                    assert answer.status_code == 201, answer.text
                    vid = str(answer.json()["id"])
                    wait_for(
                        lambda: client.get(f"/vehicles/{vid}").json()["live"].get("uid"),
                        30,
                        f"vehicle {vid} says which board it is",
                    )
                    return vid

                heard_first = registered_and_identified({"connection": listen, "sysid": 1})
                by_port = client.post("/vehicles", json={"connection": sim.connection_string(1)})
                assert by_port.status_code == 409, by_port.text
                assert heard_first in by_port.json()["detail"]

                port_first = registered_and_identified({"connection": sim.connection_string(2)})
                heard = client.post("/vehicles", json={"connection": listen, "sysid": 2})
                assert heard.status_code == 409, heard.text
                assert port_first in heard.json()["detail"]
                uids = {
                    client.get(f"/vehicles/{v}").json()["live"]["uid"]
                    for v in (heard_first, port_first)
                }
                assert len(uids) == 2  # two boards, two ids
                assert len(client.get("/vehicles").json()) == 2
        finally:
            service.stop()
