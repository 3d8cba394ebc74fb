"""Cruise kinematics of the mock against real ArduCopter SITL, at 5 and 10 m/s side by side.

One mission per vehicle flies, for each cruise speed V (set by DO_CHANGE_SPEED), five
tests from a standstill hover at 10 m, and the script measures them in the vehicle's own
time (GLOBAL_POSITION_INT.time_boot_ms at 25 Hz); a command's moment is that of the first
GLOBAL_POSITION_INT after its COMMAND_ACK (after the MISSION_CURRENT for a jump):

1. acceleration and cruise: a 150 m leg to a waypoint with a 2 s hold: time and distance
   to 50, 90, 95 and 99 % of V, peak acceleration, where the slow-down (below 98 % of
   the mid-leg speed) begins (distance to the waypoint), its time and distance to
   standstill, peak deceleration, overshoot;
2. pause and brake: on a 30 V m leg, DO_PAUSE_CONTINUE 0 once 10 V m are flown, continue
   after 5 s of standstill (< 0.1 m/s throughout); on the next 25 V m leg the same with
   BRAKE mode and back to AUTO: time and distance to standstill and to 50 and 90 % of V
   again (DO_CHANGE_SPEED is repeated after this leg: ArduCopter forgets it in BRAKE);
3. corners: five 60 m legs turning by 30, 60, 90 and 120 degrees at waypoints without a
   hold, with WP_RADIUS_M 2 m then 0.5 m: per corner, the lowest speed, the closest
   approach to the waypoint, the largest cross-track error from the polyline, and the
   time from the middle of the leg in to the middle of the leg out against 60 m at V;
4. MISSION_SET_CURRENT to the waypoint after the current one (further along the same
   line) while cruising at V: the dip in speed, how long it lasts, the time lost;
5. the parameters that shape all this, read with PARAM_REQUEST_READ (names of ArduCopter
   4.8 and of older versions; the absent are shown as "-").

Run it inside a loopback-only network namespace (SITL listens on 0.0.0.0), from the
repository's root:

    unshare -n bash -c 'ip link set lo up; .venv/bin/python bench/kinematics_vs_sitl.py \\
        --sitl /work/ardupilot/build/sitl/bin/arducopter'

SITL (`--model +`, the default `copter.parm` beside the binary's source tree) runs at
`--speedup` (default 2) on TCP 5760, the mock (`python -m sitl_mock`, ArduCopter
flavour) at `--mock-speedup` (default 4) on TCP 5900; each is stopped by its process id.
`--tracks DIR` keeps the raw tracks as JSON and `--from-tracks DIR` analyses kept ones
again without flying; `--only sitl|mock` flies one vehicle. The tables go to stdout and
to `--output` (default bench/results/kinematics_vs_sitl.txt).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pymap3d
from mock_vs_sitl import upload_items  # bench/ is on the path of a script run from it
from pymavlink import mavutil

HOME = (-35.363262, 149.165237, 584.0)
ALT_M = 10.0
SPEEDS = (5.0, 10.0)
RADII = (2.0, 0.5)
TURNS_DEG = (30.0, -60.0, 90.0, -120.0)
"""Heading change at each corner of the chain (positive: to the right)."""
LEG_M = 60.0
ACCEL_LEG_M = 150.0
PAUSE_LEG_V = 30.0
BRAKE_LEG_V = 25.0
TRIGGER_V = 10.0
"""Pause, brake and jump once 10 V metres of their leg are flown (at V by then)."""
JUMP_FIRST_V, JUMP_NEXT_V, JUMP_REF_V = 20.0, 35.0, 28.0
STAND_S = 5.0
STILL_M_S = 0.1
GPI_HZ = 25.0
FLAG_REL, FLAG_ABS = 0.10, 0.3
MAV = mavutil.mavlink
REL = MAV.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
BRAKE_MODE, AUTO_MODE, GUIDED_MODE = 17, 3, 4
PARAMS = (
    "WP_SPD", "WPNAV_SPEED", "WP_ACC", "WPNAV_ACCEL", "WP_ACC_CNR", "WPNAV_ACCEL_C",
    "WP_JERK", "WPNAV_JERK", "WP_RADIUS_M", "WPNAV_RADIUS", "PSC_JERK_NE", "PSC_JERK_XY",
    "PSC_NE_POS_P", "PSC_POSXY_P", "LOIT_SPEED_MS", "LOIT_SPEED", "LOIT_ACC_MAX_M",
    "LOIT_ACC_MAX", "LOIT_BRK_ACC_M", "LOIT_BRK_ACCEL", "LOIT_BRK_JRK_M", "LOIT_BRK_JERK",
    "LOIT_BRK_DELAY", "LOIT_ANG_MAX", "LOIT_OPTIONS", "PHLD_BRK_RATE", "ATC_INPUT_TC",
    "ATC_ACC_R_MAX", "ATC_ACC_P_MAX", "ATC_RATE_R_MAX", "ATC_RATE_P_MAX", "ANGLE_MAX",
    "ATC_ANGLE_MAX", "PSC_ANGLE_MAX", "MIS_RESTART", "WP_YAW_BEHAVIOR", "FENCE_ENABLE",
)  # fmt: skip
"""BRAKE mode itself has no parameter: BRAKE_MODE_DECEL_RATE_MSS (7.5) is compiled in."""

Item = tuple[int, int, float, float, float, float, int, int, float]
Point = tuple[float, float]


# -- the mission ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Waypoint:
    name: str
    seq: int
    east: float
    north: float
    hold: float

    @property
    def at(self) -> np.ndarray:
        return np.array([self.east, self.north])


@dataclass
class Plan:
    items: list[Item] = field(default_factory=list)
    points: dict[str, Waypoint] = field(default_factory=dict)

    def add(self, name: str, east: float, north: float, hold: float = 0.0) -> Waypoint:
        lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, *HOME)
        seq = len(self.items)
        self.items.append(
            (REL, MAV.MAV_CMD_NAV_WAYPOINT, hold, 0, 0, math.nan,
             round(lat * 1e7), round(lon * 1e7), ALT_M)
        )  # fmt: skip
        self.points[name] = Waypoint(name, seq, east, north, hold)
        return self.points[name]

    def speed(self, speed: float) -> None:
        self.items.append(
            (MAV.MAV_FRAME_MISSION, MAV.MAV_CMD_DO_CHANGE_SPEED, 1, speed, -1, 0, 0, 0, 0)
        )

    def __getitem__(self, name: str) -> Waypoint:
        return self.points[name]

    def following(self, waypoint: Waypoint) -> Waypoint:
        """The next waypoint in the mission (DO items skipped)."""
        return min((w for w in self.points.values() if w.seq > waypoint.seq), key=lambda w: w.seq)


def chain(start: Point, heading_deg: float) -> list[Point]:
    """The corner test's polyline: five LEG_M legs turning by TURNS_DEG."""
    points, heading = [np.array(start)], heading_deg
    for turn in (0.0, *TURNS_DEG):
        heading += turn
        step = np.array([math.sin(math.radians(heading)), math.cos(math.radians(heading))])
        points.append(points[-1] + LEG_M * step)
    return [(float(p[0]), float(p[1])) for p in points]


