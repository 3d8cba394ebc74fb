"""A UAV's flight: `[t, x, y]` points, piecewise linear in time, airborne until the last."""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

DIGITS = 6  # decimals of a stored plan's times and positions


@dataclass(frozen=True)
class Trajectory:
    points: NDArray[np.float64]  # (k, 3): t, x, y with t non-decreasing

    @classmethod
    def from_waypoints(
        cls,
        waypoints: ArrayLike,
        speed: float,
        waits: Sequence[float] | NDArray[np.float64] | None = None,
        start_time: float = 0.0,
    ) -> Trajectory:
        """Fly through `waypoints` at `speed`, hovering `waits[k]` seconds at waypoint k."""
        xy = np.asarray(waypoints, dtype=float).reshape(-1, 2)
        hold = np.zeros(len(xy)) if waits is None else np.asarray(waits, dtype=float)
        legs = np.hypot(*np.diff(xy, axis=0).T) / speed
        rows = []
        t = start_time
        for k, (x, y) in enumerate(xy):
            if k:
                t += legs[k - 1]
            rows.append((t, x, y))
            if hold[k] > 0:
                t += hold[k]
                rows.append((t, x, y))
        return cls(np.array(rows))

    @property
    def times(self) -> NDArray[np.float64]:
        return self.points[:, 0]

    @property
    def xy(self) -> NDArray[np.float64]:
        return self.points[:, 1:]

    @property
    def end_time(self) -> float:
        return float(self.points[-1, 0])

    @property
    def end(self) -> NDArray[np.float64]:
        return self.points[-1, 1:]

    @functools.cached_property
    def length(self) -> float:
        """Kept once computed (the points are never changed): the safe start sums the
        fleet's costs after every step, 250 flights each time at 250 UAVs."""
        return float(np.hypot(*np.diff(self.xy, axis=0).T).sum())

    def max_speed(self) -> float:
        dt = np.diff(self.times)
        dist = np.hypot(*np.diff(self.xy, axis=0).T)
        moving = dist > 1e-12
        if not moving.any():
            return 0.0
        with np.errstate(divide="ignore"):
            return float(np.max(dist[moving] / dt[moving]))

    def at(self, times: ArrayLike) -> NDArray[np.float64]:
        """Positions at `times`, shape (n, 2); NaN before take-off at 0 or after landing."""
        t = np.asarray(times, dtype=float)
        points, nan = self.points, math.nan  # interp's left and right: NaN outside the flight
        out = np.empty((t.size, 2))
        out[:, 0] = np.interp(t, points[:, 0], points[:, 1], nan, nan).ravel()
        out[:, 1] = np.interp(t, points[:, 0], points[:, 2], nan, nan).ravel()
        return out

    def between(self, start: float, end: float) -> Trajectory | None:
        """The part flown during [start, end], its ends interpolated (None if not airborne
        then): what is left of a flight after `now`, or what meets an object's time window."""
        lo, hi = max(start, float(self.times[0])), min(end, self.end_time)
        if lo > hi:
            return None
        inner = self.points[(self.times > lo) & (self.times < hi)]
        ends = np.column_stack([[lo, hi], self.at([lo, hi])])
        return Trajectory(np.vstack([ends[:1], inner, ends[1:]]))

    def quantised(self, speed: float, digits: int = DIGITS) -> Trajectory:
        """This flight as `to_json` writes it (`digits` decimals), with each time moved up
        to the grid so that no rounded leg is faster than `speed`: a plan checked in this
        form is the plan that is stored and flown. Hovers keep their duration."""
        scale = 10.0**digits
        xy = np.round(self.xy, digits)
        legs = np.hypot(*np.diff(xy, axis=0).T)
        spans = np.maximum(np.diff(self.times), legs / speed)
        times = [round(float(self.times[0]), digits)]
        for span in spans:
            times.append(math.ceil((times[-1] + float(span)) * scale - 1e-6) / scale)
        return Trajectory(np.column_stack([times, xy]))

    def to_json(self) -> list[list[float]]:
        return [
            [round(float(t), 6), round(float(x), 6), round(float(y), 6)] for t, x, y in self.points
        ]


def merge_collinear(cells: ArrayLike) -> NDArray[np.float64]:
    """Keep only the turning points of a polyline (first and last included)."""
    xy = np.asarray(cells, dtype=float).reshape(-1, 2)
    if len(xy) <= 2:
        return xy
    d1, d2 = xy[1:-1] - xy[:-2], xy[2:] - xy[1:-1]
    cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    same_way = np.einsum("ij,ij->i", d1, d2) > 0
    keep = np.concatenate([[True], ~((np.abs(cross) < 1e-9) & same_way), [True]])
    turns: NDArray[np.float64] = xy[keep]
    return turns
