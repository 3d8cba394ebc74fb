"""What the optimizer benchmark against mealpy and EvoloPy runs, and what a run records.

Shared by `library_comparison` (which runs it) and `library_report` (which reports it).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

from planner.optimizers import ALGORITHMS, GWO, Algorithm

LIBRARIES = ("ours", "mealpy", "evolopy")
MEALPY_CLASSES = {
    "mvo": ("mealpy.physics_based.MVO", "OriginalMVO"),
    "alo": ("mealpy.swarm_based.ALO", "OriginalALO"),
    "da": ("mealpy.swarm_based.DO", "OriginalDO"),
    "gwo": ("mealpy.swarm_based.GWO", "OriginalGWO"),
    "mfo": ("mealpy.swarm_based.MFO", "OriginalMFO"),
    "woa": ("mealpy.swarm_based.WOA", "OriginalWOA"),
}
EVOLOPY_FUNCTIONS = {"mvo": "MVO", "gwo": "GWO", "mfo": "MFO", "woa": "WOA"}  # no ALO, no DA
# Variants of ours that adopt one of EvoloPy's own rules, to show where a difference comes from.
VARIANTS: dict[str, tuple[str, Algorithm]] = {
    "gwo": ("GWO with EvoloPy's leader demotion", GWO(demote_leaders=True)),
}
VARIANT = "ours-variant"
SPEED_TARGET = 10.0  # ours must be at least this many times faster than the faster library
ALPHA = 0.05  # Mann-Whitney significance level
INSTALL_HINT = "pip install -e '.[bench]'"


class BenchDependencyError(ImportError):
    """mealpy, EvoloPy or scipy (the 'bench' extra) is not installed."""


@dataclass(frozen=True)
class ComparisonConfig:
    """What to run: every algorithm on every function, `seeds` runs per library."""

    seeds: int = 10
    iterations: int = 1000
    population: int = 30
    dim: int = 30
    algorithms: tuple[str, ...] = tuple(ALGORITHMS)
    functions: tuple[str, ...] = ("rastrigin", "sphere")


@dataclass(frozen=True)
class Run:
    """One run of one library's algorithm: a row of the CSV."""

    function: str
    algorithm: str
    library: str
    seed: int
    seconds: float
    best_cost: float
    nfe: int


@dataclass(frozen=True)
class Libraries:
    mealpy: ModuleType
    stats: ModuleType  # scipy.stats
