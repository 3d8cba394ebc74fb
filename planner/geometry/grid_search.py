"""Shortest paths on the grid: 8-connected moves that never cut the corner of a blocked cell.

A diagonal step is allowed only when both cells it passes between are free, so a UAV
whose radius is below half a cell never touches a blocked cell while it follows such
a path. Distances are exact (1 per straight step, √2 per diagonal) and come from
scipy's Dijkstra on a sparse graph built in one vectorised pass.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import dijkstra

if TYPE_CHECKING:
    from planner.model.scenario import Scenario

Cell = tuple[int, int]
MOVES = np.array([(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)])


@dataclass(frozen=True)
class GridGraph:
    """The free cells of a grid and the moves between them."""

    blocked: NDArray[np.bool_]  # indexed [x, y]
    graph: csr_matrix

    @classmethod
    def build(cls, blocked: NDArray[np.bool_]) -> GridGraph:
        width, height = blocked.shape
        xs, ys = np.nonzero(~blocked)
        rows, cols, weights = [], [], []
        free = np.pad(~blocked, 1)  # padded: the outside is blocked
        for dx, dy in MOVES:
            nx, ny = xs + dx, ys + dy
            ok = free[nx + 1, ny + 1]
            if dx and dy:  # no corner cutting
                ok &= free[xs + dx + 1, ys + 1] & free[xs + 1, ys + dy + 1]
            rows.append(xs[ok] * height + ys[ok])
            cols.append(nx[ok] * height + ny[ok])
            weights.append(np.full(ok.sum(), np.hypot(dx, dy)))
        size = width * height
        graph = coo_matrix(
            (np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
            shape=(size, size),
        ).tocsr()
        return cls(blocked, graph)

    @property
    def shape(self) -> tuple[int, int]:
        width, height = self.blocked.shape
        return width, height

    def index(self, cell: Cell) -> int:
        return cell[0] * self.shape[1] + cell[1]

    def distances_to(self, goal: Cell) -> NDArray[np.float64]:
        """Shortest distance from every cell to `goal` (inf where unreachable), as [x, y]."""
        # Moves are symmetric, so distances from the goal equal distances to it.
        field = dijkstra(self.graph, indices=self.index(goal))
        distances: NDArray[np.float64] = field.reshape(self.shape)
        return distances

    def tree_to(self, goal: Cell) -> tuple[NDArray[np.float64], NDArray[np.int32]]:
        """Distances to `goal` as [x, y] and each cell's next cell towards it (flat index,
        -9999 where there is none): one Dijkstra, every start's shortest path."""
        distance, towards = dijkstra(self.graph, indices=self.index(goal), return_predecessors=True)
        return distance.reshape(self.shape), towards

    def walk(self, towards: NDArray[np.int32], start: Cell) -> list[Cell]:
        """The path from `start` along a `tree_to` tree (start must reach the goal)."""
        height = self.shape[1]
        path, at = [], self.index(start)
        while at >= 0:
            path.append((at // height, at % height))
            at = int(towards[at])
        return path

    def route(self, start: Cell, goal: Cell) -> tuple[float, list[Cell] | None]:
        """A shortest path from `start` to `goal` and its length (inf, None: cut off).

        Dijkstra on the cells whose octile distances to both ends add up to at most a
        bound B (an ellipse round the two): every path of length at most B lies inside
        it, so a path found within B is a shortest one of the whole grid. The bound
        starts 10 % above the octile distance and grows until it holds; on an open map
        the ellipse is a tenth of the grid.
        """
        span = float(_octile(np.array(start), np.array(goal)))
        for factor in (1.1, 1.5, 3.0):
            bound = factor * span + 3.0
            idx = self._ellipse(start, goal, bound, span)
            sub = self._subgraph(idx)
            to, at = np.searchsorted(idx, [self.index(goal), self.index(start)]).tolist()
            distance, towards = dijkstra(sub, indices=to, return_predecessors=True)
            if distance[at] <= bound:
                cells, nexts, height = idx.tolist(), towards.tolist(), self.shape[1]
                path, k = [], at
                while k >= 0:
                    path.append(divmod(cells[k], height))
                    k = nexts[k]
                return float(distance[at]), path
        field, towards = self.tree_to(goal)
        if not np.isfinite(field[start]):
            return float("inf"), None
        return float(field[start]), self.walk(towards, start)

    def _ellipse(self, start: Cell, goal: Cell, bound: float, span: float) -> NDArray[np.intp]:
        """Flat indices (sorted) of the free cells c with oct(start, c) + oct(c, goal) <= bound.

        On the box round the two ends, the columns' and rows' offsets broadcast against
        each other (a route is asked for every UAV: no grid of coordinates is built)."""
        pad = math.ceil((bound - span) / 2) + 1
        width, height = self.shape
        lo_x, lo_y = max(min(start[0], goal[0]) - pad, 0), max(min(start[1], goal[1]) - pad, 0)
        hi_x = min(max(start[0], goal[0]) + pad, width - 1)
        hi_y = min(max(start[1], goal[1]) + pad, height - 1)
        xs, ys = np.arange(lo_x, hi_x + 1)[:, None], np.arange(lo_y, hi_y + 1)[None, :]
        inside = _octile_apart(xs, ys, start) + _octile_apart(xs, ys, goal) <= bound
        inside &= ~self.blocked[lo_x : hi_x + 1, lo_y : hi_y + 1]
        x, y = np.nonzero(inside)
        indices: NDArray[np.intp] = (x + lo_x) * height + (y + lo_y)
        return indices

    def _subgraph(self, idx: NDArray[np.intp]) -> csr_matrix:
        """The moves among the cells `idx` (sorted): `graph[idx][:, idx]`, each row's
        entries in the same order, built from the graph's arrays in a few numpy calls
        (scipy's two fancy indexings cost several times as much on a route's ellipse)."""
        indptr, indices = self.graph.indptr, self.graph.indices
        lookup = np.full(self.graph.shape[0], -1, dtype=np.intp)
        lookup[idx] = np.arange(len(idx))
        starts = indptr[idx]
        counts = indptr[idx + 1] - starts
        index = np.repeat(starts - (np.cumsum(counts) - counts), counts) + np.arange(counts.sum())
        columns = lookup[indices[index]]
        keep = columns >= 0
        rows = np.zeros(len(idx) + 1, dtype=indptr.dtype)
        np.cumsum(
            np.bincount(np.repeat(np.arange(len(idx)), counts)[keep], minlength=len(idx)),
            out=rows[1:],
        )
        entries = (self.graph.data[index][keep], columns[keep].astype(indices.dtype), rows)
        return csr_matrix(entries, shape=(len(idx), len(idx)))

    def shortest_path(self, start: Cell, goal: Cell) -> list[Cell] | None:
        """Cells from start to goal along a shortest path, or None if the goal is cut off."""
        field = self.distances_to(goal)
        if not np.isfinite(field[start]):
            return None
        return descend(field, start, self.blocked)


def descend(field: NDArray[np.float64], start: Cell, blocked: NDArray[np.bool_]) -> list[Cell]:
    """Follow a distance field down to 0; straight moves first on ties, for tidy paths."""
    width, height = field.shape
    path = [start]
    x, y = start
    while field[x, y] > 0:
        best, best_cell = np.inf, None
        for dx, dy in MOVES:
            nx, ny = x + dx, y + dy
            if not (0 <= nx < width and 0 <= ny < height) or blocked[nx, ny]:
                continue
            if dx and dy and (blocked[x + dx, y] or blocked[x, y + dy]):
                continue
            through = field[nx, ny] + np.hypot(dx, dy)
            if through < best - 1e-9:
                best, best_cell = through, (nx, ny)
        assert best_cell is not None, "a finite distance always has a downhill neighbour"
        x, y = best_cell
        path.append(best_cell)
    return path


def _octile(a: NDArray[np.int64], b: NDArray[np.int64]) -> NDArray[np.float64]:
    """Octile distance (8-connected, diagonals √2) between cells, broadcast over (..., 2)."""
    d = np.abs(a - b)
    distance: NDArray[np.float64] = np.max(d, axis=-1) + (np.sqrt(2.0) - 1.0) * np.min(d, axis=-1)
    return distance


def _octile_apart(xs: NDArray[np.int64], ys: NDArray[np.int64], cell: Cell) -> NDArray[np.float64]:
    """`_octile` from `cell` to every (x, y) of a column `xs` and a row `ys`, broadcast."""
    dx, dy = np.abs(xs - cell[0]), np.abs(ys - cell[1])
    distance: NDArray[np.float64] = np.maximum(dx, dy) + (np.sqrt(2.0) - 1.0) * np.minimum(dx, dy)
    return distance


def cell_map(cells: Iterable[Cell], shape: tuple[int, int]) -> NDArray[np.bool_]:
    """A boolean map, indexed [x, y], that is True on `cells`."""
    grid = np.zeros(shape, dtype=bool)
    for x, y in cells:  # unpacked: a list [x, y] as an index would pick whole rows
        grid[x, y] = True
    return grid


def path_length(cells: list[Cell]) -> float:
    steps = np.diff(np.asarray(cells, dtype=float), axis=0)
    return float(np.hypot(steps[:, 0], steps[:, 1]).sum())


def shortest_lengths(scenario: Scenario) -> dict[str, float]:
    """Per-UAV shortest path length: the reference a plan's length is judged by.

    That is 8-connected, no corner cutting, objects blocked; where the objects wall
    a goal off, the obstacles-only length is used instead.
    """
    obstacles = scenario.blocked()
    with_objects = obstacles | cell_map(scenario.object_cells(), obstacles.shape)
    graphs = [GridGraph.build(with_objects), GridGraph.build(obstacles)]
    out = {}
    for u in scenario.uavs:
        for graph in graphs:
            distance = float(graph.distances_to(u.goal)[u.start])
            if np.isfinite(distance):
                break
        out[u.id] = distance
    return out
