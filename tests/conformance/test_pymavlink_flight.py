"""Flying a mission at a speed-up, checked against the simulator's recorded truth, and the
`mvo-gcs sitl` command as a subprocess."""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pymap3d
import pytest

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil

from sitl_mock import Simulator, VehicleConfig

mavutil.set_dialect("ardupilotmega")
mavlink = mavutil.mavlink

HOME = (47.397742, 8.545594, 488.0)
SIDE_M = 60.0
ALT_M = 20.0
CORNERS_EN = [(0.0, SIDE_M), (SIDE_M, SIDE_M), (SIDE_M, 0.0), (0.0, 0.0)]
ACCEPT_RADIUS_M = 2.0


def corner(east: float, north: float) -> tuple[int, int]:
    lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, *HOME)
    return round(lat * 1e7), round(lon * 1e7)


def square_mission(with_home: bool) -> list[tuple[int, int, int, float, float]]:
    """(command, x, y, z, p1): [home,] take-off, four corners, land where it stops."""
    items = [(16, *corner(0, 0), HOME[2], 0.0)] if with_home else []
    items.append((22, 0, 0, ALT_M, 0.0))
    items += [(16, *corner(e, n), ALT_M, 0.0) for e, n in CORNERS_EN]
    items.append((21, 0, 0, 0.0, 0.0))
    return items


def upload(link, items) -> int:
    link.mav.mission_count_send(1, 1, len(items), 0)
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        msg = link.recv_match(
            type=["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"],
            blocking=True,
            timeout=1.0,
        )
        if msg is None:
            continue
        if msg.get_type() == "MISSION_ACK":
            return msg.type
        command, x, y, z, p1 = items[msg.seq]
        frame = 0 if msg.seq == 0 and command == 16 and z == HOME[2] else 6
        link.mav.mission_item_int_send(1, 1, msg.seq, frame, command, 0, 1, p1, 0, 0, 0, x, y, z, 0)
    return -1


def command(link, cmd: int, *params: float) -> int:
    padded = [*params, *[0.0] * (7 - len(params))]
    link.mav.command_long_send(1, 1, cmd, 0, *padded)
    ack = link.recv_match(
        type="COMMAND_ACK", blocking=True, timeout=2.0, condition=f"COMMAND_ACK.command=={cmd}"
    )
    return -1 if ack is None else ack.result


def horizontal_path_m(track) -> float:
    lat = np.array([p.lat for p in track])
    lon = np.array([p.lon for p in track])
    east, north, _ = pymap3d.geodetic2enu(lat, lon, HOME[2], *HOME)
    return float(np.sum(np.hypot(np.diff(east), np.diff(north))))


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_square_mission_is_flown_and_landed_at_the_last_waypoint(autopilot):
    ardupilot = autopilot == "ardupilot"
    # Over TCP: the test counts every MISSION_ITEM_REACHED, and a starved reader on a busy
    # machine loses UDP datagrams (PX4 repeats only the last one). UDP has its own tests.
    config = VehicleConfig(sysid=1, home=HOME, autopilot=autopilot, transport="tcp")
    sim = Simulator([config], speedup=20.0)
    with sim.running():
        link = mavutil.mavlink_connection(sim.connection_string(1), source_system=255)
        try:
            link.mav.heartbeat_send(6, 8, 0, 0, 0)
            assert (
                link.recv_match(
                    type="HEARTBEAT",
                    blocking=True,
                    timeout=5.0,
                    condition="HEARTBEAT.system_status!=1",
                )
                is not None
            )
            assert upload(link, square_mission(with_home=ardupilot)) == 0
            assert sim.wait_until(lambda: sim.state(1).estimate_ready, 10.0)
            if ardupilot:  # GUIDED -> arm -> AUTO -> MISSION_START, as ArduCopter needs
                assert command(link, 176, 1, 4) == 0
                assert command(link, 400, 1) == 0
                assert command(link, 176, 1, 3) == 0
                time.sleep(0.1)
                assert sim.state(1).alt == 0.0  # AUTO alone does not take off
                assert command(link, 300) == 0
            else:  # PX4: arm, then AUTO.MISSION
                assert command(link, 400, 1) == 0
                assert command(link, 176, 1, 4, 4) == 0
            assert sim.wait_until(lambda: sim.state(1).alt > 1.0, 5.0)
            reached: list[int] = []
            deadline = time.monotonic() + 15.0
            while time.monotonic() < deadline and sim.state(1).armed:
                msg = link.recv_match(type="MISSION_ITEM_REACHED", blocking=True, timeout=0.5)
                if msg is not None:
                    reached.append(msg.seq)
            assert not sim.state(1).armed  # landed and disarmed: the end of the flight
            while (
                msg := link.recv_match(type="MISSION_ITEM_REACHED", blocking=True, timeout=0.2)
            ) is not None:
                reached.append(msg.seq)
        finally:
            link.close()
        if ardupilot:  # take-off and corners once each; no report for NAV_LAND (seq 6)
            assert reached == [1, 2, 3, 4, 5]
            state = sim.state(1)
            assert (state.mode, state.mission_seq, state.mission_state) == ("AUTO", 1, 3)
        else:  # PX4 reports every navigation item, the landing too, and repeats them
            assert sorted(set(reached)) == list(range(6))
        final = sim.final_position(1)
        assert final is not None
        land_e, land_n, _ = pymap3d.geodetic2enu(final.lat, final.lon, HOME[2], *HOME)
        assert math.hypot(land_e, land_n) <= ACCEPT_RADIUS_M
        assert final.alt == 0.0
        track = sim.track(1)
        assert max(p.alt for p in track) == pytest.approx(ALT_M, abs=0.5)
        flown = horizontal_path_m([p for p in track if p.armed])
        legs = 4 * SIDE_M
        # each of the three corners is rounded, its middle inside the acceptance radius
        assert legs - 3 * 2 * ACCEPT_RADIUS_M < flown < legs + 2
        assert sim.min_separation() is None  # one vehicle: no pairs