def mission() -> Plan:
    """Home, take-off, then per speed: the acceleration leg (S-A), pause leg (A-P), brake
    leg (P-B), the jump test (B-M1-M2, M1 a pass-through point), two corner chains (K, J).
    DO_CHANGE_SPEED comes again after the brake test: ArduCopter forgets it when AUTO is
    entered anew (ModeAuto::init clears desired_speed_override_ms)."""
    plan = Plan()
    home = (round(HOME[0] * 1e7), round(HOME[1] * 1e7))
    plan.items.append((MAV.MAV_FRAME_GLOBAL, MAV.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, 0, *home, 0.0))
    plan.items.append((REL, MAV.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, *home, ALT_M))
    for block, v in enumerate(SPEEDS):
        x0, y0, tag = 250.0 * block, 20.0, f"{v:g}"
        plan.speed(v)
        plan.add(f"{tag}/S", x0, y0, hold=5)
        plan.add(f"{tag}/A", x0, y0 + ACCEL_LEG_M, hold=2)
        plan.add(f"{tag}/P", x0, y0 + ACCEL_LEG_M + PAUSE_LEG_V * v, hold=2)
        brake_end = y0 + ACCEL_LEG_M + (PAUSE_LEG_V + BRAKE_LEG_V) * v
        plan.add(f"{tag}/B", x0, brake_end, hold=3)
        plan.speed(v)
        plan.add(f"{tag}/M1", x0, brake_end - JUMP_FIRST_V * v)
        plan.add(f"{tag}/M2", x0, brake_end - JUMP_NEXT_V * v, hold=3)
        first = chain((x0 + 60.0, brake_end - JUMP_NEXT_V * v), 180.0)
        second = chain((first[-1][0] + 40.0, first[-1][1]), 0.0)
        for letter, points in (("K", first), ("J", second)):
            plan.speed(v)
            for k, (east, north) in enumerate(points):
                hold = 5 if k == 0 else (3 if k == len(points) - 1 else 0)
                plan.add(f"{tag}/{letter}{k}", east, north, hold=hold)
    return plan


# -- flying --------------------------------------------------------------------------------


