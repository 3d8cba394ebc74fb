"""Ant lion optimizer (Mirjalili 2015), as the authors' ALO.m."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.optimizers.algorithm import Algorithm, Best
from planner.optimizers.problem import Problem
from planner.optimizers.random_walk import random_walks
from planner.optimizers.roulette import roulette_wheel


@dataclass(repr=False)
class ALO(Algorithm):
    """Ants random-walk around a roulette-chosen antlion and the elite; antlions keep the best."""

    name = "alo"

    def iterate(
        self, problem: Problem, population: int, iterations: int, rng: np.random.Generator
    ) -> Iterator[Best]:
        n = population
        antlions = problem.random_population(n, rng)
        fitness = problem.evaluate(antlions)
        order = np.argsort(fitness, kind="stable")
        antlions, fitness = antlions[order], fitness[order]
        elite = Best(antlions[0].copy(), float(fitness[0]))
        # ALO.m spends its first iteration evaluating the antlions, so the ants move
        # T - 1 times and the run costs N * T evaluations.
        yield elite
        for t in range(2, iterations + 1):
            with np.errstate(divide="ignore"):
                chosen = roulette_wheel(1.0 / fitness, n, rng)
            ants = 0.5 * (  # eq. (2.13)
                self._walk(problem, antlions[chosen], t, iterations, rng)
                + self._walk(problem, np.broadcast_to(elite.x, antlions.shape), t, iterations, rng)
            )
            ants = problem.clip(ants)
            ant_fitness = problem.evaluate(ants)

            # Antlions catch the ants that became fitter (eq. 2.14): best n of both.
            # ALO.m never refreshes `sorted_antlion_fitness` inside its loop, so its
            # merge and roulette keep using the initial antlions' fitness for ever; we
            # treat that as a bookkeeping slip and track each antlion's own fitness.
            pool = np.concatenate([antlions, ants])
            pool_fitness = np.concatenate([fitness, ant_fitness])
            keep = np.argsort(pool_fitness, kind="stable")[:n]
            antlions, fitness = pool[keep], pool_fitness[keep]
            if fitness[0] < elite.cost:
                elite = Best(antlions[0].copy(), float(fitness[0]))
            antlions[0], fitness[0] = elite.x, elite.cost  # elitism
            yield elite

    @staticmethod
    def _walk(
        problem: Problem,
        centres: NDArray[np.float64],
        t: int,
        iterations: int,
        rng: np.random.Generator,
    ) -> NDArray[np.float64]:
        """One point of `Random_walk_around_antlion.m` for each row of `centres`."""
        n, d = centres.shape
        ratio = _shrink_ratio(t, iterations)
        # Eq. (2.8)-(2.9): one sign draw per walk for each bound, shared by all dimensions.
        lo_sign = np.where(rng.random(n) < 0.5, 1.0, -1.0)[:, None]
        hi_sign = np.where(rng.random(n) >= 0.5, 1.0, -1.0)[:, None]
        lo = lo_sign * problem.lower / ratio + centres
        hi = hi_sign * problem.upper / ratio + centres
        # Eq. (2.1) walks of T steps, read after t - 1 steps (MATLAB's RWs(t, :)).
        value, a, b = random_walks(rng, n * d, iterations, t - 1)
        value, a, b = (v.reshape(n, d) for v in (value, a, b))
        return (value - a) * (hi - lo) / (b - a) + lo  # eq. (2.7)


def _shrink_ratio(t: int, iterations: int) -> float:
    """I in eq. (2.10)-(2.11). ALO.m uses 1 + 10^w t/T (the paper writes 10^w t/T)."""
    progress = t / iterations
    ratio = 1.0
    for threshold, w in ((0.1, 2), (0.5, 3), (0.75, 4), (0.9, 5), (0.95, 6)):
        if progress > threshold:
            ratio = 1.0 + 10.0**w * progress
    return ratio
