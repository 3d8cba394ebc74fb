"""Ground truth for tests: every vehicle's sampled track, and the closest approach of any two
airborne vehicles, checked at every physics step with numpy in local metres."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import numpy as np


@dataclass(frozen=True)
class TrackPoint:
    t: float
    sysid: int
    lat: float
    lon: float
    alt: float
    """Metres above home."""
    armed: bool


@dataclass(frozen=True)
class Separation:
    distance_m: float
    """Horizontal distance."""
    t: float
    sysids: tuple[int, int]
    lat: float
    """Midpoint of the two vehicles."""
    lon: float


class TrackRecorder:
    """Samples of all vehicles at once; optionally mirrored to a JSON-lines file."""

    def __init__(self, sysids: list[int], log_path: Path | None = None) -> None:
        self.sysids = list(sysids)
        self._column = {sysid: i for i, sysid in enumerate(self.sysids)}
        self._t: list[float] = []
        self._samples: list[np.ndarray] = []
        self._log: TextIO | None = open(log_path, "w") if log_path else None  # noqa: SIM115

    def record(
        self, t: float, lat: np.ndarray, lon: np.ndarray, alt: np.ndarray, armed: np.ndarray
    ) -> None:
        sample = np.stack([lat, lon, alt, armed.astype(float)])
        self._t.append(t)
        self._samples.append(sample)
        if self._log is not None:
            self._log.writelines(
                f'{{"t": {t:.3f}, "sysid": {sysid}, "lat": {sample[0, i]:.8f}, '
                f'"lon": {sample[1, i]:.8f}, "alt": {sample[2, i]:.3f}, '
                f'"armed": {"true" if sample[3, i] else "false"}}}\n'
                for i, sysid in enumerate(self.sysids)
            )

    def track(self, sysid: int) -> list[TrackPoint]:
        column = self._column[sysid]
        return [
            TrackPoint(
                t,
                sysid,
                float(s[0, column]),
                float(s[1, column]),
                float(s[2, column]),
                bool(s[3, column]),
            )
            for t, s in zip(self._t, self._samples, strict=True)
        ]

    def final(self, sysid: int) -> TrackPoint | None:
        if not self._samples:
            return None
        column, s = self._column[sysid], self._samples[-1]
        return TrackPoint(
            self._t[-1],
            sysid,
            float(s[0, column]),
            float(s[1, column]),
            float(s[2, column]),
            bool(s[3, column]),
        )

    def close(self) -> None:
        if self._log is not None:
            self._log.close()
            self._log = None


class SeparationMonitor:
    """Minimum horizontal distance between any two airborne vehicles over the run."""

    def __init__(self, sysids: list[int]) -> None:
        self._sysids = np.asarray(sysids)
        self.distance = np.inf
        self.t = 0.0
        self.pair: tuple[int, int] | None = None
        self.midpoint_en: tuple[float, float] = (0.0, 0.0)

    def update(self, t: float, en: np.ndarray, airborne: np.ndarray) -> None:
        index = np.flatnonzero(airborne)
        if len(index) < 2:
            return
        points = en[index]
        delta = points[:, None, :] - points[None, :, :]
        dist2 = np.einsum("ijk,ijk->ij", delta, delta)
        np.fill_diagonal(dist2, np.inf)
        flat = int(np.argmin(dist2))
        best = float(np.sqrt(dist2.flat[flat]))
        if best < self.distance:
            i, j = divmod(flat, len(index))
            self.distance, self.t = best, t
            self.pair = (int(self._sysids[index[i]]), int(self._sysids[index[j]]))
            self.midpoint_en = tuple((points[i] + points[j]) / 2)

    def result(
        self, to_geodetic: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
    ) -> Separation | None:
        if self.pair is None:
            return None
        lat, lon = to_geodetic(np.array([self.midpoint_en[0]]), np.array([self.midpoint_en[1]]))
        a, b = sorted(self.pair)
        return Separation(self.distance, self.t, (a, b), float(lat[0]), float(lon[0]))