@dataclass
class Flight:
    """What a vehicle reported: its track and the moments of events, in its own time."""

    track: np.ndarray  # rows (t, east, north, alt, v_east, v_north)
    events: list[tuple[float, str]]
    params: dict[str, float | None]
    wall_s: float
    started: str = ""
    """UTC start of the flight (ISO 8601) and the load average then."""

    def when(self, name: str, after: float = -math.inf) -> float:
        return next((t for t, e in self.events if e == name and t >= after), math.nan)

    def to_json(self) -> dict:
        return {
            "track": self.track.tolist(),
            "events": self.events,
            "params": self.params,
            "wall_s": self.wall_s,
            "started": self.started,
        }

    @classmethod
    def from_json(cls, data: dict) -> Flight:
        events = [(float(t), str(e)) for t, e in data["events"]]
        track = np.array(data["track"])
        return cls(track, events, data["params"], data["wall_s"], data.get("started", ""))


class Pilot:
    """Flies the plan on one connection and pulls its triggers while recording."""

    def __init__(self, link: mavutil.mavfile, plan: Plan) -> None:
        self.link = link
        self.plan = plan
        self.target = 1
        self.rows: list[tuple[float, ...]] = []
        self.events: list[tuple[float, str]] = []
        self._unstamped: list[str] = []
        self._current = -1
        self._mode = -1
        self._pending: dict[int, tuple[str, list[float], float]] = {}
        self._done: set[str] = set()
        self._still_since: dict[str, float] = {}
        self._radius_param = "WP_RADIUS_M"

    # -- set-up, blocking --------------------------------------------------------------

    def prepare(self) -> dict[str, float | None]:
        self.link.wait_heartbeat(timeout=90)
        self.target = self.link.target_system
        while True:  # boot over: missions are accepted
            beat = self.link.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
            if beat is not None and beat.system_status != MAV.MAV_STATE_BOOT:
                break
        for message_id, hz in ((33, GPI_HZ), (42, 10.0)):
            self.link.mav.command_long_send(
                self.target, 1, MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                message_id, 1e6 / hz, 0, 0, 0, 0, 0,
            )  # fmt: skip
        params = {name: self.read_param(name) for name in PARAMS}
        if params.get("WP_RADIUS_M") is None and params.get("WPNAV_RADIUS") is not None:
            self._radius_param = "WPNAV_RADIUS"
        if params.get("FENCE_ENABLE"):
            self.set_param("FENCE_ENABLE", 0)  # the legs reach 700 m from home
        self.upload()
        self.command_until_accepted(MAV.MAV_CMD_DO_SET_MODE, 1, GUIDED_MODE)
        self.command_until_accepted(MAV.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        self.command_until_accepted(MAV.MAV_CMD_DO_SET_MODE, 1, AUTO_MODE)
        self.command_until_accepted(MAV.MAV_CMD_MISSION_START)
        return params

    def read_param(self, name: str) -> float | None:
        for _ in range(2):
            self.link.mav.param_request_read_send(self.target, 1, name.encode(), -1)
            deadline = time.monotonic() + 0.8
            while time.monotonic() < deadline:
                msg = self.link.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.3)
                if msg is not None and msg.param_id == name:
                    return float(msg.param_value)
        return None

    def set_param(self, name: str, value: float) -> None:
        self.link.mav.param_set_send(
            self.target, 1, name.encode(), value, MAV.MAV_PARAM_TYPE_REAL32
        )

    def upload(self) -> None:
        upload_items(self.link, self.target, self.plan.items)

    def command_until_accepted(self, command: int, *params: float) -> None:
        padded = [*params, *[0.0] * (7 - len(params))]
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline:
            self.link.mav.command_long_send(self.target, 1, command, 0, *padded)
            ack = self.link.recv_match(type="COMMAND_ACK", blocking=True, timeout=3)
            if ack is not None and ack.command == command and ack.result == 0:
                return
            time.sleep(1.0)  # arming waits for the position estimate
        raise RuntimeError(f"command {command} never accepted")

    # -- the flight, event-driven ------------------------------------------------------

    def fly(self, wall_limit_s: float) -> None:
        last = len(self.plan.items) - 1
        deadline = time.monotonic() + wall_limit_s
        while time.monotonic() < deadline:
            msg = self.link.recv_match(blocking=True, timeout=1)
            self._resend_pending()
            if msg is None or msg.get_srcSystem() != self.target:
                continue
            kind = msg.get_type()
            if kind == "GLOBAL_POSITION_INT":
                self._position(msg)
                if self._current == last and self._standing("end", 3.0):
                    return
            elif kind == "MISSION_CURRENT" and msg.seq != self._current:
                self._current = msg.seq
                self._unstamped.append(f"current {msg.seq}")
            elif kind == "MISSION_ITEM_REACHED":
                self._unstamped.append(f"reached {msg.seq}")
            elif kind == "STATUSTEXT":
                self._unstamped.append(f"text {msg.text}")
            elif kind == "HEARTBEAT" and msg.custom_mode != self._mode:
                self._mode = msg.custom_mode
                self._unstamped.append(f"mode {msg.custom_mode}")
            elif kind == "COMMAND_ACK" and msg.command in self._pending:
                tag, _, _ = self._pending.pop(msg.command)
                self._unstamped.append(f"{tag} ack {msg.result}")
            elif kind == "PARAM_VALUE":
                self._unstamped.append(f"param {msg.param_id} {msg.param_value:g}")
        raise RuntimeError(f"flight not over in {wall_limit_s:.0f} s (at item {self._current})")

    def _position(self, msg: mavutil.mavlink.MAVLink_message) -> None:
        now = msg.time_boot_ms / 1e3
        east, north, _ = pymap3d.geodetic2enu(msg.lat / 1e7, msg.lon / 1e7, HOME[2], *HOME)
        self.rows.append((now, east, north, msg.relative_alt / 1e3, msg.vy / 100, msg.vx / 100))
        self.events.extend((now, name) for name in self._unstamped)
        self._unstamped.clear()
        self._drive(now)

    def _speed(self) -> float:
        return math.hypot(self.rows[-1][4], self.rows[-1][5])

    def _standing(self, key: str, seconds: float) -> bool:
        """Whether the vehicle has stood still (< STILL_M_S) `seconds` in a row."""
        now = self.rows[-1][0]
        if self._speed() >= STILL_M_S:
            self._still_since.pop(key, None)
            return False
        return now - self._still_since.setdefault(key, now) >= seconds

    def _flown(self, start: str, end: str) -> float:
        a, b = self.plan[start].at, self.plan[end].at
        unit = (b - a) / np.linalg.norm(b - a)
        return float((np.array(self.rows[-1][1:3]) - a) @ unit)

    def _once(self, key: str, action: Callable[[], None]) -> None:
        if key not in self._done:
            self._done.add(key)
            action()

    def _command(self, tag: str, command: int, *params: float) -> None:
        padded = [*params, *[0.0] * (7 - len(params))]
        self._pending[command] = (tag, padded, time.monotonic())
        self.link.mav.command_long_send(self.target, 1, command, 0, *padded)
        self.events.append((self.rows[-1][0], f"{tag} sent"))

    def _resend_pending(self) -> None:
        for command, (tag, padded, sent) in list(self._pending.items()):
            if time.monotonic() - sent > 1.5:
                self._pending[command] = (tag, padded, time.monotonic())
                self.link.mav.command_long_send(self.target, 1, command, 0, *padded)

    def _acked(self, tag: str) -> bool:
        return any(e == f"{tag} ack 0" for _, e in self.events)

    def _drive(self, now: float) -> None:
        """Pull the triggers of the tests, each once, from the vehicle's state."""
        seq = {name: wp.seq for name, wp in self.plan.points.items()}
        for v in SPEEDS:
            tag = f"{v:g}"
            if self._current == seq[f"{tag}/S"]:
                self._once(f"{tag} radius S", lambda: self.set_param(self._radius_param, 2.0))
            if self._current == seq[f"{tag}/K0"]:
                self._once(f"{tag} radius K", lambda: self.set_param(self._radius_param, 2.0))
            if self._current == seq[f"{tag}/J0"]:
                self._once(f"{tag} radius J", lambda: self.set_param(self._radius_param, 0.5))
            self._stop_and_go(
                tag, "pause", (f"{tag}/A", f"{tag}/P"),
                (MAV.MAV_CMD_DO_PAUSE_CONTINUE, 0.0), (MAV.MAV_CMD_DO_PAUSE_CONTINUE, 1.0),
            )  # fmt: skip
            self._stop_and_go(
                tag, "brake", (f"{tag}/P", f"{tag}/B"),
                (MAV.MAV_CMD_DO_SET_MODE, 1.0, BRAKE_MODE),
                (MAV.MAV_CMD_DO_SET_MODE, 1.0, AUTO_MODE),
            )  # fmt: skip
            if (
                self._current == seq[f"{tag}/M1"]
                and self._flown(f"{tag}/B", f"{tag}/M1") >= TRIGGER_V * v
            ):
                self._once(f"{tag} jump", lambda tag=tag: self._jump(seq[f"{tag}/M2"], tag))

    def _stop_and_go(
        self,
        tag: str,
        test: str,
        leg: tuple[str, str],
        stop: tuple[float, ...],
        go: tuple[float, ...],
    ) -> None:
        name = f"{tag} {test}"
        v = float(tag)
        leg_is_current = self._current == self.plan[leg[1]].seq
        if leg_is_current and self._flown(*leg) >= TRIGGER_V * v:
            self._once(f"{name} stop", lambda: self._command(f"{name} stop", *stop))
        if self._acked(f"{name} stop") and self._standing(name, STAND_S):
            self._once(f"{name} go", lambda: self._command(f"{name} go", *go))

    def _jump(self, seq: int, tag: str) -> None:
        self.link.mav.mission_set_current_send(self.target, 1, seq)
        self.events.append((self.rows[-1][0], f"{tag} jump sent"))


