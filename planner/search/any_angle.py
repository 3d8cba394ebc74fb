"""Any-angle shortcuts of a grid path, kept exactly clear of blocked cells.

An 8-connected path through cell centres is up to 8 % longer than the straight line
it approximates. Pulling the string (from each anchor, jump to the furthest later point
the UAV's disc can reach in a straight line) gives the polyline a UAV actually wants to
fly. Every shortcut is tested exactly, with the same disc-against-square distance as the
safety check (`planner.geometry.squares.segment_clearance`), so the result never enters a
blocked cell when the grid path did not.

A fleet's paths are shaped together (`pull_strings`, `tighten_all`): each path is walked
in its own order, exactly as alone, but the walks advance in step, so that one round
tests a shortcut or a corner of every path in a few numpy calls. Alone, each test was a
few dozen numpy calls on a handful of cells, and their fixed cost was most of the time.
"""

from __future__ import annotations

import functools
from collections.abc import Generator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.geometry.clearance import SQUARE_REACH, segment_square_distance
from planner.geometry.squares import segment_clearance
from planner.model.trajectory import merge_collinear

Array = NDArray[np.float64]
Indices = NDArray[np.intp]
# Cells: `segment_square_distance` and `segment_clearance` round the same distance
# differently in the last bits only, far less than this; nearer a clearance than this,
# `segment_clearance` itself decides (`_sees`).
EPS = 1e-9
WITHIN = 0.5  # `segment_clearance`'s reach: below it, every cell that matters is measured
FEW = 4  # segments `_sees` measures one by one: batching them would cost more calls


def pull_string(cells: Array, radius: float, blocked: NDArray[np.bool_]) -> Array:
    """The shortcut polyline of a grid path (cells (n, 2), first and last kept)."""
    return pull_strings([cells], [radius], blocked)[0]


def pull_strings(
    paths: Sequence[Array], radii: Sequence[float], blocked: NDArray[np.bool_]
) -> list[Array]:
    """The shortcut polylines of grid paths, each walked by `_anchors`; each round asks
    every unfinished walk's next shortcut at once (`_sees`)."""
    grid = _Obstacles(blocked)
    points = [merge_collinear(c) for c in paths]
    walks = [_anchors(len(p)) for p in points]
    widths = np.asarray(radii, dtype=float)
    asked: dict[int, tuple[int, int]] = {}
    kept: dict[int, list[int]] = {}

    def answer(j: int, clear: bool | None) -> None:
        try:
            asked[j] = walks[j].send(clear)  # type: ignore[arg-type]  # None starts it
        except StopIteration as done:
            asked.pop(j, None)
            kept[j] = done.value

    for j in range(len(walks)):
        answer(j, None)
    while asked:
        js = list(asked)
        starts = np.array([points[j][asked[j][0]] for j in js])
        ends = np.array([points[j][asked[j][1]] for j in js])
        for j, clear in zip(js, _sees(starts, ends, widths[js], grid).tolist(), strict=True):
            answer(j, clear)
    return [p if len(p) <= 2 else np.array([p[k] for k in kept[j]]) for j, p in enumerate(points)]


def _anchors(n: int) -> Generator[tuple[int, int], bool, list[int]]:
    """The anchors kept of a path of n points; it yields each shortcut (a, b) it needs
    tested and is sent whether it is clear.

    From each anchor the next one is found by galloping (2, 4, 8, ... points ahead) and
    then halving the gap to the first blocked jump: O(log n) exact tests per anchor
    rather than one per point. A grid step itself is always clear (no corner cutting),
    so the anchor always moves on.
    """
    anchors = [0]
    while n > 2 and anchors[-1] < n - 1:
        anchor = anchors[-1]
        lo, reach = anchor + 1, 2
        hi = n  # the smallest index known to be out of sight (n: none yet)
        while anchor + reach < n:
            if not (yield anchor, anchor + reach):
                hi = anchor + reach
                break
            lo, reach = anchor + reach, 2 * reach
        else:
            if lo != n - 1:
                if (yield anchor, n - 1):
                    lo = n - 1
                else:
                    hi = n - 1
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if (yield anchor, mid):
                lo = mid
            else:
                hi = mid
        anchors.append(lo)
    return anchors


def segments_clearance(p0: Array, p1: Array, cells: NDArray[np.int64]) -> Array:
    """Exact distance from each segment p0[k]-p1[k] (S, 2) to the nearest of the given
    cells' unit squares (C, 2): the test of `planner.geometry.squares.segment_clearance`,
    for many segments at once (inf without cells)."""
    if not len(cells):
        return np.full(len(p0), np.inf)
    gaps = segment_square_distance(p0[:, None, :], p1[:, None, :], cells[None].astype(float))
    clearance: Array = gaps.min(axis=1)
    return clearance


def tighten(
    points: Array, clearance: float, blocked: NDArray[np.bool_], sweeps: int = 2, steps: int = 10
) -> Array:
    """One polyline tightened (`tighten_all`)."""
    return tighten_all([points], [clearance], blocked, sweeps, steps)[0]


