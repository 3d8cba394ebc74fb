"""Whale optimization algorithm (Mirjalili & Lewis 2016), as the authors' WOA.m."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.optimizers.algorithm import Algorithm, Best, track_best
from planner.optimizers.problem import Problem


@dataclass(repr=False)
class WOA(Algorithm):
    """Encircling, searching around a random whale, and the bubble-net spiral."""

    name = "woa"
    spiral_shape: float = 1.0  # b in eq. (2.5)

    def iterate(
        self, problem: Problem, population: int, iterations: int, rng: np.random.Generator
    ) -> Iterator[Best]:
        n, d = population, problem.dim
        whales = problem.random_population(n, rng)
        best: Best | None = None
        for t in range(iterations):
            whales = problem.clip(whales)
            costs = problem.evaluate(whales)
            best = track_best(best, whales, costs)
            yield best

            a = 2.0 - t * 2.0 / iterations  # 2 -> 0, eq. (2.3)
            a2 = -1.0 - t / iterations  # -1 -> -2, for l
            # One A, C, l and p per whale, as WOA.m draws them outside the dimension loop.
            r1, r2, r3, p = rng.random((4, n))
            big_a = 2.0 * a * r1 - a  # eq. (2.3)
            big_c = 2.0 * r2  # eq. (2.4)
            # The paper takes l in [-1, 1]; WOA.m draws it in [a2, 1], which we follow.
            spiral_l = (a2 - 1.0) * r3 + 1.0
            a_col, c_col = big_a[:, None], big_c[:, None]
            spiral = (  # eq. (2.5)
                np.abs(best.x - whales)
                * np.exp(self.spiral_shape * spiral_l)[:, None]
                * np.cos(2.0 * np.pi * spiral_l)[:, None]
                + best.x
            )
            encircle = best.x - a_col * np.abs(c_col * best.x - whales)  # eq. (2.1)
            fixed = np.where((p < 0.5)[:, None], encircle, spiral)
            searching = (p < 0.5) & (np.abs(big_a) >= 1.0)
            if not searching.any():  # always so once a < 1, in the second half of the run
                whales = fixed
                continue
            # WOA.m draws the random whale anew for every coordinate.
            partner = rng.integers(0, n, size=(n, d))
            whales = _search_in_order(whales, fixed, searching, partner, a_col, c_col)


def _search_in_order(
    whales: NDArray[np.float64],
    fixed: NDArray[np.float64],
    searching: NDArray[np.bool_],
    partner: NDArray[np.intp],
    a_col: NDArray[np.float64],
    c_col: NDArray[np.float64],
) -> NDArray[np.float64]:
    """New positions with eq. (2.8) for the searching whales, exactly as WOA.m's in-place loop.

    WOA.m moves whales one after another, so a whale searching around a partner that
    has already moved (a lower index) reads the partner's new coordinate. A coordinate
    depends only on the same coordinate of an earlier whale, so these chains are short
    (about log n on average). Repeating the vectorised update until the partners' values
    stop changing resolves them in as many rounds as the longest chain, giving exactly
    the sequential result without a loop over whales.
    """
    rows = np.flatnonzero(searching)
    cols = np.arange(whales.shape[1])
    partners = partner[rows]
    moved_before = partners < rows[:, None]
    old = whales[partners, cols]
    a, c, own = a_col[rows], c_col[rows], whales[rows]
    new = fixed.copy()
    source = old
    for _ in range(rows.size + 1):
        new[rows] = source - a * np.abs(c * source - own)
        updated = np.where(moved_before, new[partners, cols], old)
        if np.array_equal(updated, source):
            return new
        source = updated
    raise AssertionError("whale dependencies must form chains shorter than the population")
