"""Grid cells to WGS84 latitude and longitude and back, through pymap3d's local ENU frame.

The planner's convention (docs/planner.md): cell (x, y) lies x · cell_size_m metres east
and y · cell_size_m metres north of the scenario's origin, which is cell (0, 0) on the
ground at `origin.alt_m` metres AMSL. The grid is the origin's east-north tangent plane,
so `to_geodetic` and `to_cells` invert each other exactly (up to floating point) and
work on scalars or numpy arrays alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymap3d
from numpy.typing import ArrayLike, NDArray

from planner.model.scenario import Scenario

Floats = NDArray[np.float64]
MAX_EXTENT_M = 100_000.0
"""A grid is flown as one tangent plane, whose east-north metres part from the ground's
by about d^3 / 6R^2: 4 m at 100 km across, and growing with the cube beyond."""


@dataclass(frozen=True, slots=True)
class GridFrame:
    """Where a scenario's grid lies on the Earth."""

    lat0: float  # cell (0, 0), degrees
    lon0: float
    alt0: float  # ground altitude at the origin, metres AMSL
    cell_size_m: float

    @classmethod
    def of(cls, scenario: Scenario) -> GridFrame:
        """The scenario's frame; a scenario without an origin can be planned but not flown."""
        if scenario.origin is None:
            raise ValueError(f"scenario {scenario.name!r} has no origin: it cannot be flown")
        extent = max(scenario.grid.width, scenario.grid.height) * scenario.grid.cell_size_m
        if extent > MAX_EXTENT_M:
            raise ValueError(
                f"scenario {scenario.name!r} spans {extent / 1000:.0f} km: a flat grid is "
                f"flown only up to {MAX_EXTENT_M / 1000:.0f} km across"
            )
        o = scenario.origin
        return cls(o.lat, o.lon, o.alt_m, scenario.grid.cell_size_m)

    def to_geodetic(self, x: ArrayLike, y: ArrayLike) -> tuple[Floats, Floats]:
        """Latitude and longitude in degrees of grid positions (cells, fractional allowed)."""
        east = np.asarray(x, dtype=float) * self.cell_size_m
        north = np.asarray(y, dtype=float) * self.cell_size_m
        lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, self.lat0, self.lon0, self.alt0)
        return np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)

    def to_cells(self, lat: ArrayLike, lon: ArrayLike) -> tuple[Floats, Floats]:
        """Grid position (x, y) in cells of latitudes and longitudes, e.g. from telemetry.

        The point is taken at the origin's altitude: at grid scale (kilometres) the height
        moves the east-north position by well under a millimetre per kilometre climbed.
        """
        east, north, _ = pymap3d.geodetic2enu(
            np.asarray(lat, dtype=float),
            np.asarray(lon, dtype=float),
            self.alt0,
            self.lat0,
            self.lon0,
            self.alt0,
        )
        return np.asarray(east) / self.cell_size_m, np.asarray(north) / self.cell_size_m

    def to_metres(self, lat: float, lon: float) -> Floats:
        """One place as metres east and north of cell (0, 0), as planned paths are kept
        (`passing_order.PlannedPath`)."""
        x, y = self.to_cells(lat, lon)
        return np.array([float(x), float(y)]) * self.cell_size_m


def to_e7(degrees: ArrayLike) -> NDArray[np.int64]:
    """Degrees to the integer degE7 of MISSION_ITEM_INT (1e-7° is about 1.1 cm)."""
    return np.rint(np.asarray(degrees, dtype=float) * 1e7).astype(np.int64)


def local_metres(
    lat: ArrayLike, lon: ArrayLike, lat0: float, lon0: float, alt0: float = 0.0
) -> Floats:
    """East-north metres, shape (n, 2), of points around a reference point (lat0, lon0).

    For distances along a mission when no grid is at hand: over a few kilometres the
    tangent plane of any nearby point gives the same distances to better than 1e-6. The
    altitude (AMSL) matters more: a degree is 2.5e-4 longer 1600 m up than at sea level.
    """
    east, north, _ = pymap3d.geodetic2enu(
        np.asarray(lat, dtype=float), np.asarray(lon, dtype=float), alt0, lat0, lon0, alt0
    )
    return np.column_stack([np.ravel(east), np.ravel(north)])


def distance_m(lat1: float, lon1: float, lat2: float, lon2: float, alt_m: float = 0.0) -> float:
    """Horizontal distance in metres between two points a few kilometres apart at most,
    on the tangent plane at the first one (pymap3d, WGS84)."""
    east, north, _ = pymap3d.geodetic2enu(lat2, lon2, alt_m, lat1, lon1, alt_m)
    return float(np.hypot(east, north))


@dataclass(frozen=True, slots=True)
class TangentPlane:
    """East-north metres around a reference point: one frame for comparing positions."""

    lat0: float
    lon0: float
    alt0: float = 0.0

    def east_north(self, lat: float, lon: float) -> tuple[float, float]:
        east, north, _ = pymap3d.geodetic2enu(lat, lon, self.alt0, self.lat0, self.lon0, self.alt0)
        return float(east), float(north)
