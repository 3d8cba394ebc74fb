"""An independent observer of real autopilots: their own positions, on a second port.

Each ArduCopter SITL instance serves more than one TCP port (5760 + 10·i for the ground
station, 5762 + 10·i beside it). The observer connects there with plain pymavlink in a
thread, asks for positions and the mission item flown at 10 Hz, and records what each
autopilot reports, so that the separation flown, where each vehicle came down and how
long the mission took are measured by something that shares no code with the ground
station.
"""

from __future__ import annotations

import itertools
import math
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
from pymavlink import mavutil

OBSERVER_PORT_OFFSET = 2
RATE_HZ = 10
M_PER_DEGREE = 111_320.0  # of latitude; of longitude times cos(latitude)


@dataclass(frozen=True)
class Mark:
    """A vehicle's reported position at a moment of its own clock."""

    boot_s: float
    lat: float
    lon: float
    alt: float


@dataclass
class Track:
    t: list[float] = field(default_factory=list)  # when it arrived (one clock for all)
    lat: list[float] = field(default_factory=list)
    lon: list[float] = field(default_factory=list)
    alt: list[float] = field(default_factory=list)  # metres above home
    boot_s: list[float] = field(default_factory=list)  # the autopilot's own clock
    speed: list[float] = field(default_factory=list)  # its horizontal ground speed, m/s
    armed: bool | None = None  # as its last HEARTBEAT said
    mode: str | None = None  # likewise
    seq: list[tuple[float, int]] = field(default_factory=list)  # (boot_s, item) on a change
    params: dict[str, float] = field(default_factory=dict)  # those asked for, as answered

    def arrays(self) -> tuple[np.ndarray, ...]:
        """t, lat, lon, alt, boot_s of the samples complete now: the watching thread may
        be between two appends while the flight's figures are taken."""
        columns = (self.t, self.lat, self.lon, self.alt, self.boot_s)
        n = min(len(column) for column in columns)
        return tuple(np.array(column[:n]) for column in columns)

    def latest(self) -> Mark:
        _, lat, lon, alt, boot_s = self.arrays()
        assert len(boot_s), "a vehicle has not reported its position yet"
        return Mark(float(boot_s[-1]), float(lat[-1]), float(lon[-1]), float(alt[-1]))


