"""Any-angle shortcuts of a grid path, kept exactly clear of blocked cells.

An 8-connected path through cell centres is up to 8 % longer than the straight line
it approximates. Pulling the string (from each anchor, jump to the furthest later point
the UAV's disc can reach in a straight line) gives the polyline a UAV actually wants to
fly. Every shortcut is tested exactly, with the same disc-against-square distance as the
safety check (`planner.geometry.squares.segment_clearance`), so the result never enters a blocked
cell when the grid path did not.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.geometry.clearance import SQUARE_REACH, distance_to_polyline, segment_square_distance
from planner.geometry.squares import segment_clearance
from planner.model.trajectory import merge_collinear

Array = NDArray[np.float64]


def pull_string(cells: Array, radius: float, blocked: NDArray[np.bool_]) -> Array:
    """The shortcut polyline of a grid path (cells (n, 2), first and last kept).

    From each anchor the next one is found by galloping (2, 4, 8, ... cells ahead) and
    then halving the gap to the first blocked jump: O(log n) exact tests per anchor
    rather than one per cell. A grid step itself is always clear (no corner cutting),
    so the anchor always moves on.
    """
    points = merge_collinear(cells)
    n = len(points)
    if n <= 2:
        return points

    def clear(a: int, b: int) -> bool:
        return segment_clearance(points[a], points[b], blocked) >= radius

    out = [points[0]]
    anchor = 0
    while anchor < n - 1:
        lo, reach = anchor + 1, 2
        hi = n  # the smallest index known to be out of sight (n: none yet)
        while anchor + reach < n:
            if not clear(anchor, anchor + reach):
                hi = anchor + reach
                break
            lo, reach = anchor + reach, 2 * reach
        else:
            if lo != n - 1:
                if clear(anchor, n - 1):
                    lo = n - 1
                else:
                    hi = n - 1
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if clear(anchor, mid):
                lo = mid
            else:
                hi = mid
        anchor = lo
        out.append(points[anchor])
    return np.array(out)


def segments_clearance(p0: Array, p1: Array, cells: NDArray[np.int64]) -> Array:
    """Exact distance from each segment p0[k]-p1[k] (S, 2) to the nearest of the given
    cells' unit squares (C, 2): the test of `planner.geometry.squares.segment_clearance`, for many
    segments at once (inf without cells)."""
    if not len(cells):
        return np.full(len(p0), np.inf)
    gaps = segment_square_distance(p0[:, None, :], p1[:, None, :], cells[None].astype(float))
    clearance: Array = gaps.min(axis=1)
    return clearance


def tighten(
    points: Array, clearance: float, blocked: NDArray[np.bool_], sweeps: int = 2, steps: int = 10
) -> Array:
    """Shorten a polyline by sliding each interior point towards the chord of its
    neighbours as far as its two legs stay `clearance` clear of blocked cells (exactly):
    a string pulled through cell centres, tightened round the corners it bends at.

    Every candidate position of one point is tested in one vectorised call; moving a point
    towards the chord never lengthens the path (the two legs are convex in the move).
    """
    pts = np.array(points, dtype=float)
    fractions = np.linspace(1.0, 0.0, steps + 1)[:-1]
    todo = set(range(1, len(pts) - 1))
    for _ in range(sweeps):
        moved: set[int] = set()
        for i in sorted(todo):
            a, v, b = pts[i - 1], pts[i], pts[i + 1]
            chord = b - a
            u = min(max(float((v - a) @ chord / max(float(chord @ chord), 1e-300)), 0.0), 1.0)
            candidates = v + fractions[:, None] * (a + u * chord - v)
            cells = _cells_in(pts[i - 1 : i + 2], clearance, blocked)
            k = len(candidates)
            starts, ends = np.empty((2 * k, 2)), np.empty((2 * k, 2))
            starts[:k], starts[k:], ends[:k], ends[k:] = a, candidates, candidates, b
            clear = segments_clearance(starts, ends, cells)
            ok = np.flatnonzero((clear[:k] >= clearance) & (clear[k:] >= clearance))
            if len(ok) and np.hypot(*(candidates[ok[0]] - v)) > 1e-6:
                pts[i] = candidates[ok[0]]
                moved.add(i)
        # Only a point whose neighbour moved can move further.
        todo = {j for i in moved for j in (i - 1, i + 1) if 0 < j < len(pts) - 1}
        if not todo:
            break
    return _drop_needless(pts, clearance, blocked)


def _cells_in(points: Array, clearance: float, blocked: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Blocked cells that may come within `clearance` of the triangle `points` (3, 2):
    those whose centre is inside it or within clearance + √2/2 of an edge."""
    reach = clearance + 0.5
    lo = np.maximum(np.floor(points.min(axis=0) - reach).astype(int), 0)
    hi = np.minimum(np.ceil(points.max(axis=0) + reach).astype(int), np.array(blocked.shape) - 1)
    if np.any(lo > hi):
        return np.empty((0, 2), dtype=np.int64)
    cells: NDArray[np.int64] = np.argwhere(blocked[lo[0] : hi[0] + 1, lo[1] : hi[1] + 1]) + lo
    if len(cells) <= 8:
        return cells
    centres = cells.astype(float)
    a, b, c = points
    near = distance_to_polyline(centres, np.array([a, b, c, a])) <= clearance + SQUARE_REACH
    side = np.array(
        [
            (q[0] - p[0]) * (centres[:, 1] - p[1]) - (q[1] - p[1]) * (centres[:, 0] - p[0])
            for p, q in ((a, b), (b, c), (c, a))
        ]
    )
    inside = np.all(side >= 0, axis=0) | np.all(side <= 0, axis=0)
    nearby: NDArray[np.int64] = cells[near | inside]
    return nearby


def _drop_needless(pts: Array, clearance: float, blocked: NDArray[np.bool_]) -> Array:
    """Drop interior points whose neighbours see each other (collinear ones included)."""
    keep = [pts[0]]
    for i in range(1, len(pts) - 1):
        if segment_clearance(keep[-1], pts[i + 1], blocked) < clearance:
            keep.append(pts[i])
    keep.append(pts[-1])
    return np.array(keep)
