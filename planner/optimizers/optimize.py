"""The one public entry point: `optimize(algorithm, objective, lower, upper, ...)`."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.optimizers.algorithm import Algorithm
from planner.optimizers.problem import Objective, OptimizerInputError, Problem
from planner.optimizers.registry import get_algorithm


@dataclass(frozen=True)
class Progress:
    """What a callback sees after every iteration."""

    iteration: int  # 1-based
    iterations: int
    best_cost: float
    best_x: NDArray[np.float64]
    nfe: int


Callback = Callable[[Progress], bool | None]
"""Called after every iteration; returning True stops the run early."""


@dataclass(frozen=True)
class OptimizeResult:
    algorithm: str
    best_x: NDArray[np.float64]
    best_cost: float
    history: NDArray[np.float64]
    """Best cost after every iteration."""
    nfe_history: NDArray[np.int64]
    """Objective evaluations used by the end of every iteration."""
    nfe: int
    seconds: float

    @property
    def iterations(self) -> int:
        return self.history.size

    def nfe_to_reach(self, target: float) -> int | None:
        """Evaluations spent by the end of the first iteration whose best cost is <= target."""
        hit = np.flatnonzero(self.history <= target)
        return int(self.nfe_history[hit[0]]) if hit.size else None


def optimize(
    algorithm: str | Algorithm,
    objective: Objective,
    lower: ArrayLike,
    upper: ArrayLike,
    *,
    population: int,
    iterations: int,
    rng: np.random.Generator,
    callback: Callback | None = None,
    dim: int | None = None,
) -> OptimizeResult:
    """Minimise `objective` inside [lower, upper].

    The objective takes a whole population, shape (n, d), and returns its n costs;
    `lower` and `upper` are arrays of length d (or scalars with `dim=`). The same
    generator state gives the same result.
    """
    algo = get_algorithm(algorithm)
    problem = Problem.create(objective, lower, upper, dim)
    _check_budget(algo, population, iterations, rng)
    history: list[float] = []
    nfe_history: list[int] = []
    best = None
    start = time.perf_counter()
    for best in algo.iterate(problem, population, iterations, rng):
        history.append(best.cost)
        nfe_history.append(problem.nfe)
        if callback is not None:
            progress = Progress(len(history), iterations, best.cost, best.x, problem.nfe)
            if callback(progress):
                break
    seconds = time.perf_counter() - start
    assert best is not None  # iterations >= 1 guarantees one yield
    return OptimizeResult(
        algorithm=algo.name,
        best_x=best.x,
        best_cost=best.cost,
        history=np.asarray(history),
        nfe_history=np.asarray(nfe_history, dtype=np.int64),
        nfe=problem.nfe,
        seconds=seconds,
    )


def _check_budget(algo: Algorithm, population: int, iterations: int, rng: object) -> None:
    for name, value in (("population", population), ("iterations", iterations)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise OptimizerInputError(f"{name} must be an integer, got {value!r}")
    if population < algo.min_population:
        raise OptimizerInputError(
            f"{algo.name} needs a population of at least {algo.min_population}, got {population}"
        )
    if iterations < 1:
        raise OptimizerInputError(f"iterations must be at least 1, got {iterations}")
    if not isinstance(rng, np.random.Generator):
        raise OptimizerInputError(
            f"rng must be a numpy.random.Generator (numpy.random.default_rng(seed)), got {rng!r}"
        )
