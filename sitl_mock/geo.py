"""One local east-north frame for the whole fleet (pymap3d, WGS84), so distances are metres."""

from __future__ import annotations

import numpy as np
import pymap3d
from pymap3d.ecef import ecef2geodetic, enu2uvw, geodetic2ecef

WGS84 = pymap3d.Ellipsoid.from_name("wgs84")


class LocalFrame:
    """East/north metres about an origin; altitudes stay relative to each vehicle's home."""

    def __init__(self, lat: float, lon: float, alt: float = 0.0) -> None:
        self.lat, self.lon, self.alt = lat, lon, alt
        self._origin_ecef = geodetic2ecef(lat, lon, alt, WGS84)

    def to_local(self, lat: float, lon: float) -> tuple[float, float]:
        east, north, _ = pymap3d.geodetic2enu(lat, lon, self.alt, self.lat, self.lon, self.alt)
        return float(east), float(north)

    def to_geodetic(self, east: np.ndarray, north: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`pymap3d.enu2geodetic`'s own steps, to the bit, with the origin's ECEF position
        worked out once (the simulator converts the fleet's positions at every step)."""
        x0, y0, z0 = self._origin_ecef
        u, v, w = enu2uvw(east, north, np.zeros_like(east), self.lat, self.lon)
        lat, lon, _ = ecef2geodetic(x0 + u, y0 + v, z0 + w, WGS84)
        return np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)


def offset(lat: float, lon: float, alt: float, east: float, north: float) -> tuple[float, float]:
    """The point `east`, `north` metres from (lat, lon)."""
    new_lat, new_lon, _ = pymap3d.enu2geodetic(east, north, 0.0, lat, lon, alt)
    return float(new_lat), float(new_lon)
