"""Clearance from blocked cells for the optimizer's cost: a raster, or exact per leg.

`ClearanceField`: distance from any point of the map to the nearest blocked cell, on a
fine raster. The cost needs the clearance of thousands of points per evaluation;
reading it from a precomputed distance transform is one gather. It is approximate (to
half a pixel), which is why the cost adds a margin. Algorithm 1 as the paper runs it
uses it.

`ExactClearance`: the blocked cells near one search's corridor, and the exact distance
of each leg of each candidate to them (the safety check's own geometry), for the
anytime planner: no raster to build on a 500 x 500 map, and no margin that would keep
a path off the obstacles it may hug. Every plan is still judged by `planner.check.safety`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

PIXELS_PER_CELL = 8
SQUARE_REACH = float(np.sqrt(0.5)) + 1e-9  # centre of a unit square to its corners
_CORNERS = np.array([(-0.5, -0.5), (-0.5, 0.5), (0.5, -0.5), (0.5, 0.5)])


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


def distance_to_polyline(
    points: NDArray[np.float64], polyline: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Distance from each point (M, 2) to the polyline (P, 2), all segments at once."""
    a, b = polyline[:-1], polyline[1:]
    distance: NDArray[np.float64]
    if not len(a):
        distance = np.hypot(*(points - polyline[0]).T)
        return distance
    d = b - a
    length2 = np.einsum("ij,ij->i", d, d)
    rel = points[:, None, :] - a[None]  # (M, S, 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(length2 > 0, np.einsum("msi,si->ms", rel, d) / length2, 0.0)
    u = np.minimum(np.maximum(u, 0.0), 1.0)  # np.clip's value, faster on small arrays
    gap = rel - u[..., None] * d[None]
    distance = np.sqrt(np.einsum("msi,msi->ms", gap, gap)).min(axis=1)
    return distance


def segment_square_distance(
    a: NDArray[np.float64], b: NDArray[np.float64], centre: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Exact distance between segments a-b and the unit squares centred on `centre`, all
    (..., 2) and broadcast together: 0 if the segment enters the square, else the least
    of its ends' distances to the square and the square's corners' to the segment (two
    disjoint convex shapes are closest at a vertex of one of them)."""
    # Called thousands of times on small arrays (the shaping's tightening), so in few
    # numpy calls: the two axes as views rather than reductions, each |a - centre| once.
    d = b - a
    off_a = np.abs(a - centre)
    inside = off_a <= 0.5  # per axis, for a segment parallel to it
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (centre - 0.5 - a) / d, (centre + 0.5 - a) / d
    moving = d != 0
    beyond = np.where(inside, -np.inf, np.inf)
    t_in = np.where(moving, np.minimum(t1, t2), beyond)
    t_out = np.where(moving, np.maximum(t1, t2), -beyond)
    enter = np.maximum(np.maximum(t_in[..., 0], t_in[..., 1]), 0.0)
    crosses = enter <= np.minimum(np.minimum(t_out[..., 0], t_out[..., 1]), 1.0)

    def to_square(off: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.maximum(off - 0.5, 0.0)
        return np.hypot(out[..., 0], out[..., 1])

    best = np.minimum(to_square(off_a), to_square(np.abs(b - centre)))
    length2 = np.maximum(d[..., 0] ** 2 + d[..., 1] ** 2, 1e-300)[..., None]
    # The four corners along a last axis at once: the same arithmetic per corner.
    rel = centre[..., None, :] + _CORNERS - a[..., None, :]
    dx, dy = d[..., None, 0], d[..., None, 1]
    u = np.minimum(np.maximum((rel[..., 0] * dx + rel[..., 1] * dy) / length2, 0.0), 1.0)
    corners = np.hypot(rel[..., 0] - u * dx, rel[..., 1] - u * dy).min(axis=-1)
    return np.where(crosses, 0.0, np.minimum(best, corners))


@dataclass(frozen=True)
class ExactClearance:
    """The blocked cells near one search's paths, for exact clearance of whole legs.

    Where the raster reads clearance at samples and so needs a margin, this measures each
    leg's distance to each nearby blocked square in closed form, as the safety check
    does: a path that hugs an obstacle at exactly the UAV's radius is clear here too.
    """

    cells: NDArray[np.float64]  # (C, 2) centres of the blocked cells the paths may meet

    @classmethod
    def near(
        cls, blocked: NDArray[np.bool_], polyline: NDArray[np.float64], reach: float
    ) -> ExactClearance:
        """Blocked cells whose square may come within `reach` of `polyline`, and the grid's
        outside (a ring of cells around it), so that a path cannot leave the map."""
        padded = np.pad(blocked, 1, constant_values=True)
        lo = np.maximum(np.floor(polyline.min(axis=0) - reach - 0.5).astype(int) + 1, 0)
        hi = np.minimum(
            np.ceil(polyline.max(axis=0) + reach + 0.5).astype(int) + 1,
            np.array(padded.shape) - 1,
        )
        if np.any(lo > hi):
            return cls(np.zeros((0, 2)))
        centres = (np.argwhere(padded[lo[0] : hi[0] + 1, lo[1] : hi[1] + 1]) + lo - 1).astype(float)
        close = distance_to_polyline(centres, polyline) <= reach + SQUARE_REACH
        return cls(centres[close])

    def leg_terms(
        self, waypoints: NDArray[np.float64], radius: float
    ) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
        """Per candidate path (N, P, 2): the summed depth of its discs' entries into
        blocked squares, and how many legs enter one."""
        n, p = waypoints.shape[:2]
        if not len(self.cells) or p < 2:
            return np.zeros(n), np.zeros(n, dtype=np.intp)
        a = waypoints[:, :-1].reshape(-1, 2)
        d = waypoints[:, 1:].reshape(-1, 2) - a
        length2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
        rel = self.cells[None, :, :] - a[:, None, :]  # (L, C, 2): centre to leg, cheaply
        u = np.clip(np.einsum("lci,li->lc", rel, d) / length2[:, None], 0.0, 1.0)
        gx = rel[..., 0] - u * d[:, None, 0]
        gy = rel[..., 1] - u * d[:, None, 1]
        legs, cells = np.nonzero(gx * gx + gy * gy < (radius + SQUARE_REACH) ** 2)
        if not len(legs):
            return np.zeros(n), np.zeros(n, dtype=np.intp)
        gap = segment_square_distance(a[legs], a[legs] + d[legs], self.cells[cells])
        deficit = np.maximum(radius - gap, 0.0)
        row = legs // (p - 1)
        depth = np.bincount(row, weights=deficit, minlength=n).astype(np.float64)
        entered = np.zeros(n * (p - 1), dtype=bool)
        entered[legs[deficit > 0]] = True
        return depth, entered.reshape(n, p - 1).sum(axis=1).astype(np.intp)