def tighten_all(
    polylines: Sequence[Array],
    clearances: Sequence[float],
    blocked: NDArray[np.bool_],
    sweeps: int = 2,
    steps: int = 10,
) -> list[Array]:
    """Shorten polylines by sliding each interior point towards the chord of its
    neighbours as far as its two legs stay its polyline's clearance clear of blocked
    cells (exactly): a string pulled through cell centres, tightened round its corners.

    Moving a point towards the chord never lengthens the path (the two legs are convex
    in the move). A polyline's points move in order, each from its neighbours' latest
    places; each round moves the next point of every polyline (`_slides`).
    """
    grid = _Obstacles(blocked)
    pts = [np.array(p, dtype=float) for p in polylines]
    fractions = np.linspace(1.0, 0.0, steps + 1)[:-1]
    todo = [list(range(1, len(p) - 1)) for p in pts]
    for _ in range(sweeps):
        moved: list[set[int]] = [set() for _ in pts]
        for rank in range(max(map(len, todo), default=0)):
            batch = [(j, t[rank]) for j, t in enumerate(todo) if rank < len(t)]
            trios = np.array([pts[j][i - 1 : i + 2] for j, i in batch])
            radii = np.array([clearances[j] for j, _ in batch], dtype=float)
            for k, place in _slides(trios, radii, grid, fractions):
                j, i = batch[k]
                pts[j][i] = place
                moved[j].add(i)
        # Only a point whose neighbour moved can move further.
        todo = [
            sorted({k for i in m for k in (i - 1, i + 1) if 0 < k < len(p) - 1})
            for m, p in zip(moved, pts, strict=True)
        ]
        if not any(todo):
            break
    return _drop_needless(pts, clearances, grid)


def _slides(
    trios: Array, clearances: Array, grid: _Obstacles, fractions: Array
) -> list[tuple[int, Array]]:
    """Where each middle point of trios (K, 3, 2) moves: its candidate furthest towards
    the chord of its neighbours whose two legs are both clear, unless that is where it is.
    Every leg is measured as `segments_clearance` measures it (the same arithmetic)."""
    a, v, b = trios[:, 0], trios[:, 1], trios[:, 2]
    chord = b - a
    u = np.array([_projection(*row) for row in zip(a, v, chord, strict=True)])
    candidates = v[:, None] + fractions[None, :, None] * (a + u[:, None] * chord - v)[:, None]
    k, s = candidates.shape[:2]
    starts = np.concatenate([np.broadcast_to(a[:, None], candidates.shape), candidates], axis=1)
    ends = np.concatenate([candidates, np.broadcast_to(b[:, None], candidates.shape)], axis=1)
    cells, owner = grid.near_boxes(trios, clearances)
    near = _near_triangles(cells, trios[owner], clearances[owner] + SQUARE_REACH)
    clear = _leg_gaps(starts, ends, cells[near], owner[near], clearances) >= clearances[:, None]
    ok = clear[:, :s] & clear[:, s:]
    chosen = candidates[np.arange(k), ok.argmax(axis=1)]
    shift = chosen - v
    moves = ok.any(axis=1) & (np.hypot(shift[:, 0], shift[:, 1]) > 1e-6)
    return [(int(m), chosen[m]) for m in np.flatnonzero(moves)]


def _projection(a: Array, v: Array, chord: Array) -> float:
    """Where v projects on the chord from a, as a share of it clamped to [0, 1]; point by
    point, since a 2-vector `@` is BLAS's product, whose rounding the plans keep."""
    return min(max(float((v - a) @ chord / max(float(chord @ chord), 1e-300)), 0.0), 1.0)


def _near_triangles(cells: Array, triangles: Array, reach: Array) -> NDArray[np.bool_]:
    """Whether each cell centre (M, 2) is inside its triangle (M, 3, 2) or within `reach`
    (M,) of its edges: the cells that may come near a leg inside the triangle."""
    a, b = triangles, triangles[:, _NEXT_CORNER]  # np.roll(-1)'s values, in one call
    d, rel = b - a, cells[:, None] - a
    gx, gy = _offsets(rel, d)
    near: NDArray[np.bool_] = (gx * gx + gy * gy).min(axis=1) <= reach * reach
    side = d[..., 0] * rel[..., 1] - d[..., 1] * rel[..., 0]
    inside: NDArray[np.bool_] = np.all(side >= 0, axis=1) | np.all(side <= 0, axis=1)
    return near | inside


_NEXT_CORNER = [1, 2, 0]


def _offsets(rel: Array, d: Array) -> tuple[Array, Array]:
    """From the nearest point of each segment (start + [0, 1]·d) to the points at `rel`
    from its start, per axis."""
    length2 = np.maximum(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1], 1e-300)
    along = (rel[..., 0] * d[..., 0] + rel[..., 1] * d[..., 1]) / length2
    t = np.minimum(np.maximum(along, 0.0), 1.0)
    return rel[..., 0] - t * d[..., 0], rel[..., 1] - t * d[..., 1]


