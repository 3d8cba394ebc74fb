"""MAVProxy, a third independent client, against the simulated vehicles: with its defaults
it connects over TCP as to ArduPilot SITL and loads one of our `.waypoints` files with
`wp load`, and the vehicle then holds our mission item by item (as ArduPilot stores it);
listening on a UDP port it sees every vehicle that `--out` sends there, by system id.

MAVProxy runs headless, driven over standard input (mavproxy_process.py)."""

from __future__ import annotations

import math
import socket
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from gcs.mavlink.mission_item import Autopilot, Mission
from gcs.mission.build import build_missions
from gcs.mission.files import write_waypoints
from planner.cases import load_case
from planner.pipeline import PlannerSettings, plan
from sitl_mock import Simulator, VehicleConfig
from sitl_mock.codec import mavlink
from tests.conformance.mavproxy_process import MavProxy

SPEEDUP = 20.0
SEEN_S = 20.0
"""Wall seconds for MAVProxy to start (it imports a lot) and see a vehicle."""
UPLOAD_S = 15.0
LOCATION_COMMANDS = {16, 17, 19, 20, 21, 22}


@pytest.fixture(scope="module")
def mission() -> Mission:
    """A case VI mission as the ground station builds it, with a 0.5 m acceptance radius."""
    scenario = load_case("case-6")
    result = plan(scenario, PlannerSettings(population=10, iterations=20))
    missions = build_missions(result, scenario, Autopilot.ARDUPILOT, acceptance_radius_m=0.5)
    return next(iter(missions.values()))


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture
def mavproxy(tmp_path: Path) -> Iterator[list[MavProxy]]:
    started: list[MavProxy] = []
    yield started
    for proc in started:
        proc.stop()


def stored_by_ardupilot(item) -> tuple:
    """Our item as ArduCopter SITL gave it back (docs/sitl_mock.md): relative frames as 3, DO
    items in frame 0 without a position, waypoint holds in whole seconds and no radius,
    NAV_LAND param4 1, NaN 0, altitudes in whole centimetres."""
    p1, p2, p3, p4 = (0.0 if math.isnan(p) else p for p in item.params)
    if item.command in LOCATION_COMMANDS:
        frame, x, y = (3 if item.frame in (3, 6) else 0), item.x, item.y
        z = float(np.float32(int(np.float32(item.z) * np.float32(100.0))) * np.float32(0.01))
    else:
        frame, x, y, z = 0, 0, 0, 0.0
    if item.command == 16:
        p1, p2, p3, p4 = float(int(p1)), 0.0, 0.0, 0.0
    elif item.command == 21:
        p4 = 1.0
    return (
        int(item.command),
        frame,
        x,
        y,
        round(z, 2),
        *(float(np.float32(p)) for p in (p1, p2, p3, p4)),
    )


def held(sim: Simulator, sysid: int) -> list[tuple]:
    return [
        (
            i.command,
            i.frame,
            i.x,
            i.y,
            round(i.z, 2),
            *(float(np.float32(p)) for p in (i.param1, i.param2, i.param3, i.param4)),
        )
        for i in sim.mission(sysid)
    ]


def booted(sim: Simulator, sysid: int) -> bool:
    return sim.wait_until(lambda: sim.state(sysid).system_status != mavlink.MAV_STATE_BOOT, SEEN_S)


def load_waypoints(proxy: MavProxy, path: Path) -> bool:
    after = proxy.command(f"wp load {path}")
    return proxy.wait_for("Flight plan received", UPLOAD_S, after) is not None


def test_mavproxy_with_its_defaults_loads_our_waypoints_file(
    mission: Mission, mavproxy: list[MavProxy], tmp_path: Path
) -> None:
    path = tmp_path / "uav.waypoints"
    write_waypoints(mission, path)
    assert mission.home is not None
    sim = Simulator([VehicleConfig(sysid=1, transport="tcp", home=mission.home)], speedup=SPEEDUP)
    with sim.running():
        proxy = MavProxy(sim.connection_string(1), tmp_path)
        mavproxy.append(proxy)
        assert proxy.wait_for("online system 1", SEEN_S) is not None, proxy.output
        assert booted(sim, 1)
        assert load_waypoints(proxy, path), proxy.output
        ours = [stored_by_ardupilot(item) for item in mission.items[1:]]
        assert held(sim, 1)[1:] == ours  # item 0 is the vehicle's home
        assert len(ours) == len(mission.items) - 1 >= 4


def test_mavproxy_listening_on_udp_sees_every_vehicle_sent_there(
    mission: Mission, mavproxy: list[MavProxy], tmp_path: Path
) -> None:
    port = free_udp_port()
    out = (f"udp:127.0.0.1:{port}",)
    assert mission.home is not None
    configs = [
        VehicleConfig(sysid=k, transport="tcp", home=mission.home, outputs=out) for k in (1, 2, 3)
    ]
    path = tmp_path / "uav.waypoints"
    write_waypoints(mission, path)
    sim = Simulator(configs, speedup=SPEEDUP)
    with sim.running():
        proxy = MavProxy(f"udpin:127.0.0.1:{port}", tmp_path)
        mavproxy.append(proxy)
        for sysid in (1, 2, 3):
            assert proxy.wait_for(f"Detected vehicle {sysid}:1", SEEN_S) is not None, proxy.output
        assert booted(sim, 2)
        after = proxy.command("vehicle 2")
        assert proxy.wait_for("Set vehicle 2", SEEN_S, after) is not None, proxy.output
        assert load_waypoints(proxy, path), proxy.output
        assert held(sim, 2)[1:] == [stored_by_ardupilot(item) for item in mission.items[1:]]
        assert len(sim.mission(1)) == len(sim.mission(3)) == 1  # only the chosen one
