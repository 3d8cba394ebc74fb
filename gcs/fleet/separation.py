"""The separation actually flown, from the positions the vehicles report.

Each position report is compared with the latest report of every other airborne
vehicle, moved forward by that vehicle's velocity over the time since it was heard
(on the vehicles' clock, which a simulator may run faster than the wall clock), so
that the two positions describe the same moment.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable
from dataclasses import dataclass

from gcs.mavlink.link import VehicleLink
from gcs.mission.geodesy import TangentPlane

MAX_EXTRAPOLATION_S = 1.0
"""Vehicle seconds a report may be carried forward; beyond that (a link outage) it says
nothing of where the vehicle is now."""


@dataclass
class _Fix:
    east: float
    north: float
    v_east: float
    v_north: float
    wall: float
    boot_ms: int
    rate: float  # vehicle seconds per wall second


@dataclass(frozen=True)
class Closest:
    distance_m: float
    pair: tuple[str, str]
    wall_time: float


class SeparationTracker:
    """Minimum horizontal distance between airborne vehicles over a flight."""

    def __init__(self, lat0: float, lon0: float) -> None:
        self._plane = TangentPlane(lat0, lon0)
        self._fixes: dict[str, _Fix] = {}
        self._first: dict[str, tuple[float, int]] = {}
        self.closest: Closest | None = None

    def update(
        self,
        uav_id: str,
        lat: float,
        lon: float,
        velocity_n_e: tuple[float, float],
        airborne: bool,
        wall: float,
        boot_ms: int,
    ) -> None:
        if not airborne:
            self._fixes.pop(uav_id, None)
            return
        east, north = self._plane.east_north(lat, lon)
        fix = _Fix(
            east,
            north,
            velocity_n_e[1],
            velocity_n_e[0],
            wall,
            boot_ms,
            self._clock_rate(uav_id, wall, boot_ms),
        )
        self._fixes[uav_id] = fix
        for other_id, other in self._fixes.items():
            if other_id != uav_id:
                self._compare(uav_id, fix, other_id, other)

    def _clock_rate(self, uav_id: str, wall: float, boot_ms: int) -> float:
        first_wall, first_boot = self._first.setdefault(uav_id, (wall, boot_ms))
        if wall - first_wall < 1.0 or boot_ms < first_boot:
            return 1.0
        return (boot_ms - first_boot) / 1000.0 / (wall - first_wall)

    def _compare(self, uav_id: str, fix: _Fix, other_id: str, other: _Fix) -> None:
        dt = (fix.wall - other.wall) * other.rate
        if abs(dt) > MAX_EXTRAPOLATION_S:
            return  # the other's last report is too old to say where it is now
        east = other.east + other.v_east * dt
        north = other.north + other.v_north * dt
        distance = math.hypot(fix.east - east, fix.north - north)
        if self.closest is None or distance < self.closest.distance_m:
            first, second = sorted((uav_id, other_id))
            self.closest = Closest(distance, (first, second), fix.wall)


class SeparationWatch:
    """Feeds every member's position reports to one tracker, until `close`."""

    def __init__(self, tracker: SeparationTracker) -> None:
        self.tracker = tracker
        self._stops: list[Callable[[], None]] = []

    def watch(self, uav_id: str, link: VehicleLink) -> None:
        loop = asyncio.get_running_loop()

        def on_position(msg: object) -> None:
            state = link.state
            if state.position is not None:
                self.tracker.update(
                    uav_id,
                    state.position.lat,
                    state.position.lon,
                    state.velocity_n_e_m_s,
                    state.airborne,
                    loop.time(),
                    state.time_boot_ms,
                )

        self._stops.append(link.on_message(on_position, ["GLOBAL_POSITION_INT"]))

    def close(self) -> None:
        for stop in self._stops:
            stop()
        self._stops.clear()
