"""Exact distances from straight segments to blocked cells' unit squares: what the
safety check measures a leg against the obstacles with (`planner.check.safety`), and the
any-angle shaping tests every shortcut with."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.geometry.clearance import SQUARE_REACH


def pairs_square_distance(
    p0: NDArray[np.float64], p1: NDArray[np.float64], cells: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Distance from segment p0[k]-p1[k] to cells[k]'s unit square, for many pairs at
    once, and the segment parameter of the closest point. Between two disjoint convex
    shapes the minimum is reached at a vertex of one of them, so the endpoints and the
    square's corners are enough."""
    centre = cells.astype(float)
    d = p1 - p0
    n = len(cells)
    entry, exit_ = np.zeros(n), np.ones(n)
    for axis in range(2):
        lo, hi = centre[:, axis] - 0.5, centre[:, axis] + 0.5
        da, pa = d[:, axis], p0[:, axis]
        flat = np.abs(da) < 1e-15
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (lo - pa) / da, (hi - pa) / da
        outside = flat & ((pa < lo) | (pa > hi))
        entry = np.where(flat, np.where(outside, 2.0, entry), np.maximum(entry, np.minimum(t1, t2)))
        exit_ = np.where(flat, exit_, np.minimum(exit_, np.maximum(t1, t2)))
    crosses = entry <= exit_

    candidates = [_point_to_square(p0, centre), _point_to_square(p1, centre)]
    taus = [np.zeros(n), np.ones(n)]
    length2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]
    moving = length2 > 0
    safe2 = np.where(moving, length2, 1.0)
    for sx in (-0.5, 0.5):
        for sy in (-0.5, 0.5):
            corner = centre + np.array([sx, sy])
            rel = corner - p0
            u = np.where(
                moving, np.clip((rel[:, 0] * d[:, 0] + rel[:, 1] * d[:, 1]) / safe2, 0, 1), 0.0
            )
            candidates.append(np.hypot(*(p0 + u[:, None] * d - corner).T))
            taus.append(u)
    stack, tau_stack = np.stack(candidates), np.stack(taus)
    best = np.argmin(stack, axis=0)
    cols = np.arange(n)
    dist = np.where(crosses, 0.0, stack[best, cols])
    tau = np.where(crosses, np.clip(entry, 0, 1), tau_stack[best, cols])
    return dist, tau


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
    times."""
    centre = cells.astype(float)
    d = p1 - p0
    entry, exit_ = _slabs(p0, d, centre)
    if (entry <= exit_).any():
        return 0.0  # it crosses a square
    least = min(
        float(_point_to_square(p0, centre).min()), float(_point_to_square(p1, centre).min())
    )
    length2 = float(d @ d)
    for sx in (-0.5, 0.5):
        for sy in (-0.5, 0.5):
            corner = centre + np.array([sx, sy])
            u = np.clip((corner - p0) @ d / length2, 0, 1) if length2 > 0 else np.zeros(len(cells))
            least = min(least, float(np.hypot(*(p0 + u[:, None] * d - corner).T).min()))
    return least


def _cells_near(
    p0: NDArray[np.float64], p1: NDArray[np.float64], radius: float, blocked: NDArray[np.bool_]
) -> NDArray[np.int64]:
    """Blocked cells whose square may come within `radius` of the segment: those in its
    bounding box (widened) whose centre is within radius + √2/2 of it (no point of a
    square is further than √2/2 from its centre, so no cell that matters is dropped)."""
    reach = radius + 0.5
    lo = np.floor(np.minimum(p0, p1) - reach).astype(int)
    hi = np.ceil(np.maximum(p0, p1) + reach).astype(int)
    lo = np.maximum(lo, 0)
    hi = np.minimum(hi, np.array(blocked.shape) - 1)
    if np.any(lo > hi):
        return np.empty((0, 2), dtype=np.int64)
    window = blocked[lo[0] : hi[0] + 1, lo[1] : hi[1] + 1]
    cells: NDArray[np.int64] = np.argwhere(window) + lo
    if len(cells) > 8:
        d = p1 - p0
        length2 = float(d @ d)
        rel = cells - p0
        u = np.clip(rel @ d / length2, 0.0, 1.0) if length2 > 0 else np.zeros(len(cells))
        gap = rel - u[:, None] * d
        cells = cells[np.einsum("ij,ij->i", gap, gap) <= (radius + SQUARE_REACH) ** 2]
    return cells


def _slabs(
    p0: NDArray[np.float64], d: NDArray[np.float64], centre: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Where the segment p0 + t·d (t in [0, 1]) enters and leaves each unit square
    centred on `centre` (slab clipping): it crosses the squares where entry <= exit."""
    entry, exit_ = np.zeros(len(centre)), np.ones(len(centre))
    for axis in range(2):
        lo, hi = centre[:, axis] - 0.5, centre[:, axis] + 0.5
        if abs(d[axis]) < 1e-15:
            entry = np.where((p0[axis] < lo) | (p0[axis] > hi), 2.0, entry)
            continue
        t1, t2 = (lo - p0[axis]) / d[axis], (hi - p0[axis]) / d[axis]
        entry = np.maximum(entry, np.minimum(t1, t2))
        exit_ = np.minimum(exit_, np.maximum(t1, t2))
    return entry, exit_


def _point_to_square(p: NDArray[np.float64], centre: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance from p to each unit square centred on `centre`."""
    off = np.maximum(np.abs(p - centre) - 0.5, 0.0)
    distance: NDArray[np.float64] = np.hypot(off[..., 0], off[..., 1])
    return distance
