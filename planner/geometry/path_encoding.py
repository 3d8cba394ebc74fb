"""How a row of the optimizer's population becomes a path for one UAV.

Two encodings, one per objective:

- `DetourEncoding` (qos): the UAV's current path, as a polyline of base points (its
  turning points plus points every couple of cells), moved point by point by an
  offset, with a hover time at each point. Genes near zero mean "no offset" and
  negative wait genes mean "no hover", so the unchanged path and its parts are
  easy to hit exactly.
- `TurnEncoding` (paper): the paper's rule. At one step of its path the UAV turns by
  one grid cell to the left or right and flies parallel to its old path from there,
  so it ends one cell from where that path ended.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.model.trajectory import merge_collinear

Array = NDArray[np.float64]
DEAD_ZONE = 0.3  # share of each offset gene's half-range that means "no offset"


@dataclass(frozen=True)
class DetourEncoding:
    start: Array  # (2,)
    goal: Array  # (2,)
    base: Array  # (K, 2) interior base points
    max_offset: float = 1.5  # cells
    max_wait: float = 10.0  # seconds per hover
    # A window of a longer path: flown unchanged (no hover) before `start` and after
    # `goal`; (B, 2) ending at `start` and (A, 2) beginning at `goal`. None: no window.
    before: Array | None = None
    after: Array | None = None

    @classmethod
    def around(
        cls,
        path: Array,
        points: int = 10,
        max_offset: float = 1.5,
        max_wait: float = 10.0,
        before: Array | None = None,
        after: Array | None = None,
    ) -> DetourEncoding:
        """Base points on `path` (cells or waypoints): its corners plus about `points` more
        spread along it, at least 2 cells apart, so a straight stretch can still bend."""
        corners = merge_collinear(path)
        total = float(np.hypot(*np.diff(corners, axis=0).T).sum()) if len(corners) > 1 else 0.0
        spacing = max(2.0, total / points)
        spread = [corners[0]]
        for a, b in itertools.pairwise(corners):
            pieces = max(1, int(np.ceil(np.hypot(*(b - a)) / spacing)))
            spread.extend(a + (b - a) * k / pieces for k in range(1, pieces + 1))
        base = np.array(spread)
        return cls(base[0], base[-1], base[1:-1], max_offset, max_wait, before, after)

    @property
    def dim(self) -> int:
        return 3 * len(self.base) + 1

    def bounds(self) -> tuple[Array, Array]:
        return -np.ones(self.dim), np.ones(self.dim)

    def _fixed(self) -> list[Array]:
        return [p for p in (self.before, self.after) if p is not None]

    def region(self) -> tuple[Array, Array]:
        """A box that holds every path this encoding can produce."""
        points = np.vstack([self.start, self.goal, self.base, *self._fixed()])
        reach = self.max_offset if len(self.base) else 0.0
        return points.min(axis=0) - reach, points.max(axis=0) + reach

    def corridor(self) -> tuple[Array, float]:
        """The base polyline and how far any decoded path can stray from it: each point
        moves by at most max_offset per axis, and a leg between two moved points stays
        within the larger of their moves of the leg between the unmoved ones."""
        parts = [self.start[None], self.base, self.goal[None]]
        if self.before is not None:
            parts.insert(0, self.before[:-1])
        if self.after is not None:
            parts.append(self.after[1:])
        polyline = np.vstack(parts)
        return polyline, float(np.sqrt(2.0) * self.max_offset) if len(self.base) else 0.0

    def unchanged(self) -> Array:
        """Genes that decode to the base path with no hovering."""
        genes = np.zeros(self.dim)
        genes[2 * len(self.base) :] = -1.0
        return genes

    def decode(self, genes: Array) -> tuple[Array, Array]:
        """Waypoints (N, K + 2, 2) and hover times (N, K + 2) of a population (N, dim);
        with a window, the fixed points before and after it (without hovers) as well."""
        n, k = genes.shape[0], len(self.base)
        raw = genes[:, : 2 * k].reshape(n, k, 2)
        offset = np.sign(raw) * np.maximum(np.abs(raw) - DEAD_ZONE, 0.0) / (1 - DEAD_ZONE)
        interior = self.base[None] + self.max_offset * offset
        waypoints = np.concatenate(
            [
                np.broadcast_to(self.start, (n, 1, 2)),
                interior,
                np.broadcast_to(self.goal, (n, 1, 2)),
            ],
            axis=1,
        )
        waits = np.zeros((n, k + 2))
        waits[:, : k + 1] = self.max_wait * np.maximum(genes[:, 2 * k :], 0.0)
        if self.before is None and self.after is None:
            return waypoints, waits
        head = np.zeros((0, 2)) if self.before is None else self.before[:-1]
        tail = np.zeros((0, 2)) if self.after is None else self.after[1:]
        waypoints = np.concatenate(
            [
                np.broadcast_to(head, (n, *head.shape)),
                waypoints,
                np.broadcast_to(tail, (n, *tail.shape)),
            ],
            axis=1,
        )
        waits = np.concatenate([np.zeros((n, len(head))), waits, np.zeros((n, len(tail)))], axis=1)
        return waypoints, waits


@dataclass(frozen=True)
class TurnEncoding:
    cells: Array  # (M, 2) the current path, one grid step at a time
    # A UAV that has turned before keeps turning the same way (by this grid step), so
    # each turn adds a grid of deviation, as in the paper's cases III and IV.
    same_way: Array | None = None

    @property
    def dim(self) -> int:
        return 2

    def bounds(self) -> tuple[Array, Array]:
        return np.array([0.0, -1.0]), np.array([1.0, 1.0])

    def region(self) -> tuple[Array, Array]:
        return self.cells.min(axis=0) - 1.0, self.cells.max(axis=0) + 1.0

    def decode(self, genes: Array) -> tuple[Array, Array]:
        """Gene 0 picks the step where the UAV turns, gene 1's sign the side."""
        steps = len(self.cells) - 1
        n = genes.shape[0]
        if steps < 1:
            return np.broadcast_to(self.cells, (n, *self.cells.shape)).copy(), np.zeros(
                (n, len(self.cells))
            )
        turn = np.minimum((genes[:, 0] * steps).astype(int), steps - 1)  # step turn -> turn+1
        heading = self.cells[turn + 1] - self.cells[turn]  # (N, 2)
        if self.same_way is not None:
            lateral = np.broadcast_to(self.same_way, (n, 2))
        else:
            side = np.where(genes[:, 1] >= 0, 1.0, -1.0)[:, None]
            lateral = side * np.column_stack([-heading[:, 1], heading[:, 0]])  # left or right
        after = np.arange(len(self.cells))[None, :] > turn[:, None]
        waypoints = self.cells[None] + after[..., None] * lateral[:, None, :]
        return waypoints, np.zeros((n, len(self.cells)))


def grid_steps(waypoints: Array) -> Array:
    """A path through grid cells, split into single steps (for the turn rule)."""
    cells = [np.asarray(waypoints[0], dtype=float)]
    for a, b in itertools.pairwise(waypoints):
        count = round(np.max(np.abs(b - a)))
        cells.extend(a + (b - a) * k / count for k in range(1, count + 1))
    return np.round(np.array(cells), 9)
