"""Multi-verse optimizer (Mirjalili, Mirjalili & Hatamlou 2016), as the authors' MVO.m."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.optimizers.algorithm import Algorithm, Best, track_best
from planner.optimizers.problem import Problem
from planner.optimizers.roulette import roulette_wheel


@dataclass(repr=False)
class MVO(Algorithm):
    """White/black-hole exchange by normalised inflation rate, wormholes around the best universe.

    Rows are universes; the cost is the inflation rate (lower is better).
    """

    name = "mvo"
    wep_min: float = 0.2
    wep_max: float = 1.0
    exploitation_accuracy: float = 6.0  # p in the TDR schedule

    def iterate(
        self, problem: Problem, population: int, iterations: int, rng: np.random.Generator
    ) -> Iterator[Best]:
        n, d = population, problem.dim
        universes = problem.random_population(n, rng)
        best: Best | None = None
        for t in range(1, iterations + 1):
            # Eq. (3.3) and (3.4): wormhole existence probability and travelling distance rate.
            wep = self.wep_min + t * (self.wep_max - self.wep_min) / iterations
            p = 1.0 / self.exploitation_accuracy
            tdr = 1.0 - t**p / iterations**p
            universes = problem.clip(universes)
            costs = problem.evaluate(universes)
            best = track_best(best, universes, costs)
            yield best

            order = np.argsort(costs, kind="stable")
            sorted_costs, sorted_universes = costs[order], universes[order]
            inflation = _normr(sorted_costs)
            # MVO.m overwrites row 1 with the best universe but leaves rows 2..n unsorted,
            # while pairing row i with the normalised inflation rate of sorted rank i.
            universes[0] = sorted_universes[0]
            rest = universes[1:]

            # Eq. (3.1): white/black-hole tunnels exchange objects (coordinates).
            exchange = rng.random((n - 1, d)) < inflation[1:, None]
            rows, cols = np.nonzero(exchange)
            white = roulette_wheel(-sorted_costs, rows.size, rng)
            rest[rows, cols] = sorted_universes[white, cols]

            # Eq. (3.2): wormholes move coordinates around the best universe by
            # TDR * ((ub - lb) * rand + lb), each side with probability 1/2.
            tunnel = rng.random((n - 1, d)) < wep
            side = rng.random((n - 1, d))
            step = tdr * (problem.span * rng.random((n - 1, d)) + problem.lower)
            rest[:] = np.where(tunnel & (side < 0.5), best.x + step, rest)
            rest[:] = np.where(tunnel & (side > 0.5), best.x - step, rest)


def _normr(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """MATLAB's `normr` on a row vector; an all-zero row stays zero (no exchange) instead of NaN."""
    norm = np.linalg.norm(v)
    return v / norm if norm > 0 else np.zeros_like(v)