def _leg_gaps(starts: Array, ends: Array, cells: Array, owner: Indices, clearances: Array) -> Array:
    """Distance from each leg starts[k, l]-ends[k, l] (K, L, 2) to the nearest square of
    the cells owned by k (inf: none near): `segment_square_distance`, element by element,
    on the (leg, cell) pairs whose centre is within clearance + √2/2 of the leg."""
    k, legs = starts.shape[:2]
    p0, p1 = starts.reshape(-1, 2), ends.reshape(-1, 2)
    leg = (owner[:, None] * legs + np.arange(legs)).ravel()
    cell = np.repeat(np.arange(len(cells)), legs)
    reach = clearances[owner].repeat(legs) + SQUARE_REACH
    gx, gy = _offsets(cells[cell] - p0[leg], p1[leg] - p0[leg])
    near = gx * gx + gy * gy <= reach * reach
    leg, cell = leg[near], cell[near]
    gaps = np.full(k * legs, np.inf)
    np.minimum.at(gaps, leg, segment_square_distance(p0[leg], p1[leg], cells[cell]))
    return gaps.reshape(k, legs)


def _drop_needless(
    polylines: Sequence[Array], clearances: Sequence[float], grid: _Obstacles
) -> list[Array]:
    """Drop interior points whose neighbours see each other (collinear ones included):
    each polyline walked in order, a point of every polyline per round."""
    keep = [[p[0]] for p in polylines]
    radii = np.asarray(clearances, dtype=float)
    for i in range(1, max(map(len, polylines), default=0) - 1):
        batch = [j for j, p in enumerate(polylines) if i < len(p) - 1]
        starts = np.array([keep[j][-1] for j in batch])
        ends = np.array([polylines[j][i + 1] for j in batch])
        for j, sees in zip(batch, _sees(starts, ends, radii[batch], grid).tolist(), strict=True):
            if not sees:
                keep[j].append(polylines[j][i])
    return [np.array([*k, p[-1]]) for k, p in zip(keep, polylines, strict=True)]


def _sees(starts: Array, ends: Array, clearances: Array, grid: _Obstacles) -> NDArray[np.bool_]:
    """`segment_clearance(starts[k], ends[k], blocked) >= clearances[k]` for many segments:
    measured all at once (`segment_square_distance`), then by `segment_clearance` itself
    for the few within EPS of their clearance (or all, where a clearance reaches WITHIN,
    or where there are only FEW segments: one path alone)."""
    if len(starts) <= FEW:
        rows = zip(starts, ends, clearances.tolist(), strict=True)
        return np.array([_exactly_sees(p0, p1, c, grid.blocked) for p0, p1, c in rows])
    reach = clearances + EPS
    cells, owner = grid.near_boxes(np.stack([starts, ends], axis=1), reach)
    gaps = _leg_gaps(starts[:, None], ends[:, None], cells, owner, reach)[:, 0]
    clear: NDArray[np.bool_] = gaps >= clearances
    doubt = (np.abs(gaps - clearances) <= EPS) | (clearances >= WITHIN - EPS)
    for k in np.flatnonzero(doubt):
        clear[k] = _exactly_sees(starts[k], ends[k], clearances[k], grid.blocked)
    return clear


def _exactly_sees(start: Array, end: Array, clearance: float, blocked: NDArray[np.bool_]) -> bool:
    return segment_clearance(start, end, blocked) >= clearance


@dataclass(frozen=True)
class _Obstacles:
    """A grid's blocked cells as sorted flat indices: many boxes' cells in a few calls."""

    blocked: NDArray[np.bool_]

    @functools.cached_property
    def flat(self) -> Indices:
        """Taken when first needed: a path alone may never need it (`FEW`)."""
        return np.flatnonzero(self.blocked)

    def near_boxes(self, shapes: Array, clearances: Array) -> tuple[Array, Indices]:
        """Centres of the blocked cells in each shape's box (K, points, 2) widened by its
        clearance and half a cell (every cell that may come within clearance of a segment
        inside the shape's hull), and which shape each belongs to."""
        reach = (clearances + 0.5)[:, None]
        top = np.array(self.blocked.shape) - 1
        lo = np.maximum(np.floor(shapes.min(axis=1) - reach).astype(np.intp), 0)
        hi = np.minimum(np.ceil(shapes.max(axis=1) + reach).astype(np.intp), top)
        rows = hi[:, 0] - lo[:, 0] + 1  # one run of flat indices per row of each box
        box = np.repeat(np.arange(len(lo)), rows)
        x = lo[box, 0] + _counting(rows)
        width = self.blocked.shape[1]
        first = np.searchsorted(self.flat, x * width + lo[box, 1])
        counts = np.searchsorted(self.flat, x * width + hi[box, 1] + 1) - first
        run = np.repeat(np.arange(len(box)), counts)
        flat = self.flat[first[run] + _counting(counts)]
        cells = np.stack([flat // width, flat % width], axis=1).astype(float)
        return cells, box[run]


def _counting(lengths: Indices) -> Indices:
    """0, 1, ..., n - 1 for each n of `lengths`, one after the other."""
    total = int(lengths.sum())
    starts = np.repeat(np.cumsum(lengths) - lengths, lengths)
    counted: Indices = np.arange(total) - starts
    return counted