class Observer:
    def __init__(self, ports: list[int], params: tuple[str, ...] = ()) -> None:
        self.tracks = {k: Track() for k in range(len(ports))}
        self._ports = ports
        self._params = params
        self._stop = threading.Event()
        self._threads = [
            threading.Thread(target=self._watch, args=(k, port), daemon=True)
            for k, port in enumerate(ports)
        ]

    def _watch(self, k: int, port: int) -> None:
        conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=254)
        try:
            if conn.wait_heartbeat(timeout=30) is None:
                return
            for message_id in (
                mavutil.mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                mavutil.mavlink.MAVLINK_MSG_ID_MISSION_CURRENT,
            ):
                conn.mav.command_long_send(
                    conn.target_system, conn.target_component,
                    mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                    message_id, 1e6 / RATE_HZ, 0, 0, 0, 0, 0,
                )  # fmt: skip
            for name in self._params:
                conn.mav.param_request_read_send(
                    conn.target_system, conn.target_component, name.encode(), -1
                )
            track = self.tracks[k]
            wanted = ["GLOBAL_POSITION_INT", "HEARTBEAT", "MISSION_CURRENT", "PARAM_VALUE"]
            while not self._stop.is_set():
                msg = conn.recv_match(type=wanted, blocking=True, timeout=0.5)
                if msg is None or msg.get_srcSystem() != conn.target_system:
                    continue
                kind = msg.get_type()
                if kind == "HEARTBEAT":
                    track.armed = bool(msg.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
                    track.mode = mavutil.mode_string_v10(msg)
                elif kind == "MISSION_CURRENT":
                    if (not track.seq or track.seq[-1][1] != msg.seq) and track.boot_s:
                        track.seq.append((track.boot_s[-1], int(msg.seq)))
                elif kind == "PARAM_VALUE":
                    if msg.param_id in self._params:
                        track.params[msg.param_id] = float(msg.param_value)
                elif msg.lat != 0 or msg.lon != 0:
                    track.t.append(time.monotonic())
                    track.lat.append(msg.lat / 1e7)
                    track.lon.append(msg.lon / 1e7)
                    track.alt.append(msg.relative_alt / 1000.0)
                    track.boot_s.append(msg.time_boot_ms / 1000.0)
                    track.speed.append(math.hypot(msg.vx, msg.vy) / 100.0)
        finally:
            conn.close()

    def min_separation(self, airborne_m: float = 1.0, since: float = -math.inf) -> float | None:
        """Closest horizontal approach of two airborne vehicles, on a common 10 Hz clock:
        the observer's own (`time.monotonic()`, from `since` on), as reports arrive over
        loopback (the instances' boot clocks started at different moments)."""
        best: float | None = None
        tracks = [track.arrays() for track in self.tracks.values()]
        for (at, alat, alon, aalt, _), (bt, blat, blon, balt, _) in itertools.combinations(
            tracks, 2
        ):
            if len(at) < 2 or len(bt) < 2:
                continue
            start, end = max(at[0], bt[0], since), min(at[-1], bt[-1])
            if end <= start:
                continue
            grid = np.arange(start, end, 1.0 / RATE_HZ)
            lat0 = math.radians(alat[0])
            north = (np.interp(grid, at, alat) - np.interp(grid, bt, blat)) * M_PER_DEGREE
            east = (np.interp(grid, at, alon) - np.interp(grid, bt, blon)) * M_PER_DEGREE
            east *= math.cos(lat0)
            up = (np.interp(grid, at, aalt) > airborne_m) & (np.interp(grid, bt, balt) > airborne_m)
            if up.any():
                closest = float(np.min(np.hypot(north, east)[up]))
                best = closest if best is None else min(best, closest)
        return best

    def started_at(self, k: int, takeoff_seq: int = 1) -> float | None:
        """Vehicle k's own clock when its mission went past the take-off item (the
        ground station's common start: AUTO over its start at altitude)."""
        return next((t for t, seq in self.tracks[k].seq if seq > takeoff_seq), None)

    def arrived_at(
        self, k: int, lat: float, lon: float, within_m: float, since: float
    ) -> float | None:
        """Vehicle k's own clock when it first reported itself within `within_m` of a
        place (horizontally) at or after `since`."""
        _, lats, lons, _, boot_s = self.tracks[k].arrays()
        after = boot_s >= since
        near = metres_apart(lats[after], lons[after], Mark(0.0, lat, lon, 0.0)) <= within_m
        return float(boot_s[after][near][0]) if near.any() else None

    def latest(self) -> list[Mark]:
        """Where and when (by its own clock) each vehicle last reported itself."""
        return [track.latest() for track in self.tracks.values()]

    def speeds(self) -> list[float]:
        """Each vehicle's last reported horizontal ground speed, m/s."""
        return [track.speed[-1] if track.speed else 0.0 for track in self.tracks.values()]

    def seconds_since(self, marks: list[Mark]) -> float:
        """The least time any vehicle's own clock has run since its mark."""
        return min(now.boot_s - then.boot_s for now, then in zip(self.latest(), marks, strict=True))

    def moved_since(self, marks: list[Mark]) -> list[float]:
        """How far each vehicle got from its mark (horizontally, m) at any report since."""
        moved = []
        for track, mark in zip(self.tracks.values(), marks, strict=True):
            _, lat, lon, _, boot_s = track.arrays()
            since = boot_s >= mark.boot_s
            moved.append(float(np.max(metres_apart(lat[since], lon[since], mark), initial=0.0)))
        return moved


def metres_apart(lat: np.ndarray, lon: np.ndarray, mark: Mark) -> np.ndarray:
    """Horizontal distances from a mark (equirectangular: the vehicles are metres apart)."""
    north = (lat - mark.lat) * M_PER_DEGREE
    east = (lon - mark.lon) * M_PER_DEGREE * math.cos(math.radians(mark.lat))
    return np.asarray(np.hypot(north, east))


@contextmanager
def observing(ports: list[int], params: tuple[str, ...] = ()) -> Iterator[Observer]:
    observer = Observer([p + OBSERVER_PORT_OFFSET for p in ports], params)
    for thread in observer._threads:
        thread.start()
    try:
        yield observer
    finally:
        observer._stop.set()
        for thread in observer._threads:
            thread.join(timeout=5)
