"""The fleet's lone paths shaped together (`pull_strings`, `tighten_all`, d75cb27) give,
bit for bit, what shaping each path alone gives: the one-path wrappers (`pull_string`,
`tighten`) and a copy of the per-path code they replaced (`_reference_pull`,
`_reference_tighten`, from before d75cb27, kept here as the oracle). Batches of more
than `FEW` paths take `_sees`' vectorised branch, which one path alone never takes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from planner.experiments.scenario_generator import random_scenario
from planner.flows import lone_paths
from planner.flows.budget import Budget
from planner.geometry.clearance import SQUARE_REACH, distance_to_polyline
from planner.geometry.grid_search import GridGraph
from planner.geometry.squares import segment_clearance
from planner.model.trajectory import merge_collinear
from planner.search.any_angle import (
    FEW,
    pull_string,
    pull_strings,
    segments_clearance,
    tighten,
    tighten_all,
)

Array = NDArray[np.float64]
Blocked = NDArray[np.bool_]

# Radii at which a shortcut between cell centres can pass a square at (to the last bits)
# its clearance, the decisions `_sees` hands back to `segment_clearance`: the line
# (0, 0)-(2, 1) passes the corner (1.5, 0.5) at 0.5/√5, (0, 0)-(3, 1) passes (2.5, 0.5)
# at 1/√10, an axis-parallel one passes a neighbouring row's squares at 0.5 (`WITHIN`).
TIES = (0.5 / math.sqrt(5.0), 1.0 / math.sqrt(10.0), 0.5)
RADII = (0.2, 0.25, 0.3, 0.45, 0.4999995, *TIES)


# -- the oracle: the per-path shaping as it was before d75cb27 ------------------------


def _reference_pull(cells: Array, radius: float, blocked: Blocked) -> Array:
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
        hi = n
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


def _reference_tighten(
    points: Array, clearance: float, blocked: Blocked, sweeps: int = 2, steps: int = 10
) -> Array:
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
            cells = _reference_cells_in(pts[i - 1 : i + 2], clearance, blocked)
            k = len(candidates)
            starts, ends = np.empty((2 * k, 2)), np.empty((2 * k, 2))
            starts[:k], starts[k:], ends[:k], ends[k:] = a, candidates, candidates, b
            clear = segments_clearance(starts, ends, cells)
            ok = np.flatnonzero((clear[:k] >= clearance) & (clear[k:] >= clearance))
            if len(ok) and np.hypot(*(candidates[ok[0]] - v)) > 1e-6:
                pts[i] = candidates[ok[0]]
                moved.add(i)
        todo = {j for i in moved for j in (i - 1, i + 1) if 0 < j < len(pts) - 1}
        if not todo:
            break
    keep = [pts[0]]
    for i in range(1, len(pts) - 1):
        if segment_clearance(keep[-1], pts[i + 1], blocked) < clearance:
            keep.append(pts[i])
    keep.append(pts[-1])
    return np.array(keep)


def _reference_cells_in(points: Array, clearance: float, blocked: Blocked) -> NDArray[np.int64]:
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


# -- grids and paths ------------------------------------------------------------------


def _grid_paths(seed: int, size: int, count: int, share: float) -> tuple[Blocked, list[Array]]:
    """A seeded random grid and the shortest grid paths between `count` random pairs of
    its free cells (unreachable pairs skipped), as the flow feeds them to the shaping."""
    rng = np.random.default_rng(seed)
    blocked = rng.random((size, size)) < share
    graph = GridGraph.build(blocked)
    free = np.argwhere(~blocked)
    paths = []
    for _ in range(count):
        a, b = rng.choice(len(free), 2, replace=False)
        _, cells = graph.route(
            (int(free[a][0]), int(free[a][1])), (int(free[b][0]), int(free[b][1]))
        )
        if cells is not None:
            paths.append(merge_collinear(np.array(cells, dtype=float)))
    return blocked, paths


def _assert_same(got: list[Array], want: list[Array]) -> None:
    assert len(got) == len(want)
    for k, (g, w) in enumerate(zip(got, want, strict=True)):
        assert g.shape == w.shape, f"path {k}: {g.shape} != {w.shape}"
        assert np.array_equal(g, w), f"path {k} differs:\n{g}\n!=\n{w}"


def _check(
    paths: list[Array], radii: list[float], blocked: Blocked, tight_too: bool = True
) -> None:
    """Batched, one-by-one and the oracle agree exactly, on the pulled strings and on
    the tightened polylines (tightened with `STORED_SHIFT` as `lone_paths.shaped` does)."""
    pulled = pull_strings(paths, radii, blocked)
    _assert_same(pulled, [pull_string(p, r, blocked) for p, r in zip(paths, radii, strict=True)])
    _assert_same(
        pulled, [_reference_pull(p, r, blocked) for p, r in zip(paths, radii, strict=True)]
    )
    if not tight_too:
        return
    clearances = [r + lone_paths.STORED_SHIFT for r in radii]
    tight = tighten_all(pulled, clearances, blocked)
    one_by_one = [tighten(p, c, blocked) for p, c in zip(pulled, clearances, strict=True)]
    _assert_same(tight, one_by_one)
    oracle = [_reference_tighten(p, c, blocked) for p, c in zip(pulled, clearances, strict=True)]
    _assert_same(tight, oracle)


# -- the tests ------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_random_fleet_shaped_together_is_shaped_as_each_path_alone(seed: int) -> None:
    blocked, paths = _grid_paths(seed, size=24, count=30, share=(0.1, 0.2, 0.3, 0.35)[seed])
    assert len(paths) > FEW  # the vectorised branch
    rng = np.random.default_rng(100 + seed)
    radii = [float(r) for r in rng.choice(RADII, len(paths))]
    _check(paths, radii, blocked)


def test_the_flows_shaping_of_a_random_scenario_is_each_uavs_alone() -> None:
    """`lone_paths.shaped` (batches of `AT_ONCE`) on a generated scenario, against each
    UAV's path pulled and tightened alone."""
    scenario = random_scenario(5, size=30, uavs=40, obstacle_share=0.2, objects=8)
    obstacles = scenario.blocked()
    blocked = obstacles.copy()
    for x, y in scenario.object_cells():
        blocked[x, y] = True
    found, _, _ = lone_paths.routes(scenario, obstacles, blocked, Budget(None))
    got = lone_paths.shaped(scenario, found, blocked, Budget(None))
    for u in scenario.uavs:
        cells = merge_collinear(np.array(found[u.id], dtype=float))
        alone = _reference_tighten(
            _reference_pull(cells, u.radius, blocked), u.radius + lone_paths.STORED_SHIFT, blocked
        )
        assert np.array_equal(got[u.id], alone), u.id


