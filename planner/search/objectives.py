"""The two objectives a UAV's path is scored by.

`qos` (the product's default) is a weighted sum: path length, a small price for
hovering, and a penalty for any conflict or obstacle hit that is larger than any
detour could cost, so no unsafe path ever beats a safe one. Every candidate ends at
the goal, so the deviation is zero.

`paper` is eq. (10) of the paper, J = w1 (#UAV)^2 x w2 sp x w3 delta / (w4 Dist(t0)),
with the weights equal to 1 as in its experiments, plus the same conflict penalty.
Because the terms multiply, a path that reaches its goal (delta = 0) scores 0 whatever
its length; with the paper's one-grid turn a UAV that turns always ends one cell off.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.search.path_cost import PathTerms

ObjectiveName = Literal["qos", "paper"]
HOVER_PRICE = 0.5  # cells of length one second of hovering costs, per cell/s of speed


class PathObjective(Protocol):
    def cost(self, terms: PathTerms) -> NDArray[np.float64]: ...


def unsafe_penalty(terms: PathTerms, scale: float) -> NDArray[np.float64]:
    """`scale` for coming too close to a UAV, twice that for entering a blocked cell (the
    other UAVs can still move out of the way, a blocked cell cannot), plus the depth of
    the hits so that the search can tell a better unsafe path from a worse one."""
    uav_hit = terms.separation_hits > 0
    cell_hit = terms.clearance_hits > 0
    depth = terms.separation_deficit + terms.clearance_deficit
    return scale * (uav_hit + 2.0 * cell_hit + depth)


@dataclass(frozen=True)
class QosObjective:
    speed: float
    penalty: float  # more than the longest detour the encoding can produce

    def cost(self, terms: PathTerms) -> NDArray[np.float64]:
        return (
            terms.length
            + HOVER_PRICE * self.speed * terms.waiting
            + self.penalty * terms.deviation
            + unsafe_penalty(terms, self.penalty)
        )


@dataclass(frozen=True)
class PaperObjective:
    objects: int  # #UAV in eq. (10): the other UAVs and non-UAV objects
    start_distance: float  # Dist(t0): to the UAV of adjoining priority
    penalty: float

    def cost(self, terms: PathTerms) -> NDArray[np.float64]:
        return paper_fitness(
            self.objects, terms.length, terms.deviation, self.start_distance
        ) + unsafe_penalty(terms, self.penalty)


def paper_fitness(
    objects: int, length: ArrayLike, deviation: ArrayLike, start_distance: float
) -> NDArray[np.float64]:
    """Eq. (10) with w1 = w2 = w3 = w4 = 1."""
    fitness: NDArray[np.float64] = (
        objects**2 * np.asarray(length) * np.asarray(deviation) / max(start_distance, 1e-9)
    )
    return fitness
