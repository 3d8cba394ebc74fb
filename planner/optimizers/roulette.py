"""Roulette-wheel selection exactly as the authors' `RouletteWheelSelection.m`."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def roulette_wheel(
    weights: NDArray[np.float64], size: int, rng: np.random.Generator
) -> NDArray[np.intp]:
    """Draw `size` indices: the first index whose cumulative weight exceeds u * total.

    The MATLAB returns -1 when no index qualifies and both callers (MVO, ALO) then
    take the first one; we return 0 directly. With all-negative weights (MVO passes
    the negated costs) the cumulative sum only falls, so only index 0 can qualify:
    the white hole is then always the best universe, as in the reference code.
    """
    with np.errstate(invalid="ignore", over="ignore"):  # an infinite weight (ALO: 1 / 0)
        acc = np.cumsum(weights)
        steps = np.diff(acc)
        if np.all(steps <= 0):
            return np.zeros(size, dtype=np.intp)
        target = rng.random(size) * acc[-1]
    if np.all(steps >= 0):
        idx: NDArray[np.intp] = np.searchsorted(acc, target, side="right")
        idx[(idx >= acc.size) | np.isnan(target)] = 0
        return idx
    hit = acc[None, :] > target[:, None]
    return np.where(hit.any(axis=1), hit.argmax(axis=1), 0)
