"""The exact segment-to-square distances the shaping and the safety check use, against a
plain cell-by-cell measurement (`pairs_square_distance`): `segment_clearance` (one
segment, plain floats per cell) and `segment_square_distance` (many, broadcast)."""

from __future__ import annotations

import numpy as np

from planner.geometry.clearance import segment_square_distance
from planner.geometry.squares import pairs_square_distance, segment_clearance


def _segments(rng: np.random.Generator, n: int, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Random segments, a third of them along an axis, some on cell edges, some points."""
    p0 = rng.uniform(-1.0, size, (n, 2))
    p1 = p0 + rng.normal(0.0, 4.0, (n, 2))
    along = rng.random(n) < 0.33
    p1[along, 1] = p0[along, 1]
    edge = rng.random(n) < 0.2
    p0[edge] = np.round(p0[edge]) + 0.5
    p1[edge, 0] = np.round(p1[edge, 0]) + 0.5
    point = rng.random(n) < 0.05
    p1[point] = p0[point]
    return p0, p1


def test_segment_clearance_is_the_least_square_distance() -> None:
    rng = np.random.default_rng(7)
    blocked = rng.random((30, 30)) < 0.15
    cells = np.argwhere(blocked)
    p0, p1 = _segments(rng, 400, 30)
    for a, b in zip(p0, p1, strict=True):
        got = segment_clearance(a, b, blocked)
        k = len(cells)
        gaps, _ = pairs_square_distance(np.tile(a, (k, 1)), np.tile(b, (k, 1)), cells)
        reference = float(gaps.min())
        if reference <= 0.5:
            assert abs(got - reference) <= 1e-9, (a, b, got, reference)
            assert (got == 0.0) == (reference == 0.0)
        else:
            assert got > 0.5 - 1e-9


def test_segment_square_distance_matches_pairs() -> None:
    rng = np.random.default_rng(8)
    cells = rng.integers(0, 12, (9, 2))
    p0, p1 = _segments(rng, 60, 12)
    grid = segment_square_distance(p0[:, None, :], p1[:, None, :], cells[None].astype(float))
    assert grid.shape == (60, 9)
    for k in range(len(cells)):
        column = np.tile(cells[k], (len(p0), 1))
        reference, _ = pairs_square_distance(p0, p1, column)
        assert np.allclose(grid[:, k], reference, rtol=0.0, atol=1e-9)
