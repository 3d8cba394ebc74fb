"""Multi-UAV path planning with the multi-verse optimizer and five other metaheuristics."""

from planner.optimizers import (
    ALGORITHMS,
    ObjectiveError,
    OptimizeResult,
    OptimizerInputError,
    Progress,
    UnknownAlgorithmError,
    get_algorithm,
    optimize,
)

__all__ = [
    "ALGORITHMS",
    "ObjectiveError",
    "OptimizeResult",
    "OptimizerInputError",
    "Progress",
    "UnknownAlgorithmError",
    "get_algorithm",
    "optimize",
]
