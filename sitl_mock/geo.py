"""One local east-north frame for the whole fleet (pymap3d, WGS84), so distances are metres."""

from __future__ import annotations

import numpy as np
import pymap3d


class LocalFrame:
    """East/north metres about an origin; altitudes stay relative to each vehicle's home."""

    def __init__(self, lat: float, lon: float, alt: float = 0.0) -> None:
        self.lat, self.lon, self.alt = lat, lon, alt

    def to_local(self, lat: float, lon: float) -> tuple[float, float]:
        east, north, _ = pymap3d.geodetic2enu(lat, lon, self.alt, self.lat, self.lon, self.alt)
        return float(east), float(north)

    def to_geodetic(self, east: np.ndarray, north: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lat, lon, _ = pymap3d.enu2geodetic(
            east, north, np.zeros_like(east), self.lat, self.lon, self.alt
        )
        return np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)


def offset(lat: float, lon: float, alt: float, east: float, north: float) -> tuple[float, float]:
    """The point `east`, `north` metres from (lat, lon)."""
    new_lat, new_lon, _ = pymap3d.enu2geodetic(east, north, 0.0, lat, lon, alt)
    return float(new_lat), float(new_lon)
