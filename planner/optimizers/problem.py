"""The minimisation problem every optimizer sees: a vectorised objective inside a box."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

Objective = Callable[[NDArray[np.float64]], ArrayLike]
"""Maps a population of shape (n, d) to its costs, shape (n,)."""


class OptimizerInputError(ValueError):
    """The bounds, population size, iteration budget or generator cannot be used."""


class ObjectiveError(ValueError):
    """The objective returned something that is not one finite cost per row."""


@dataclass
class Problem:
    """Bounds plus an objective that counts its evaluations and checks its answers.

    Counting here, not in the algorithms, is what makes the NFE exact: every row
    handed to the objective is one function evaluation, whichever algorithm asks.
    """

    objective: Objective
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    nfe: int = field(default=0, init=False)

    @classmethod
    def create(
        cls, objective: Objective, lower: ArrayLike, upper: ArrayLike, dim: int | None = None
    ) -> Problem:
        if not callable(objective):
            raise OptimizerInputError("objective must be callable: (n, d) array -> (n,) costs")
        lo, hi = _bounds(lower, upper, dim)
        return cls(objective, lo, hi)

    @property
    def dim(self) -> int:
        return self.lower.size

    @property
    def span(self) -> NDArray[np.float64]:
        return self.upper - self.lower

    def random_population(self, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
        """Uniform positions in the box, as the authors' `initialization.m`."""
        return rng.random((n, self.dim)) * self.span + self.lower

    def clip(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.clip(x, self.lower, self.upper)

    def evaluate(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Costs of the rows of `x`; raises ObjectiveError on a wrong shape or a non-finite cost."""
        n = x.shape[0]
        try:
            costs = np.asarray(self.objective(x), dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ObjectiveError(
                f"objective failed on a ({n}, {self.dim}) population: {exc}"
            ) from exc
        if costs.shape != (n,):
            raise ObjectiveError(
                f"objective must return shape ({n},) for a ({n}, {self.dim}) population, "
                f"got shape {costs.shape}"
            )
        bad = ~np.isfinite(costs)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise ObjectiveError(
                f"objective returned {costs[row]} for row {row} (x = {x[row].tolist()}); "
                "costs must be finite: use a large finite penalty instead of inf or NaN"
            )
        self.nfe += n
        return costs


def _bounds(
    lower: ArrayLike, upper: ArrayLike, dim: int | None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    try:
        lo = np.asarray(lower, dtype=np.float64)
        hi = np.asarray(upper, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise OptimizerInputError(
            f"bounds must be numbers or 1-D arrays of numbers: {exc}"
        ) from exc
    if lo.ndim > 1 or hi.ndim > 1:
        raise OptimizerInputError(f"bounds must be 1-D, got shapes {lo.shape} and {hi.shape}")
    if dim is None:
        sizes = {a.size for a in (lo, hi) if a.ndim == 1}
        if not sizes:
            raise OptimizerInputError("scalar bounds need dim=...; or pass arrays of length d")
        if len(sizes) > 1:
            raise OptimizerInputError(f"lower and upper differ in length: {lo.size} vs {hi.size}")
        dim = sizes.pop()
    if dim < 1:
        raise OptimizerInputError(f"the problem needs at least one dimension, got {dim}")
    for name, a in (("lower", lo), ("upper", hi)):
        if a.ndim == 1 and a.size != dim:
            raise OptimizerInputError(f"{name} has {a.size} entries but the problem has {dim}")
    lo = np.broadcast_to(lo, (dim,)).copy()
    hi = np.broadcast_to(hi, (dim,)).copy()
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        raise OptimizerInputError("bounds must be finite")
    wrong = np.flatnonzero(lo >= hi)
    if wrong.size:
        j = int(wrong[0])
        raise OptimizerInputError(
            f"lower must be below upper in every dimension; dimension {j} has "
            f"lower={lo[j]} >= upper={hi[j]}"
        )
    return lo, hi
