"""The small interface the six metaheuristics share."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator
from typing import ClassVar, NamedTuple

import numpy as np
from numpy.typing import NDArray

from planner.optimizers.problem import Problem


class Best(NamedTuple):
    """The best solution an algorithm has evaluated so far."""

    x: NDArray[np.float64]
    cost: float


class Algorithm(ABC):
    """A population-based minimiser driven one iteration at a time.

    `iterate` is a generator so that the caller (`planner.optimize`) owns the loop:
    it records history, reports progress and may stop early without each algorithm
    re-implementing that bookkeeping.
    """

    name: ClassVar[str]
    min_population: ClassVar[int] = 2

    @abstractmethod
    def iterate(
        self, problem: Problem, population: int, iterations: int, rng: np.random.Generator
    ) -> Iterator[Best]:
        """Run `iterations` iterations, yielding the best-so-far after each one."""

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in vars(self).items())
        return f"{type(self).__name__}({params})"


def track_best(best: Best | None, x: NDArray[np.float64], costs: NDArray[np.float64]) -> Best:
    """Keep the best-ever solution; a tie keeps the older one (the references' strict `<`)."""
    i = int(np.argmin(costs))
    if best is None or costs[i] < best.cost:
        return Best(x[i].copy(), float(costs[i]))
    return best
