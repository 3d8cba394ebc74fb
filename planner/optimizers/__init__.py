"""Six population-based metaheuristics behind one small interface."""

from planner.optimizers.algorithm import Algorithm, Best
from planner.optimizers.alo import ALO
from planner.optimizers.da import DA
from planner.optimizers.gwo import GWO
from planner.optimizers.mfo import MFO
from planner.optimizers.mvo import MVO
from planner.optimizers.optimize import Callback, OptimizeResult, Progress, optimize
from planner.optimizers.problem import ObjectiveError, OptimizerInputError, Problem
from planner.optimizers.registry import ALGORITHMS, UnknownAlgorithmError, get_algorithm
from planner.optimizers.woa import WOA

__all__ = [
    "ALGORITHMS",
    "ALO",
    "DA",
    "GWO",
    "MFO",
    "MVO",
    "WOA",
    "Algorithm",
    "Best",
    "Callback",
    "ObjectiveError",
    "OptimizeResult",
    "OptimizerInputError",
    "Problem",
    "Progress",
    "UnknownAlgorithmError",
    "get_algorithm",
    "optimize",
]
