"""An independent observer of real autopilots: their own positions, on a second port.

Each ArduCopter SITL instance serves more than one TCP port (5760 + 10·i for the ground
station, 5762 + 10·i beside it). The observer connects there with plain pymavlink in a
thread, asks for positions at 10 Hz, and records what each autopilot reports, so that
the separation flown is measured by something that shares no code with the ground
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


@dataclass
class Track:
    t: list[float] = field(default_factory=list)  # when it arrived (one clock for all)
    lat: list[float] = field(default_factory=list)
    lon: list[float] = field(default_factory=list)
    alt: list[float] = field(default_factory=list)  # metres above home

    def arrays(self) -> tuple[np.ndarray, ...]:
        """t, lat, lon, alt of the samples complete now: the watching thread may be
        between two appends while the flight's figures are taken."""
        n = min(len(self.t), len(self.lat), len(self.lon), len(self.alt))
        return tuple(np.array(column[:n]) for column in (self.t, self.lat, self.lon, self.alt))


class Observer:
    def __init__(self, ports: list[int]) -> None:
        self.tracks = {k: Track() for k in range(len(ports))}
        self._ports = ports
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
            message_id = mavutil.mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
            conn.mav.command_long_send(
                conn.target_system, conn.target_component,
                mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                message_id, 1e6 / RATE_HZ, 0, 0, 0, 0, 0,
            )  # fmt: skip
            track = self.tracks[k]
            while not self._stop.is_set():
                msg = conn.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=0.5)
                if msg is None or (msg.lat == 0 and msg.lon == 0):
                    continue
                track.t.append(time.monotonic())
                track.lat.append(msg.lat / 1e7)
                track.lon.append(msg.lon / 1e7)
                track.alt.append(msg.relative_alt / 1000.0)
        finally:
            conn.close()

    def min_separation(self, airborne_m: float = 1.0) -> float | None:
        """Closest horizontal approach of two airborne vehicles, on a common 10 Hz clock:
        the observer's own, as reports arrive over loopback (the instances' boot clocks
        started at different moments)."""
        best: float | None = None
        tracks = [track.arrays() for track in self.tracks.values()]
        for (at, alat, alon, aalt), (bt, blat, blon, balt) in itertools.combinations(tracks, 2):
            if len(at) < 2 or len(bt) < 2:
                continue
            start, end = max(at[0], bt[0]), min(at[-1], bt[-1])
            if end <= start:
                continue
            grid = np.arange(start, end, 1.0 / RATE_HZ)
            lat0 = math.radians(alat[0])
            north = (np.interp(grid, at, alat) - np.interp(grid, bt, blat)) * 111_320.0
            east = (np.interp(grid, at, alon) - np.interp(grid, bt, blon)) * 111_320.0
            east *= math.cos(lat0)
            up = (np.interp(grid, at, aalt) > airborne_m) & (np.interp(grid, bt, balt) > airborne_m)
            if up.any():
                closest = float(np.min(np.hypot(north, east)[up]))
                best = closest if best is None else min(best, closest)
        return best


@contextmanager
def observing(ports: list[int]) -> Iterator[Observer]:
    observer = Observer([p + OBSERVER_PORT_OFFSET for p in ports])
    for thread in observer._threads:
        thread.start()
    try:
        yield observer
    finally:
        observer._stop.set()
        for thread in observer._threads:
            thread.join(timeout=5)
