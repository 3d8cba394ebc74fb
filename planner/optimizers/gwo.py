"""Grey wolf optimizer (Mirjalili, Mirjalili & Lewis 2014), as the authors' GWO.m."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.optimizers.algorithm import Algorithm, Best
from planner.optimizers.problem import Problem


@dataclass(repr=False)
class GWO(Algorithm):
    """Every wolf moves to the mean of three pulls toward the alpha, beta and delta wolves."""

    name = "gwo"
    min_population = 3
    # GWO.m keeps an old alpha when a better wolf arrives instead of demoting it to beta.
    # EvoloPy demotes it (the leaders are then truly the best three distinct wolves so far).
    demote_leaders: bool = False

    def iterate(
        self, problem: Problem, population: int, iterations: int, rng: np.random.Generator
    ) -> Iterator[Best]:
        n, d = population, problem.dim
        wolves = problem.random_population(n, rng)
        leaders = np.zeros((3, d))
        scores = np.full(3, np.inf)
        for t in range(iterations):
            wolves = problem.clip(wolves)
            costs = problem.evaluate(wolves)
            update = _rank_leaders if self.demote_leaders else _update_leaders
            update(leaders, scores, wolves, costs)
            yield Best(leaders[0].copy(), float(scores[0]))

            a = 2.0 - t * 2.0 / iterations  # decreases linearly from 2 to 0
            # Eq. (3.3)-(3.7): per-coordinate A and C for each of the three leaders.
            r1 = rng.random((3, n, d))
            r2 = rng.random((3, n, d))
            big_a = 2.0 * a * r1 - a
            big_c = 2.0 * r2
            dist = np.abs(big_c * leaders[:, None, :] - wolves)
            wolves = (leaders[:, None, :] - big_a * dist).mean(axis=0)


def _update_leaders(
    leaders: NDArray[np.float64],
    scores: NDArray[np.float64],
    wolves: NDArray[np.float64],
    costs: NDArray[np.float64],
) -> None:
    """GWO.m's sequential alpha/beta/delta update, computed without a loop over wolves.

    GWO.m visits the wolves in order and, for each, replaces alpha if better; else beta
    if strictly between alpha and beta; else delta if strictly between beta and delta.
    A new alpha does not demote the old one to beta (a quirk of the code we keep). Each
    leader is therefore a running minimum over the wolves that pass its test, so its
    final value is the first minimum among those wolves.
    """
    alpha_run = np.minimum.accumulate(np.minimum(costs, scores[0]))
    beta_pool = np.where(costs > alpha_run, costs, np.inf)
    beta_run = np.minimum.accumulate(np.minimum(beta_pool, scores[1]))
    delta_pool = np.where((costs > alpha_run) & (costs > beta_run), costs, np.inf)
    for k, pool in enumerate((costs, beta_pool, delta_pool)):
        i = int(np.argmin(pool))
        if pool[i] < scores[k]:
            scores[k] = pool[i]
            leaders[k] = wolves[i]


def _rank_leaders(
    leaders: NDArray[np.float64],
    scores: NDArray[np.float64],
    wolves: NDArray[np.float64],
    costs: NDArray[np.float64],
) -> None:
    """EvoloPy's update: a better wolf pushes the others down, equal costs are not inserted.

    Inserting wolf after wolf into a sorted top three with strict comparisons leaves the
    three smallest distinct costs, each held by the first wolf that reached it.
    """
    pool = np.concatenate([scores, costs])
    values, first = np.unique(pool, return_index=True)
    k = min(3, values.size)
    scores[:k] = values[:k]
    leaders[:k] = np.concatenate([leaders, wolves])[first[:k]]