def fly(connection: str, plan: Plan, wall_limit_s: float) -> Flight:
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    stamp = f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, load average {load}"
    started = time.monotonic()
    link = mavutil.mavlink_connection(connection, source_system=250)
    try:
        pilot = Pilot(link, plan)
        params = pilot.prepare()
        pilot.fly(wall_limit_s)
    finally:
        link.close()
    wall = time.monotonic() - started
    return Flight(np.array(pilot.rows), pilot.events, params, wall, stamp)


@dataclass
class Process:
    name: str
    popen: subprocess.Popen

    def stop(self) -> None:
        """Stop by process id: SIGTERM, then SIGKILL if it lingers."""
        if self.popen.poll() is None:
            os.kill(self.popen.pid, 15)
            try:
                self.popen.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.kill(self.popen.pid, 9)
                self.popen.wait(timeout=10)


def start_sitl(binary: Path, speedup: float, workdir: str) -> Process:
    defaults = binary.parents[3] / "Tools/autotest/default_params/copter.parm"
    home = ",".join(f"{v}" for v in HOME)
    popen = subprocess.Popen(
        [str(binary), "--model", "+", "--speedup", f"{speedup:g}", "--defaults", str(defaults),
         "-I0", "--sysid", "1", "--home", f"{home},0"],
        cwd=workdir, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    return Process("sitl", popen)


def start_mock(speedup: float) -> Process:
    home = ",".join(f"{v}" for v in HOME)
    popen = subprocess.Popen(
        [sys.executable, "-m", "sitl_mock", "--base-port", "5900", "--speedup", f"{speedup:g}",
         f"--home={home}", "--position-delay", "3", "--estimate-delay", "5"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    return Process("mock", popen)


# -- analysis ------------------------------------------------------------------------------


@dataclass
class Leg:
    """The track seen along a straight line from `a` to `b`."""

    t: np.ndarray
    s: np.ndarray  # along the line from a
    cross: np.ndarray  # signed distance from the line
    v: np.ndarray  # speed along the line
    speed: np.ndarray  # horizontal speed
    accel: np.ndarray  # along the line, from v smoothed over 0.2 s

    @classmethod
    def of(cls, track: np.ndarray, a: np.ndarray, b: np.ndarray) -> Leg:
        unit = (b - a) / np.linalg.norm(b - a)
        normal = np.array([unit[1], -unit[0]])
        rel = track[:, 1:3] - a
        vel = track[:, 4:6]
        v = vel @ unit
        smooth = np.convolve(v, np.ones(5) / 5, mode="same")
        accel = np.gradient(smooth, track[:, 0]) if len(v) > 1 else np.zeros_like(v)
        return cls(track[:, 0], rel @ unit, rel @ normal, v, np.hypot(*vel.T), accel)

    def index(self, t: float) -> int:
        return int(np.searchsorted(self.t, t))

    def first(self, mask: np.ndarray, start: int) -> int | None:
        hits = np.flatnonzero(mask[start:])
        return int(start + hits[0]) if len(hits) else None


def _nan_if_none(value: float | None) -> float:
    return math.nan if value is None else value


def accel_leg(flight: Flight, plan: Plan, v: float) -> dict[str, float]:
    tag = f"{v:g}"
    a, b = plan[f"{tag}/A"], plan[f"{tag}/P"]
    start, end = plan[f"{tag}/S"], a
    t0 = flight.when(f"current {a.seq}")
    t_end = flight.when(f"current {b.seq}", t0)
    leg = Leg.of(flight.track, start.at, end.at)
    i0, i_end = leg.index(t0), leg.index(t_end)
    out: dict[str, float] = {}
    for fraction in (0.5, 0.9, 0.95, 0.99):
        i = leg.first(leg.v >= fraction * v, i0)
        pct = f"{fraction * 100:g} %"
        out[f"time to {pct} of V (s)"] = leg.t[i] - t0 if i is not None else math.nan
        out[f"distance to {pct} of V (m)"] = leg.s[i] - leg.s[i0] if i is not None else math.nan
    middle = (leg.s >= 0.4 * ACCEL_LEG_M) & (leg.s <= 0.6 * ACCEL_LEG_M)
    cruise = float(np.median(leg.v[i0:i_end][middle[i0:i_end]]))
    out["cruise speed mid-leg (m/s)"] = cruise
    threshold = 0.98 * cruise
    fast = np.flatnonzero(leg.v[i0:i_end] >= threshold)
    i_begin = i0 + int(fast[-1])
    i_cruise = leg.first(leg.v >= threshold, i0) or i_begin
    out["peak acceleration (m/s²)"] = leg.accel[i0 : i_cruise + 1].max()
    i_stop = leg.first(leg.speed < STILL_M_S, i_begin) or i_end
    length = float(np.linalg.norm(end.at - start.at))
    out["slow-down (< 98 % of cruise) begins, to the waypoint (m)"] = length - leg.s[i_begin]
    out["slow-down time (s)"] = leg.t[i_stop] - leg.t[i_begin]
    out["slow-down distance (m)"] = leg.s[i_stop] - leg.s[i_begin]
    out["peak deceleration (m/s²)"] = -leg.accel[i_begin : i_stop + 1].min()
    out["overshoot past the waypoint (m)"] = leg.s[i_begin:i_end].max() - length
    out["standstill after start (s)"] = leg.t[i_stop] - t0
    return out


def stop_and_go(flight: Flight, plan: Plan, v: float, test: str) -> dict[str, float]:
    tag = f"{v:g}"
    names = {"pause": ("A", "P"), "brake": ("P", "B")}[test]
    a, b = plan[f"{tag}/{names[0]}"], plan[f"{tag}/{names[1]}"]
    leg = Leg.of(flight.track, a.at, b.at)
    t_stop = flight.when(f"{tag} {test} stop ack 0")
    t_go = flight.when(f"{tag} {test} go ack 0", t_stop)
    i_cmd = leg.index(t_stop)
    i_still = leg.first(leg.speed < STILL_M_S, i_cmd)
    out: dict[str, float] = {"speed at the command (m/s)": leg.speed[i_cmd]}
    if i_still is not None:
        out["time to standstill (s)"] = leg.t[i_still] - leg.t[i_cmd]
        out["distance to standstill (m)"] = leg.s[i_still] - leg.s[i_cmd]
        out["peak deceleration (m/s²)"] = -leg.accel[i_cmd : i_still + 1].min()
    if math.isfinite(t_go):
        i_go = leg.index(t_go)
        out["stood still for (s)"] = leg.t[i_go] - leg.t[i_still] if i_still else math.nan
        for fraction in (0.5, 0.9):
            i = leg.first(leg.v >= fraction * v, i_go)
            pct = f"{fraction * 100:g} %"
            out[f"go: time to {pct} of V (s)"] = leg.t[i] - leg.t[i_go] if i else math.nan
            out[f"go: distance to {pct} of V (m)"] = leg.s[i] - leg.s[i_go] if i else math.nan
        i_end = leg.index(flight.when(f"current {plan.following(b).seq}", t_go))
        window = slice(i_go, max(i_end, i_go + 1))
        out["go: top speed after (m/s)"] = leg.speed[window].max()
        out["go: largest cross-track (m)"] = np.abs(leg.cross[window]).max()
        out["go: backwards after go (m)"] = max(0.0, leg.s[i_go] - leg.s[window].min())
        length = float(np.linalg.norm(b.at - a.at))
        i_done = leg.first(leg.s >= length - 0.5, i_go)
        out["go: to the waypoint (s)"] = leg.t[i_done] - leg.t[i_go] if i_done else math.nan
    return out


def jump(flight: Flight, plan: Plan, v: float) -> dict[str, float]:
    tag = f"{v:g}"
    b, m1, m2 = plan[f"{tag}/B"], plan[f"{tag}/M1"], plan[f"{tag}/M2"]
    leg = Leg.of(flight.track, b.at, m2.at)
    t_cmd = flight.when(f"current {m2.seq}", flight.when(f"{tag} jump sent"))
    i_cmd = leg.index(t_cmd)
    i_ref = leg.first(leg.s >= JUMP_REF_V * v, i_cmd)
    out: dict[str, float] = {"speed at the jump (m/s)": leg.speed[i_cmd]}
    if i_ref is None:
        return out
    window = slice(i_cmd, i_ref + 1)
    i_min = i_cmd + int(np.argmin(leg.speed[window]))
    out["lowest speed after (m/s)"] = leg.speed[i_min]
    out["dip (m/s)"] = leg.speed[i_cmd] - leg.speed[i_min]
    out["lowest speed at (s after)"] = leg.t[i_min] - t_cmd
    slow = leg.speed[window] < 0.95 * v
    out["below 95 % of V for (s)"] = float(slow.sum()) / GPI_HZ
    i_back = leg.first(leg.speed >= 0.99 * v, i_min)
    out["back at 99 % of V (s after)"] = leg.t[i_back] - t_cmd if i_back else math.nan
    out["time lost to the 28 V m mark (s)"] = (
        leg.t[i_ref] - t_cmd - (leg.s[i_ref] - leg.s[i_cmd]) / v
    )
    out["M1 reported reached (1 = yes)"] = float(
        math.isfinite(flight.when(f"reached {m1.seq}", t_cmd - 1.0))
    )
    near = np.linalg.norm(flight.track[:, 1:3] - m2.at, axis=1) < 1.0
    i_far = leg.first(near, i_cmd)
    out["within 1 m of M2 after (s)"] = leg.t[i_far] - t_cmd if i_far else math.nan
    return out


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = b - a
    u = np.clip(((points - a) @ d) / (d @ d), 0.0, 1.0)
    return np.linalg.norm(points - (a + u[:, None] * d), axis=1)


def corners(flight: Flight, plan: Plan, v: float, letter: str) -> dict[str, float]:
    tag = f"{v:g}"
    wps = [plan[f"{tag}/{letter}{k}"] for k in range(len(TURNS_DEG) + 2)]
    track = flight.track
    t_start = flight.when(f"current {wps[1].seq}")
    out: dict[str, float] = {}
    t_after = t_start
    for k, turn in enumerate(TURNS_DEG, start=1):
        a, c, d = wps[k - 1].at, wps[k].at, wps[k + 1].at
        leg_in, leg_out = Leg.of(track, a, c), Leg.of(track, c, d)
        i_in = leg_in.first((leg_in.s >= LEG_M / 2) & (track[:, 0] >= t_after), 0)
        if i_in is None:
            break
        i_out = leg_out.first(leg_out.s >= LEG_M / 2, i_in)
        if i_out is None:
            break
        window = slice(i_in, i_out + 1)
        points = track[window, 1:3]
        cross = np.minimum(_segment_distance(points, a, c), _segment_distance(points, c, d))
        name = f"{abs(turn):g}°"
        out[f"{name} speed at mid-leg in (m/s)"] = leg_in.speed[i_in]
        out[f"{name} lowest speed (m/s)"] = leg_in.speed[window].min()
        out[f"{name} closest to the waypoint (m)"] = np.linalg.norm(points - c, axis=1).min()
        out[f"{name} largest cross-track (m)"] = cross.max()
        out[f"{name} time lost, mid to mid (s)"] = track[i_out, 0] - track[i_in, 0] - LEG_M / v
        t_after = track[i_in, 0]
    end = wps[-1]
    last = Leg.of(track, wps[-2].at, end.at)
    i_stop = last.first((last.s >= LEG_M - 1.0) & (last.speed < STILL_M_S), last.index(t_start))
    if i_stop is not None:
        total = len(wps) - 1
        out["whole chain, start to standstill (s)"] = track[i_stop, 0] - t_start
        out["whole chain at V (s)"] = total * LEG_M / v
    return out


def params_table(flights: dict[str, Flight]) -> list[str]:
    names = list(flights)
    lines = ["| parameter | " + " | ".join(names) + " |", "| --- |" + " ---: |" * len(names)]
    for param in PARAMS:
        values = [flights[n].params.get(param) for n in names]
        if all(value is None for value in values):
            continue
        cells = ["-" if value is None else f"{value:g}" for value in values]
        lines.append(f"| {param} | " + " | ".join(cells) + " |")
    absent = [p for p in PARAMS if all(flights[n].params.get(p) is None for n in names)]
    lines.append("")
    lines.append("Absent on every vehicle: " + ", ".join(absent))
    return lines


def _cell(value: float) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.2f}"


def comparison(
    title: str, rows: dict[tuple[str, float], dict[str, float]], names: list[str]
) -> list[str]:
    """One table: the measures down, (vehicle, speed) across; a mock cell off SITL by
    more than FLAG_REL and FLAG_ABS is starred."""
    columns = [(name, v) for v in SPEEDS for name in names]
    measures: list[str] = []
    for column in columns:
        for measure in rows.get(column, {}):
            if measure not in measures:
                measures.append(measure)
    header = " | ".join(f"{name} {v:g} m/s" for name, v in columns)
    lines = [f"### {title}", "", f"| measure | {header} |", "| --- |" + " ---: |" * len(columns)]
    for measure in measures:
        cells = []
        for name, v in columns:
            value = rows.get((name, v), {}).get(measure, math.nan)
            text = _cell(value)
            reference = rows.get((names[0], v), {}).get(measure, math.nan)
            if name != names[0] and math.isfinite(value) and math.isfinite(reference):
                off = abs(value - reference)
                if off > FLAG_REL * abs(reference) and off > FLAG_ABS:
                    text += " *"
            cells.append(text)
        lines.append(f"| {measure} | " + " | ".join(cells) + " |")
    return [*lines, ""]


def report(flights: dict[str, Flight], plan: Plan) -> Iterator[str]:
    names = list(flights)
    yield "# Cruise kinematics: ArduCopter SITL against sitl_mock"
    yield ""
    for name, flight in flights.items():
        yield f"- {name}: flown from {flight.started or '?'}"
    yield (
        f"- * marks a mock value off SITL's by more than {FLAG_REL:.0%} and more than"
        f" {FLAG_ABS:g} (m, s, m/s or m/s²); times and distances in the vehicle's own time"
    )
    yield ""
    tests: list[tuple[str, Callable[[Flight, float], dict[str, float]]]] = [
        ("1. Acceleration, cruise and stop (150 m leg, 2 s hold)",
         lambda f, v: accel_leg(f, plan, v)),
        ("2a. DO_PAUSE_CONTINUE 0 at 10 V m, 1 after 5 s standing",
         lambda f, v: stop_and_go(f, plan, v, "pause")),
        ("2b. BRAKE at 10 V m, AUTO after 5 s standing",
         lambda f, v: stop_and_go(f, plan, v, "brake")),
        ("3a. Corners, WP_RADIUS_M 2 m (60 m legs, no hold)",
         lambda f, v: corners(f, plan, v, "K")),
        ("3b. Corners, WP_RADIUS_M 0.5 m", lambda f, v: corners(f, plan, v, "J")),
        ("4. MISSION_SET_CURRENT to the next waypoint at 10 V m (same line)",
         lambda f, v: jump(f, plan, v)),
    ]  # fmt: skip
    for title, measure in tests:
        rows: dict[tuple[str, float], dict[str, float]] = {}
        for name, flight in flights.items():
            for v in SPEEDS:
                try:
                    rows[(name, v)] = measure(flight, v)
                except (ValueError, IndexError, TypeError) as exc:
                    rows[(name, v)] = {}
                    yield f"({title}: {name} at {v:g} m/s not measurable: {exc!r})"
        yield from comparison(title, rows, names)
    yield "### 5. Parameters (PARAM_REQUEST_READ)"
    yield ""
    yield from params_table(flights)
    yield ""
    yield "### Events after each stop, go and jump (vehicle time, s)"
    yield ""
    for name, flight in flights.items():
        marks = [t for t, e in flight.events if e.endswith(" sent")]
        for t_mark, t_next in zip(marks, [*marks[1:], math.inf], strict=True):
            nearby = [
                f"{t:.2f} {e}"
                for t, e in flight.events
                if t_mark - 0.1 <= t < min(t_next, t_mark + 40.0) and not e.startswith("param ")
            ]
            yield f"- {name}: " + "; ".join(nearby)
    yield ""
    for name, flight in flights.items():
        span = flight.track[-1, 0] - flight.track[0, 0] if len(flight.track) else 0.0
        yield f"{name}: {span:.0f} s of vehicle time flown in {flight.wall_s:.0f} s of wall time"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sitl", type=Path, help="ArduCopter SITL binary")
    parser.add_argument("--speedup", type=float, default=2.0, help="SITL's speed-up")
    parser.add_argument("--mock-speedup", type=float, default=4.0)
    parser.add_argument("--only", choices=("sitl", "mock"))
    parser.add_argument("--tracks", type=Path, help="keep the raw tracks here as JSON")
    parser.add_argument("--from-tracks", type=Path, help="analyse tracks kept by --tracks")
    parser.add_argument("--wall-limit", type=float, default=1500.0, help="s per flight")
    parser.add_argument("--output", type=Path, default=Path("bench/results/kinematics_vs_sitl.txt"))
    args = parser.parse_args()
    plan = mission()
    flights: dict[str, Flight] = {}
    if args.from_tracks:
        for name in ("ArduCopter SITL", "sitl_mock"):
            path = args.from_tracks / f"{name.replace(' ', '_')}.json"
            if path.exists():
                flights[name] = Flight.from_json(json.loads(path.read_text()))
    else:
        flights = fly_both(args, plan)
    lines = list(report(flights, plan))
    text = "\n".join(lines) + "\n"
    print(text)
    if args.output:
        args.output.parent.mkdir(parents=True, exist_ok=True)
        args.output.write_text(text)
    return 0


def fly_both(args: argparse.Namespace, plan: Plan) -> dict[str, Flight]:
    flights: dict[str, Flight] = {}
    if args.only != "mock":
        if args.sitl is None:
            raise SystemExit("--sitl is needed (or --only mock)")
        with tempfile.TemporaryDirectory() as workdir:
            sitl = start_sitl(args.sitl, args.speedup, workdir)
            try:
                time.sleep(2.0)  # listening
                flights["ArduCopter SITL"] = fly("tcp:127.0.0.1:5760", plan, args.wall_limit)
            finally:
                sitl.stop()
        _keep(args.tracks, "ArduCopter SITL", flights)
    if args.only != "sitl":
        mock = start_mock(args.mock_speedup)
        try:
            time.sleep(2.0)
            flights["sitl_mock"] = fly("tcp:127.0.0.1:5900", plan, args.wall_limit)
        finally:
            mock.stop()
        _keep(args.tracks, "sitl_mock", flights)
    return flights


def _keep(directory: Path | None, name: str, flights: dict[str, Flight]) -> None:
    if directory is not None:
        directory.mkdir(parents=True, exist_ok=True)
        path = directory / f"{name.replace(' ', '_')}.json"
        path.write_text(json.dumps(flights[name].to_json()))


if __name__ == "__main__":
    raise SystemExit(main())