def test_two_vehicles_separation_is_recorded():
    homes = [HOME, (*pymap3d.enu2geodetic(30.0, 0.0, 0.0, *HOME)[:2], HOME[2])]
    sim = Simulator([VehicleConfig(sysid=i + 1, home=h) for i, h in enumerate(homes)], speedup=20.0)
    with sim.running():
        assert sim.wait_until(lambda: sim.state(2).estimate_ready, 5.0)
        for sysid in (1, 2):
            vehicle = sim.vehicle(sysid)
            sim._call(vehicle.flight.set_mode, vehicle.flight.mode.GUIDED, sim.sim_time)
            sim._call(vehicle.flight.arm, sim.sim_time)
            sim._call(vehicle.flight.takeoff, 10.0, sim.sim_time)
        assert sim.wait_until(lambda: min(sim.state(s).alt for s in (1, 2)) > 9.0, 5.0)
    separation = sim.min_separation()
    assert separation is not None and separation.sysids == (1, 2)
    assert separation.distance_m == pytest.approx(30.0, abs=0.01)
    east, _, _ = pymap3d.geodetic2enu(separation.lat, separation.lon, HOME[2], *HOME)
    assert east == pytest.approx(15.0, abs=0.1)


def wait_for_lines(path: Path, count: int, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.exists() and len(path.read_text().splitlines()) >= count:
            return True
        time.sleep(0.05)
    return False


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def sysids_heard(link, count: int, timeout: float) -> set[int]:
    heard: set[int] = set()
    deadline = time.monotonic() + timeout
    while len(heard) < count and (remaining := deadline - time.monotonic()) > 0:
        msg = link.recv_match(type="HEARTBEAT", blocking=True, timeout=remaining)
        if msg is not None:
            heard.add(msg.get_srcSystem())
    return heard


def test_mvo_gcs_sitl_prints_connection_strings_and_exits_cleanly_on_sigint(tmp_path: Path):
    """TCP servers by default, `--out` to a listening pymavlink, the strings to paste, and a
    clean exit on SIGINT (the process is stopped by its pid, with bounded waits)."""
    exe = Path(sys.executable).parent / "mvo-gcs"
    log = tmp_path / "track.jsonl"
    port = free_udp_port()
    listener = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255)
    argv = ["sitl", "--vehicles", "3", "--base-port", "0", "--speedup", "10"]
    argv += ["--track-log", str(log), "--out", f"udp:127.0.0.1:{port}"]
    proc = subprocess.Popen(
        [str(exe), *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None
    try:
        lines = [proc.stdout.readline().strip() for _ in range(3)]
        assert [line.split(":")[0] for line in lines] == ["vehicle 1", "vehicle 2", "vehicle 3"]
        url = lines[1].split(": ", 1)[1]
        assert url.startswith("tcp:127.0.0.1:")  # ArduPilot SITL's transport by default
        link = mavutil.mavlink_connection(url, source_system=255)
        heartbeat = link.recv_match(type="HEARTBEAT", blocking=True, timeout=5.0)
        link.close()
        assert heartbeat is not None and heartbeat.get_srcSystem() == 2
        assert sysids_heard(listener, 3, timeout=5.0) == {1, 2, 3}
        assert wait_for_lines(log, 3 * 10, timeout=10.0)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10.0) == 0
    finally:
        listener.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=5.0)
    printed = proc.stdout.read()
    assert f"mavproxy.py --master={url}" in printed
    assert f"tcpout://{url.removeprefix('tcp:')}" in printed
    assert f"mavproxy.py --master=udpin:127.0.0.1:{port}" in printed
    assert f"udpin://127.0.0.1:{port}" in printed
    samples = log.read_text().splitlines()
    assert {json.loads(line)["sysid"] for line in samples[-3:]} == {1, 2, 3}