def test_a_batch_of_one_is_the_path_alone() -> None:
    blocked, paths = _grid_paths(7, size=20, count=1, share=0.25)
    _check(paths, [0.3], blocked)


def test_two_point_paths_are_kept_as_they_are_among_longer_ones() -> None:
    blocked, paths = _grid_paths(8, size=20, count=8, share=0.2)
    blocked[0, 0] = blocked[0, 1] = blocked[3, 3] = blocked[4, 4] = False
    blocked[3, 4] = blocked[4, 3] = False  # the diagonal step cuts no corner
    two = [np.array([[0.0, 0.0], [0.0, 1.0]]), np.array([[3.0, 3.0], [4.0, 4.0]])]
    batch = [two[0], *paths[:3], two[1], *paths[3:]]
    radii = [0.3] * len(batch)
    _check(batch, radii, blocked)
    pulled = pull_strings(batch, radii, blocked)
    assert np.array_equal(pulled[0], two[0]) and np.array_equal(pulled[4], two[1])
    tight = tighten_all(two, [0.3, 0.3], blocked)
    assert np.array_equal(tight[0], two[0]) and np.array_equal(tight[1], two[1])


def test_paths_round_obstacle_corners_at_their_clearance_exactly() -> None:
    """Paths that bend round blocked cells' corners, some shortcuts passing a corner at
    the radius itself (to the last bits): the decisions `_sees` hands to
    `segment_clearance`, batched, alone and in the oracle."""
    blocked = np.zeros((16, 16), dtype=bool)
    blocked[2, 0] = True  # (0, 0)-(4, 2) passes its corner (1.5, 0.5) at 0.5/√5
    blocked[3, 6] = True  # (0, 6)-(6, 8) passes its corner (2.5, 6.5) at 1/√10
    blocked[8:11, 10] = True  # a wall whose end corners two paths round
    blocked[12, 3] = blocked[13, 4] = True  # diagonal neighbours: a corner to a corner
    paths = [
        np.array([[0, 0], [1, 1], [2, 2], [3, 2], [4, 2]], dtype=float),
        np.array([[0, 6], [1, 7], [2, 8], [3, 8], [4, 8], [5, 8], [6, 8]], dtype=float),
        np.array([[7, 9], [8, 9], [9, 9], [10, 9], [11, 9], [11, 10], [11, 11]], dtype=float),
        np.array([[11, 11], [10, 11], [9, 11], [8, 11], [7, 11], [7, 10], [7, 9]], dtype=float),
        np.array([[11, 2], [12, 2], [13, 2], [14, 3], [14, 4], [14, 5]], dtype=float),
        np.array([[11, 3], [11, 4], [12, 5], [13, 5], [14, 6]], dtype=float),
    ]
    ties = [
        segment_clearance(np.array([0.0, 0.0]), np.array([4.0, 2.0]), blocked),
        segment_clearance(np.array([0.0, 6.0]), np.array([6.0, 8.0]), blocked),
    ]
    assert ties == pytest.approx([0.5 / math.sqrt(5.0), 1.0 / math.sqrt(10.0)], abs=1e-12)
    for path in paths:  # each a valid grid path: free cells, no corner cut
        assert lone_paths.valid([(int(x), int(y)) for x, y in path], blocked)
    # At the measured tie a shortcut is clear, a last bit above it is not.
    near_ties = [np.nextafter(t, side) for t in ties for side in (0.0, 1.0)]
    for radius in [*RADII, *ties, *near_ties]:
        _check(paths, [float(radius)] * len(paths), blocked)
    assert len(pull_string(paths[0], ties[0], blocked)) == 2
    assert len(pull_string(paths[0], float(np.nextafter(ties[0], 1.0)), blocked)) == 3
    _check(paths, list(RADII[: len(paths)]), blocked)


