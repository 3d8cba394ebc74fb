"""Whale optimization algorithm (Mirjalili & Lewis 2016), as the authors' WOA.m."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

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
            big_a = 2.0 * a * rng.random(n) - a  # eq. (2.3)
            big_c = 2.0 * rng.random(n)  # eq. (2.4)
            # The paper takes l in [-1, 1]; WOA.m draws it in [a2, 1], which we follow.
            spiral_l = (a2 - 1.0) * rng.random(n) + 1.0
            p = rng.random(n)
            # WOA.m draws the random whale anew for every coordinate.
            partner = whales[rng.integers(0, n, size=(n, d)), np.arange(d)]

            searching = (np.abs(big_a) >= 1.0)[:, None]
            target = np.where(searching, partner, best.x)  # eq. (2.8) or eq. (2.1)
            encircle = target - big_a[:, None] * np.abs(big_c[:, None] * target - whales)
            spiral = (  # eq. (2.5)
                np.abs(best.x - whales)
                * np.exp(self.spiral_shape * spiral_l)[:, None]
                * np.cos(2.0 * np.pi * spiral_l)[:, None]
                + best.x
            )
            # WOA.m updates whales in place, so a later whale may pull toward an earlier
            # whale's new position; updating all from the same snapshot is the vectorised
            # (synchronous) form of that step.
            whales = np.where((p < 0.5)[:, None], encircle, spiral)
