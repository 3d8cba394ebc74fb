"""Vehicles that announce themselves (issue 15): mock vehicles send to the service's UDP
port as `mvo-gcs sitl --out` (and MAVProxy's outputs) do; the service lists each by its
system id, and one registered from that list flies on the same link."""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from gcs.mavlink.connection import RELOCK_AFTER_S
from gcs.mavlink.recent import SENDER_LIMIT
from planner.cases import load_case
from sitl_mock import Simulator, VehicleConfig
from tests.e2e.flying import wait_for
from tests.impostor import LONDON, forged
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
                assert isinstance(found, list)
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


@contextmanager
def impostor(port: int, sysid: int) -> Iterator[socket.socket]:
    """A local program that keeps sending as vehicle `sysid` to the listening port."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    stop = threading.Event()

    def speak() -> None:
        while not stop.wait(0.2):
            sock.sendto(forged(sysid), ("127.0.0.1", port))

    thread = threading.Thread(target=speak, daemon=True)
    thread.start()
    try:
        yield sock
    finally:
        stop.set()
        thread.join()
        sock.close()


def test_a_silent_vehicle_on_the_listening_port_is_not_taken_over(tmp_path: Path) -> None:
    """Issue 28: after a silence longer than RELOCK_AFTER_S, a program that had waited for
    it spoke for the vehicle (its position became the vehicle's). A registered vehicle
    keeps its address; the impostor is shown (`claimed_from`), and only the operator
    moves the vehicle to it. A signing key is refused there: nothing signs that port."""
    port = free_udp_port()
    listen = f"udpin:127.0.0.1:{port}"
    home = homes_at_starts(load_case("case-1"))[0]
    config = VehicleConfig(sysid=1, home=home, transport="tcp", outputs=(f"udp:{listen[6:]}",))
    service = ServiceProcess(tmp_path / "data", {"MVO_GCS_DISCOVERY_URL": listen})
    with Simulator([config], speedup=20.0, seed=1).running() as sim:
        service.start()
        try:
            with service.client() as client:
                keyed = {"connection": listen, "sysid": 1, "signing_key": "a passphrase"}
                refused = client.post("/vehicles", json=keyed)
                assert refused.status_code == 422, refused.text
                assert "signing_key" in refused.json()["detail"]
                answer = client.post("/vehicles", json={"connection": listen, "sysid": 1})
                assert answer.status_code == 201, answer.text
                vid = answer.json()["id"]

                def live() -> dict[str, Any]:
                    body: dict[str, Any] = client.get(f"/vehicles/{vid}").json()["live"]
                    return body

                wait_for(lambda: live()["online"] and live()["lat"], 30, "the vehicle heard")
                silent_until = sim.sim_time + (RELOCK_AFTER_S + 2.0) * 20.0
                sim.silence(1, silent_until - sim.sim_time)
                with impostor(port, 1) as sock:
                    wait_for(lambda: sim.sim_time > silent_until + 20.0, 60, "the silence over")
                    wait_for(lambda: live()["online"], 30, "the vehicle heard again")
                    here = live()
                    assert abs(float(here["lat"]) - home[0]) < 0.001, here  # not London
                    claimant = here["claimed_from"]
                    assert isinstance(claimant, dict), here
                    impostor_at = f"127.0.0.1:{sock.getsockname()[1]}"
                    assert claimant["address"] == impostor_at
                    held = client.post(f"/vehicles/{vid}/hold")
                    assert held.status_code == 200, held.text  # the vehicle answered it

                    wrong = client.post(f"/vehicles/{vid}/address", json={"address": "1.2.3.4:5"})
                    assert wrong.status_code == 409, wrong.text
                    moved = client.post(f"/vehicles/{vid}/address", json={"address": impostor_at})
                    assert moved.status_code == 200, moved.text
                    wait_for(
                        lambda: abs(float(live()["lat"] or 0) - LONDON[0] / 1e7) < 0.001,
                        30,
                        "the operator's choice taking effect",
                    )
        finally:
            service.stop()


def test_a_flood_of_senders_on_the_listening_port_is_bounded(tmp_path: Path) -> None:
    """Issue 28: every address that ever sent to the listening port kept a parser and got
    the ground station's HEARTBEAT every second, for ever. Now the service keeps the
    latest SENDER_LIMIT senders: of 3 x SENDER_LIMIT that each sent once, at most that
    many hear from it once the latest has been heard (the earlier ones may have heard a
    beat while they were among the latest), over two more rounds of heartbeats."""
    port = free_udp_port()
    listen = f"udpin:127.0.0.1:{port}"
    service = ServiceProcess(tmp_path / "data", {"MVO_GCS_DISCOVERY_URL": listen})
    service.start()
    senders = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(3 * SENDER_LIMIT)]
    heard = [0] * len(senders)
    try:
        for sender in senders:
            sender.bind(("127.0.0.1", 0))
            sender.setblocking(False)
            sender.sendto(b"\xfd\x09not mavlink", ("127.0.0.1", port))

        def listen_once() -> bool:
            for k, sender in enumerate(senders):
                try:
                    while sender.recv(2048):
                        heard[k] += 1
                except BlockingIOError:
                    pass
            return heard[-1] >= 2

        wait_for(listen_once, 30, "two heartbeats at the latest sender")
        heard[:] = [0] * len(senders)  # from here, every sender has been heard
        wait_for(listen_once, 30, "two more heartbeats at the latest sender")
        reached = sum(1 for count in heard if count)
        assert reached <= SENDER_LIMIT, (reached, heard)
    finally:
        for sender in senders:
            sender.close()
        service.stop()


def test_announced_vehicles_that_fall_silent_are_forgotten(tmp_path: Path) -> None:
    """Issue 28: 253 vehicles announced once on the listening port stayed listed (and
    asked for telemetry) for ever. Unregistered and silent, they are forgotten."""
    port = free_udp_port()
    env = {"MVO_GCS_DISCOVERY_URL": f"udpin:127.0.0.1:{port}", "MVO_GCS_DISCOVERY_FORGET_S": "2"}
    service = ServiceProcess(tmp_path / "data", env)
    service.start()
    try:
        with (
            service.client() as client,
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as fake,
        ):

            def listed() -> set[int]:
                return {v["sysid"] for v in client.get("/vehicles/discovered").json()}

            def announced() -> bool:
                for sysid in (201, 202, 203):
                    fake.sendto(forged(sysid), ("127.0.0.1", port))
                return listed() == {201, 202, 203}

            wait_for(announced, 30, "three announced")
            wait_for(lambda: not listed(), 30, "the silent ones forgotten")
    finally:
        service.stop()


def test_a_taken_listening_port_is_reported(tmp_path: Path) -> None:
    """Issue 28: with the discovery port held by another program, the service said
    "ready" and the console said nothing: no vehicle would ever be heard."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as squatter:
        squatter.bind(("127.0.0.1", 0))
        port = squatter.getsockname()[1]
        service = ServiceProcess(
            tmp_path / "data", {"MVO_GCS_DISCOVERY_URL": f"udpin:127.0.0.1:{port}"}
        )
        service.start()
        try:
            with service.client() as client:
                health = client.get("/health/ready").json()
            assert health["status"] == "ready"  # the API works; discovery does not
            [warning] = health["warnings"]
            assert f"127.0.0.1:{port}" in warning and "not listening" in warning, warning
        finally:
            service.stop()