def test_radii_beyond_segment_clearances_reach_are_decided_as_alone() -> None:
    """`segment_clearance` measures only the cells near a segment (inf without one): at
    radii beyond half a cell a batch must decide as it does, not by the true distance
    (`WITHIN`). These grids have shortcuts where the two differ. A UAV's radius stays
    below half a cell, so only the strings are pulled that wide; tightened, a clearance
    reaches half a cell with `STORED_SHIFT` (0.4999995 + 1e-6)."""
    for seed, share in ((6, 0.2), (5, 0.1)):
        blocked, paths = _grid_paths(seed, size=20, count=10, share=share)
        for radius in (0.6, 0.8, 1.0, 1.5):
            _check(paths, [radius] * len(paths), blocked, tight_too=False)
        _check(paths, [0.5, 0.6, 1.0, 1.5, 0.5, 0.6, 1.0, 1.5, 0.3, 0.45], blocked, tight_too=False)
        _check(paths, [0.4999995] * len(paths), blocked)


def test_an_empty_batch_is_empty() -> None:
    blocked = np.zeros((4, 4), dtype=bool)
    assert pull_strings([], [], blocked) == []
    assert tighten_all([], [], blocked) == []


@settings(max_examples=20, deadline=None, derandomize=True)
@given(
    seed=st.integers(0, 10_000),
    share=st.sampled_from([0.0, 0.15, 0.3]),
    count=st.integers(1, 12),
    radii=st.lists(st.sampled_from(RADII), min_size=12, max_size=12),
)
def test_any_batch_is_shaped_as_its_paths_alone(
    seed: int, share: float, count: int, radii: list[float]
) -> None:
    blocked, paths = _grid_paths(seed, size=14, count=count, share=share)
    _check(paths, radii[: len(paths)], blocked)
