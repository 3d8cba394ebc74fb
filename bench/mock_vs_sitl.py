"""The mock's flight physics against real ArduCopter SITL: one small mission on each.

Takes off to 10 m, flies 1 m/s (the service's pace) through a blended corner A, stops
at B and holds 2 s, turns at C, lands at D; all 20 m legs. Prints, per vehicle, the
simulated time (from the vehicle's own time_boot_ms) at which each waypoint was
reported reached after the first leg began, how close it passed corner A and how fast,
and how long it stood at B. Run it where a SITL binary is built:

    .venv/bin/python bench/mock_vs_sitl.py --sitl /path/to/arducopter

Both vehicles run at `--speedup` (default 2) on loopback TCP ports 5760 (SITL) and 5900
(mock), each stopped by its process id afterwards.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pymap3d
from pymavlink import mavutil

HOME = (-35.363262, 149.165237, 584.0)
POINTS = {"A": (20.0, 0.0), "B": (20.0, 20.0), "C": (0.0, 20.0), "D": (0.0, 0.0)}
ALT_M, SPEED_M_S, HOLD_S = 10.0, 1.0, 2
MAV = mavutil.mavlink
REL = MAV.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


def mission() -> list[tuple[int, int, float, float, float, float, int, int, float]]:
    """(frame, command, p1, p2, p3, p4, x, y, z) for seq 0 (home) onwards."""

    def place(name: str) -> tuple[int, int]:
        lat, lon, _ = pymap3d.enu2geodetic(*POINTS[name], 0.0, *HOME)
        return round(lat * 1e7), round(lon * 1e7)

    nan = math.nan
    home = (round(HOME[0] * 1e7), round(HOME[1] * 1e7))
    return [
        (MAV.MAV_FRAME_GLOBAL, MAV.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, 0, *home, HOME[2]),
        (REL, MAV.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, *home, ALT_M),
        (MAV.MAV_FRAME_MISSION, MAV.MAV_CMD_DO_CHANGE_SPEED, 1, SPEED_M_S, -1, 0, 0, 0, 0),
        (REL, MAV.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, nan, *place("A"), ALT_M),
        (REL, MAV.MAV_CMD_NAV_WAYPOINT, HOLD_S, 0, 0, nan, *place("B"), ALT_M),
        (REL, MAV.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, nan, *place("C"), ALT_M),
        (REL, MAV.MAV_CMD_NAV_LAND, 0, 0, 0, nan, *place("D"), 0.0),
    ]


@dataclass
class Flight:
    track: np.ndarray  # (t, east, north, alt, ground speed) rows, t the vehicle's time
    current: list[tuple[float, int]]  # (t, seq) at each change of MISSION_CURRENT
    reached: list[tuple[float, int]]  # (t, seq) of each MISSION_ITEM_REACHED


def fly(connection: str) -> Flight:
    intervals = {33: 5e4, 42: 2e5}  # GLOBAL_POSITION_INT 20 Hz, MISSION_CURRENT 5 Hz
    with mission_started(connection, mission(), intervals) as (link, target):
        return _record(link, target)


@contextlib.contextmanager
def mission_started(
    connection: str, items: list, intervals_us: dict[int, float]
) -> Iterator[tuple[mavutil.mavfile, int]]:
    """A vehicle once booted: the messages asked for at their intervals, `items` uploaded
    (with (frame, command, p1-p4, x, y, z) per item), armed in GUIDED and its mission
    started in AUTO; the link and the vehicle's system id, closed on the way out."""
    link = mavutil.mavlink_connection(connection, source_system=250)
    try:
        link.wait_heartbeat(timeout=60)
        target = link.target_system
        while True:  # boot over: missions are accepted
            beat = link.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
            if beat is not None and beat.system_status != MAV.MAV_STATE_BOOT:
                break
        for message_id, interval in intervals_us.items():
            link.mav.command_long_send(
                target, 1, MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0, message_id, interval, 0, 0, 0, 0, 0
            )
        upload_items(link, target, items)
        _command_until_accepted(link, target, MAV.MAV_CMD_DO_SET_MODE, 1, 4)  # GUIDED
        _command_until_accepted(link, target, MAV.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        _command_until_accepted(link, target, MAV.MAV_CMD_DO_SET_MODE, 1, 3)  # AUTO
        _command_until_accepted(link, target, MAV.MAV_CMD_MISSION_START)
        yield link, target
    finally:
        link.close()


def leg_north(speed_m_s: float, length_m: float, alt_m: float) -> list:
    """Take off at HOME to `alt_m`, fly `length_m` north at `speed_m_s`, land there."""
    lat, lon, _ = pymap3d.enu2geodetic(0.0, length_m, 0.0, *HOME)
    far = (int(lat * 1e7), int(lon * 1e7))
    home = (int(HOME[0] * 1e7), int(HOME[1] * 1e7))
    return [
        (MAV.MAV_FRAME_GLOBAL, MAV.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, 0, *home, 0.0),
        (REL, MAV.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, *home, alt_m),
        (MAV.MAV_FRAME_MISSION, MAV.MAV_CMD_DO_CHANGE_SPEED, 1, speed_m_s, -1, 0, 0, 0, 0),
        (REL, MAV.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, 0, *far, alt_m),
        (REL, MAV.MAV_CMD_NAV_LAND, 0, 0, 0, 0, *far, 0.0),
    ]


def upload_items(link: mavutil.mavfile, target: int, items: list) -> None:
    """The mission protocol by hand, (frame, command, p1-p4, x, y, z) per item, tried
    again until the vehicle accepts it (a vehicle still booting refuses)."""
    for _ in range(30):
        link.mav.mission_count_send(target, 1, len(items), 0)
        while (
            msg := link.recv_match(
                type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"],
                blocking=True,
                timeout=3,
            )
        ) is not None:
            if msg.get_type() == "MISSION_ACK":
                if msg.type == MAV.MAV_MISSION_ACCEPTED:
                    return
                break
            frame, command, p1, p2, p3, p4, x, y, z = items[msg.seq]
            link.mav.mission_item_int_send(
                target, 1, msg.seq, frame, command, 0, 1, p1, p2, p3, p4, x, y, z
            )
        time.sleep(1.0)
    raise RuntimeError("mission upload not accepted")


def _command_until_accepted(
    link: mavutil.mavfile, target: int, command: int, *params: float
) -> None:
    padded = [*params, *[0.0] * (7 - len(params))]
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        link.mav.command_long_send(target, 1, command, 0, *padded)
        ack = link.recv_match(type="COMMAND_ACK", blocking=True, timeout=3)
        if ack is not None and ack.command == command and ack.result == MAV.MAV_RESULT_ACCEPTED:
            return
        time.sleep(1.0)  # arming waits for the position estimate
    raise RuntimeError(f"command {command} never accepted")


def _record(link: mavutil.mavfile, target: int) -> Flight:
    track: list[tuple[float, float, float, float, float]] = []
    current: list[tuple[float, int]] = []
    reached: list[tuple[float, int]] = []
    now = 0.0
    deadline = time.monotonic() + 400
    while time.monotonic() < deadline:
        msg = link.recv_match(blocking=True, timeout=1)
        if msg is None or msg.get_srcSystem() != target:
            continue
        kind = msg.get_type()
        if kind == "GLOBAL_POSITION_INT":
            now = msg.time_boot_ms / 1e3
            east, north, _ = pymap3d.geodetic2enu(msg.lat / 1e7, msg.lon / 1e7, HOME[2], *HOME)
            speed = math.hypot(msg.vx, msg.vy) / 100
            track.append((now, east, north, msg.relative_alt / 1e3, speed))
        elif kind == "MISSION_CURRENT" and (not current or current[-1][1] != msg.seq):
            current.append((now, msg.seq))
        elif kind == "MISSION_ITEM_REACHED":
            reached.append((now, msg.seq))
        elif kind == "HEARTBEAT" and not msg.base_mode & MAV.MAV_MODE_FLAG_SAFETY_ARMED:
            landed = len(track) > 50 and track[-1][3] < 0.3
            if landed:
                break
    return Flight(np.array(track), current, reached)


def summary(flight: Flight) -> dict[str, float]:
    track = flight.track
    start = next(t for t, seq in flight.current if seq == 3)  # the first leg begins
    reached = {seq: t - start for t, seq in flight.reached}
    to_a = np.hypot(track[:, 1] - POINTS["A"][0], track[:, 2] - POINTS["A"][1])
    at_b = np.hypot(track[:, 1] - POINTS["B"][0], track[:, 2] - POINTS["B"][1]) < 0.3
    standing = track[at_b & (track[:, 4] < 0.05), 0]
    return {
        "A reached (s)": reached.get(3, math.nan),
        "B reached (s)": reached.get(4, math.nan),
        "C reached (s)": reached.get(5, math.nan),
        "closest to A (m)": float(to_a.min()),
        "speed there (m/s)": float(track[to_a.argmin(), 4]),
        "standing at B (s)": float(standing.max() - standing.min()) if len(standing) else 0.0,
    }


SITL_URL, MOCK_URL = "tcp:127.0.0.1:5760", "tcp:127.0.0.1:5900"


@contextlib.contextmanager
def sitl_and_mock(sitl_binary: Path, speedup: float) -> Iterator[None]:
    """One ArduCopter SITL (`SITL_URL`) and one mock vehicle (`MOCK_URL`) at `speedup`,
    both at HOME, stopped by their process ids on the way out."""
    defaults = sitl_binary.parents[3] / "Tools/autotest/default_params/copter.parm"
    home = ",".join(f"{v}" for v in HOME)
    with tempfile.TemporaryDirectory() as workdir:
        sitl = subprocess.Popen(
            [str(sitl_binary), "--model", "+", "--speedup", f"{speedup:g}",
             "--defaults", str(defaults), "-I0", "--sysid", "1", "--home", f"{home},0"],
            cwd=workdir, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        mock = subprocess.Popen(
            [sys.executable, "-m", "sitl_mock", "--base-port", "5900",
             "--speedup", f"{speedup:g}", f"--home={home}"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        try:
            time.sleep(2.0)  # both servers listening
            yield
        finally:
            for process in (sitl, mock):
                process.terminate()
                process.wait(timeout=10)


def sitl_parser(doc: str) -> argparse.ArgumentParser:
    """The arguments every SITL-beside-mock script takes: the binary and its speed-up."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--sitl", type=Path, required=True, help="ArduCopter SITL binary")
    parser.add_argument("--speedup", type=float, default=2.0)
    return parser


def main() -> int:
    args = sitl_parser(__doc__).parse_args()
    with sitl_and_mock(args.sitl, args.speedup):
        rows = {"ArduCopter SITL": summary(fly(SITL_URL))}
        rows["sitl_mock"] = summary(fly(MOCK_URL))
    names = list(rows)
    print("| measure | " + " | ".join(names) + " |")
    print("| --- |" + " ---: |" * len(names))
    for measure in rows[names[0]]:
        print(f"| {measure} | " + " | ".join(f"{rows[n][measure]:.2f}" for n in names) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
