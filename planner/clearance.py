"""Distance from any point of the map to the nearest blocked cell, on a fine raster.

The optimizer's cost needs the clearance of thousands of points per evaluation;
reading it from a precomputed distance transform is one gather. It is approximate
(to half a pixel), which is why the cost adds a margin and every plan is judged by
the exact check in `planner.safety`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

PIXELS_PER_CELL = 8


@dataclass(frozen=True)
class ClearanceField:
    distance: NDArray[np.float32]  # cells, indexed [px, py] over the padded raster
    scale: int

    @classmethod
    def build(cls, blocked: NDArray[np.bool_], scale: int = PIXELS_PER_CELL) -> ClearanceField:
        """Blocked cells, and everything outside the grid, count as obstacles."""
        padded = np.pad(blocked, 1, constant_values=True)
        raster = np.repeat(np.repeat(padded, scale, axis=0), scale, axis=1)
        # Distance from each free pixel centre to the nearest blocked pixel's edge.
        inside = ndimage.distance_transform_edt(~raster) - 0.5
        return cls((np.maximum(inside, 0.0) / scale).astype(np.float32), scale)

    def at(self, points: NDArray[np.float64]) -> NDArray[np.float32]:
        """Clearance at points given in cell coordinates, any leading shape (..., 2)."""
        # Cell (x, y) spans [x - 0.5, x + 0.5]; the raster starts one padding cell before 0.
        pix = np.floor((points + 1.5) * self.scale).astype(np.intp)
        px = np.clip(pix[..., 0], 0, self.distance.shape[0] - 1)
        py = np.clip(pix[..., 1], 0, self.distance.shape[1] - 1)
        return self.distance[px, py]

    @property
    def error(self) -> float:
        """How far a reading may be from the true clearance, in cells."""
        return float(np.sqrt(2.0) / self.scale)
