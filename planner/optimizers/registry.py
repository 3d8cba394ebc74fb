"""Names to algorithms, so the rest of the product can choose an optimizer by name."""

from __future__ import annotations

from planner.optimizers.algorithm import Algorithm
from planner.optimizers.alo import ALO
from planner.optimizers.da import DA
from planner.optimizers.gwo import GWO
from planner.optimizers.mfo import MFO
from planner.optimizers.mvo import MVO
from planner.optimizers.problem import OptimizerInputError
from planner.optimizers.woa import WOA

ALGORITHMS: dict[str, type[Algorithm]] = {cls.name: cls for cls in (MVO, ALO, DA, GWO, MFO, WOA)}


class UnknownAlgorithmError(OptimizerInputError, KeyError):
    """No algorithm is registered under that name."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


def get_algorithm(algorithm: str | Algorithm) -> Algorithm:
    """An algorithm instance with the reference defaults, from its name (case-insensitive)."""
    if isinstance(algorithm, Algorithm):
        return algorithm
    try:
        return ALGORITHMS[str(algorithm).lower()]()
    except KeyError:
        known = ", ".join(sorted(ALGORITHMS))
        raise UnknownAlgorithmError(
            f"unknown algorithm {algorithm!r}; choose one of {known}"
        ) from None
