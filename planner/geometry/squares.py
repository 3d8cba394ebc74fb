"""Exact distances from straight segments to blocked cells' unit squares: what the
safety check measures a leg against the obstacles with (`planner.check.safety`), and the
any-angle shaping tests every shortcut with."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from planner.geometry.clearance import SQUARE_REACH


def pairs_square_distance(
    p0: NDArray[np.float64], p1: NDArray[np.float64], cells: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Distance from segment p0[k]-p1[k] to cells[k]'s unit square, for many pairs at
    once, and the segment parameter of the closest point. Between two disjoint convex
    shapes the minimum is reached at a vertex of one of them, so the endpoints and the
    square's corners are enough.

    The safety check calls this after every change of a flight on a few dozen pairs, so
    both axes' slabs and the four corners are computed in one array each (the same
    element-wise operations as one axis and one corner at a time)."""
    centre = cells.astype(float)
    d = p1 - p0
    n = len(cells)
    lo, hi = centre - 0.5, centre + 0.5
    flat = np.abs(d) < 1e-15
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - p0) / d, (hi - p0) / d
    outside = flat & ((p0 < lo) | (p0 > hi))
    # Per axis: where the segment enters and leaves its slab (a flat segment outside the
    # slab never enters: 2; inside, no bound).
    enters = np.where(flat, np.where(outside, 2.0, 0.0), np.minimum(t1, t2))
    leaves = np.where(flat, np.inf, np.maximum(t1, t2))
    entry = np.maximum(np.maximum(enters[:, 0], enters[:, 1]), 0.0)
    crosses = entry <= np.minimum(np.minimum(leaves[:, 0], leaves[:, 1]), 1.0)

    length2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]
    moving = length2 > 0
    safe2 = np.where(moving, length2, 1.0)
    corner = centre + _CORNER_OFFSETS  # (4, n, 2)
    rel = corner - p0
    u = np.where(
        moving, np.clip((rel[..., 0] * d[:, 0] + rel[..., 1] * d[:, 1]) / safe2, 0, 1), 0.0
    )
    off = p0 + u[..., None] * d - corner
    stack = np.empty((6, n))
    stack[0] = _point_to_square(p0, centre)
    stack[1] = _point_to_square(p1, centre)
    stack[2:] = np.hypot(off[..., 0], off[..., 1])
    tau_stack = np.empty((6, n))
    tau_stack[0], tau_stack[1], tau_stack[2:] = 0.0, 1.0, u
    best = np.argmin(stack, axis=0)
    cols = np.arange(n)
    dist = np.where(crosses, 0.0, stack[best, cols])
    tau = np.where(crosses, np.clip(entry, 0, 1), tau_stack[best, cols])
    return dist, tau


_CORNER_OFFSETS = np.array([(-0.5, -0.5), (-0.5, 0.5), (0.5, -0.5), (0.5, 0.5)])[:, None, :]


def segment_clearance(
    p0: NDArray[np.float64],
    p1: NDArray[np.float64],
    blocked: NDArray[np.bool_],
    within: float = 0.5,
) -> float:
    """Exact distance from the segment p0-p1 to the nearest blocked cell's square (the
    test `planner.check.safety.cell_conflicts` makes), or inf if no blocked cell is
    within `within` of it."""
    cells = _cells_near(p0, p1, within, blocked)
    if not len(cells):
        return float("inf")
    return _least_square_distance(p0, p1, cells)


