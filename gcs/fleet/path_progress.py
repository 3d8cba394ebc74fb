"""How far along its path a vehicle is, in metres, from the positions it reports.

The passing order speaks of places along each path (`gcs.mission.passing_order`); a
vehicle reports latitude and longitude. Each new position is put in the grid's metres
and projected onto the path near where the vehicle was last: never behind it by more
than a little (a vehicle rounding a corner within its waypoint radius projects onto
either leg; a step backwards is noise), and never further ahead than it can have flown
since, at its top speed (a path that comes back near itself must not make a vehicle
look far along it).
Its speed along the path and its acceleration come from the reports' own clock
(time_boot_ms), so a slow link or a loaded machine does not make a vehicle look slower
than it is.
"""

from __future__ import annotations

import numpy as np

from gcs.mavlink.vehicle_state import VehicleState
from gcs.mission.geodesy import GridFrame
from gcs.mission.passing_order import PlannedPath

LOOK_AHEAD_M = 3.0
"""How far beyond its last place a new position is looked for, besides twice what it can
have flown since the last one at its speed."""
BACKWARDS_M = 0.5
"""How far back a projection may fall before it is taken as noise."""
ACCEL_SMOOTHING = 0.5


class PathProgress:
    """One vehicle's distance along its path, speed and acceleration."""

    def __init__(self, path: PlannedPath, frame: GridFrame, top_speed_m_s: float = 0.0) -> None:
        """`top_speed_m_s`: the fastest the vehicle flies (its cruise)."""
        self._frame = frame
        self._top_speed = top_speed_m_s
        self.speed = 0.0
        self.accel = 0.0
        self.s = 0.0
        self.heard_at: float | None = None  # loop time the latest position was heard
        self._time_ms: int | None = None
        self.restart(path)

    def update(self, state: VehicleState) -> bool:
        """Take the vehicle's latest position, if new; True if it was."""
        position = state.position
        if position is None or position.time_boot_ms == self._time_ms:
            return False
        here = self._frame.to_metres(position.lat, position.lon)
        speed = float(np.hypot(*state.velocity_n_e_m_s))
        if self._time_ms is not None and position.time_boot_ms > self._time_ms:
            dt = (position.time_boot_ms - self._time_ms) / 1000.0
            sample = (speed - self.speed) / dt
            self.accel += ACCEL_SMOOTHING * (sample - self.accel)
        reach = LOOK_AHEAD_M
        if self._time_ms is not None:
            elapsed = max(0.0, (position.time_boot_ms - self._time_ms) / 1000.0)
            reach += max(2.0 * max(speed, self.speed), self._top_speed) * elapsed
        self._time_ms = position.time_boot_ms
        self.heard_at = state.position_heard
        self.speed = speed
        self.s = max(self.s, self._project(here, self.s - BACKWARDS_M, self.s + reach))
        return True

    def find(self, state: VehicleState, lo_m: float, hi_m: float) -> None:
        """Place a vehicle found on its way (a flight followed again after a restart or a
        takeover): its position projected onto the path between `lo_m` and `hi_m`, the
        places of the last item it passed and of the one it flies to (a path that comes
        back near itself must not place it on the wrong pass)."""
        self.s = lo_m
        position = state.position
        if position is None:
            return
        here = self._frame.to_metres(position.lat, position.lon)
        self.s = max(lo_m, self._project(here, lo_m - BACKWARDS_M, hi_m + LOOK_AHEAD_M))
        self.speed = float(np.hypot(*state.velocity_n_e_m_s))
        self._time_ms = position.time_boot_ms
        self.heard_at = state.position_heard

    def restart(
        self, path: PlannedPath, state: VehicleState | None = None, within_m: float = 0.0
    ) -> None:
        """A path from here on (a live replan): distances count again from its start, and
        the vehicle (`state`) is found on it up to `within_m` along. It flew on while the
        replan was made and uploaded, from the place the new path starts at; looked for
        only a few metres on, it was lost for good (fuzzed flight 3034: 5 m on, and the
        order held it at the start while it flew 50 m into another's way)."""
        self.path = path
        self._s = path.s
        self._a = path.xy[:-1]
        self._d = np.diff(path.xy, axis=0)
        self._len2 = np.maximum(np.einsum("ij,ij->i", self._d, self._d), 1e-12)
        self.s = 0.0
        if state is not None:
            self.find(state, 0.0, within_m)

    def carry_on(self, path: PlannedPath) -> None:
        """The rest of the same path (a live replan kept this vehicle's): the vehicle is
        where it was, counted from where the rest begins. Found on it anew, it could be
        put on the wrong pass of a path that comes back over itself (fuzzed flight 3499:
        at 0.7 m of a rest it was 10 m along, and left there while it flew 20 m on)."""
        s = self.s - (path.skipped_m - self.path.skipped_m)
        self.restart(path)
        self.s = min(max(s, 0.0), path.length)

    def _project(self, here: np.ndarray, lo: float, hi: float) -> float:
        """The distance along the path of the point nearest `here`, between `lo` and `hi`
        metres along it (the last place if none is)."""
        legs = np.flatnonzero((self._s[1:] >= lo) & (self._s[:-1] <= hi))
        if len(legs) == 0:
            return self.s
        rel = here - self._a[legs]
        f = np.clip(np.einsum("ij,ij->i", rel, self._d[legs]) / self._len2[legs], 0.0, 1.0)
        foot = self._a[legs] + f[:, None] * self._d[legs]
        along = self._s[legs] + f * np.sqrt(self._len2[legs])
        inside = (along >= lo) & (along <= hi)
        if not inside.any():
            return self.s
        miss = np.where(inside, np.hypot(*(here - foot).T), np.inf)
        return float(along[int(np.argmin(miss))])
