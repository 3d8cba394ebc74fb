"""What `mvo-gcs reproduce benchmarks` runs: Table II's and Fig. 1's functions, algorithms,
dimensions, populations and seeds (shared by the study and its report)."""

from __future__ import annotations

from dataclasses import dataclass, field

from planner.experiments.benchmark_runs import RunSpec
from planner.optimizers import ALGORITHMS

TABLE_FUNCTIONS = ("sphere", "rosenbrock", "step", "rastrigin", "ackley", "griewank", "weierstrass")
FIGURE_FUNCTIONS = ("rastrigin", "griewank", "weierstrass", "ackley")


@dataclass(frozen=True)
class StudyConfig:
    seeds: int = 30  # Table II
    iterations: int = 1000
    tolerances: tuple[float, ...] = (1e-8, 1e-2)
    quick: bool = False
    algorithms: tuple[str, ...] = tuple(ALGORITHMS)
    dim: int = 30
    population: int = 30
    table_functions: tuple[str, ...] = TABLE_FUNCTIONS
    figure_functions: tuple[str, ...] = FIGURE_FUNCTIONS
    figure_seeds: int = 10
    figure_dims: tuple[int, ...] = field(default=(10, 30, 50))
    figure_populations: tuple[int, ...] = field(default=(10, 30, 50))

    def __post_init__(self) -> None:
        if self.quick:
            object.__setattr__(self, "figure_dims", (10, 30))
            object.__setattr__(self, "figure_populations", (10, 30))
            object.__setattr__(self, "figure_seeds", min(self.figure_seeds, 5))

    def table_runs(self) -> list[RunSpec]:
        return [
            RunSpec(f, a, self.dim, self.population, self.iterations, s)
            for f in self.table_functions
            for a in self.algorithms
            for s in range(self.seeds)
        ]

    def figure_runs(self) -> list[RunSpec]:
        return [
            RunSpec(f, a, d, p, self.iterations, s)
            for f in self.figure_functions
            for d in self.figure_dims
            for p in self.figure_populations
            for a in self.algorithms
            for s in range(self.figure_seeds)
        ]
