"""Moth-flame optimization (Mirjalili 2015), as the authors' MFO.m."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from planner.optimizers.algorithm import Algorithm, Best
from planner.optimizers.problem import Problem


@dataclass(repr=False)
class MFO(Algorithm):
    """Moths fly logarithmic spirals around flames, the best positions found so far."""

    name = "mfo"
    spiral_shape: float = 1.0  # b in eq. (3.12)

    def iterate(
        self, problem: Problem, population: int, iterations: int, rng: np.random.Generator
    ) -> Iterator[Best]:
        n, d = population, problem.dim
        moths = problem.random_population(n, rng)
        flames = np.empty((0, d))
        flame_costs = np.empty(0)
        for t in range(1, iterations + 1):
            # Eq. (3.14), rounding halves up like MATLAB's round (Python's rounds to even).
            flame_no = math.floor(n - t * (n - 1) / iterations + 0.5)
            moths = problem.clip(moths)
            costs = problem.evaluate(moths)
            # Flames: the best n of the moths and the previous flames. MFO.m merges the
            # positions it stored one iteration earlier (a one-iteration lag); EvoloPy, by
            # aliasing the same array, merges the moths just evaluated, as the paper says.
            # We follow the paper and EvoloPy.
            pool = np.concatenate([moths, flames])
            pool_costs = np.concatenate([costs, flame_costs])
            keep = np.argsort(pool_costs, kind="stable")[:n]
            flames, flame_costs = pool[keep], pool_costs[keep]
            yield Best(flames[0].copy(), float(flame_costs[0]))

            r = -1.0 - t / iterations  # -1 -> -2
            spiral_t = (r - 1.0) * rng.random((n, d)) + 1.0
            # Eq. (3.13): the distance is to flame i for every moth, but moths beyond the
            # flame count spiral around the last flame (MFO.m's indexing, kept).
            distance = np.abs(flames - moths)
            anchor = flames[np.minimum(np.arange(n), flame_no - 1)]
            moths = (  # eq. (3.12)
                distance * np.exp(self.spiral_shape * spiral_t) * np.cos(2.0 * np.pi * spiral_t)
                + anchor
            )