def _least_square_distance(
    p0: NDArray[np.float64], p1: NDArray[np.float64], cells: NDArray[np.int64]
) -> float:
    """The least distance from the segment to the cells' squares (0 if it crosses one),
    for one segment and a few cells: the any-angle shaping calls this thousands of
    times, so the per-cell arithmetic runs on plain floats (the same IEEE operations as
    numpy's, element by element). Only the corners' projections stay numpy products
    (`@` goes through BLAS, whose rounding plain floats would not reproduce) and the
    distances one `np.hypot` (`math.hypot` rounds differently)."""
    centre = cells.astype(float)
    d = p1 - p0
    x0, y0 = float(p0[0]), float(p0[1])
    x1, y1 = float(p1[0]), float(p1[1])
    dx, dy = float(d[0]), float(d[1])
    squares = centre.tolist()
    for cx, cy in squares:
        if _crosses(x0, y0, dx, dy, cx, cy):
            return 0.0
    gx, gy = [], []  # the offsets whose length is a candidate distance
    for cx, cy in squares:
        for px, py in ((x0, y0), (x1, y1)):
            gx.append(max(abs(px - cx) - 0.5, 0.0))
            gy.append(max(abs(py - cy) - 0.5, 0.0))
    length2 = float(d @ d)
    still = [0.0] * len(squares)  # a segment of no length: each corner projects on p0
    for sx in (-0.5, 0.5):
        for sy in (-0.5, 0.5):
            corner = centre + np.array([sx, sy])
            along = ((corner - p0) @ d / length2).tolist() if length2 > 0 else still
            for (cx, cy), t in zip(squares, along, strict=True):
                u = min(max(t, 0.0), 1.0)
                gx.append(x0 + u * dx - (cx + sx))
                gy.append(y0 + u * dy - (cy + sy))
    return float(np.hypot(gx, gy).min())


def _crosses(x0: float, y0: float, dx: float, dy: float, cx: float, cy: float) -> bool:
    """Whether the segment (x0, y0) + t·(dx, dy), t in [0, 1], meets the unit square
    centred on (cx, cy), by slab clipping: where it enters and leaves the square's
    stripe along each axis (a segment parallel to an axis and outside the stripe never
    enters)."""
    entry, exit_ = 0.0, 1.0
    for p, dp, c in ((x0, dx, cx), (y0, dy, cy)):
        lo, hi = c - 0.5, c + 0.5
        if abs(dp) < 1e-15:
            if p < lo or p > hi:
                entry = 2.0
            continue
        t1, t2 = (lo - p) / dp, (hi - p) / dp
        entry = max(entry, min(t1, t2))
        exit_ = min(exit_, max(t1, t2))
    return entry <= exit_


def _cells_near(
    p0: NDArray[np.float64], p1: NDArray[np.float64], radius: float, blocked: NDArray[np.bool_]
) -> NDArray[np.int64]:
    """Blocked cells whose square may come within `radius` of the segment: those in its
    bounding box (widened) whose centre is within radius + √2/2 of it (no point of a
    square is further than √2/2 from its centre, so no cell that matters is dropped)."""
    reach = radius + 0.5
    x0, y0, x1, y1 = float(p0[0]), float(p0[1]), float(p1[0]), float(p1[1])
    lo_x = max(math.floor(min(x0, x1) - reach), 0)
    lo_y = max(math.floor(min(y0, y1) - reach), 0)
    hi_x = min(math.ceil(max(x0, x1) + reach), blocked.shape[0] - 1)
    hi_y = min(math.ceil(max(y0, y1) + reach), blocked.shape[1] - 1)
    if lo_x > hi_x or lo_y > hi_y:
        return np.empty((0, 2), dtype=np.int64)
    window = blocked[lo_x : hi_x + 1, lo_y : hi_y + 1]
    cells: NDArray[np.int64] = np.argwhere(window) + np.array([lo_x, lo_y])
    if len(cells) > 8:
        d = p1 - p0
        length2 = float(d @ d)
        rel = cells - p0
        if length2 > 0:  # np.minimum/np.maximum: np.clip's value, faster on a few cells
            u = np.minimum(np.maximum(rel @ d / length2, 0.0), 1.0)
        else:
            u = np.zeros(len(cells))
        gap = rel - u[:, None] * d
        cells = cells[np.einsum("ij,ij->i", gap, gap) <= (radius + SQUARE_REACH) ** 2]
    return cells


def _point_to_square(p: NDArray[np.float64], centre: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance from p to each unit square centred on `centre`."""
    off = np.maximum(np.abs(p - centre) - 0.5, 0.0)
    distance: NDArray[np.float64] = np.hypot(off[..., 0], off[..., 1])
    return distance
