"""One optimizer run on one benchmark function: the unit of work of the benchmark study."""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from planner.optimizers import OptimizeResult, optimize
from planner.optimizers.benchmarks import BENCHMARKS


@dataclass(frozen=True)
class RunSpec:
    function: str
    algorithm: str
    dim: int
    population: int
    iterations: int
    seed: int

    def rng(self) -> np.random.Generator:
        """A generator that depends only on this spec, so any worker gives the same run."""
        key = f"{self.function}/{self.algorithm}/{self.dim}/{self.population}/{self.iterations}"
        return np.random.default_rng([self.seed, zlib.crc32(key.encode())])


@dataclass(frozen=True)
class RunRecord:
    spec: RunSpec
    result: OptimizeResult

    def nfe_to_reach(self, tolerance: float) -> int | None:
        """Evaluations used when the best cost first came within `tolerance` of the optimum."""
        return self.result.nfe_to_reach(BENCHMARKS[self.spec.function].optimum + tolerance)


def run_one(spec: RunSpec) -> RunRecord:
    function = BENCHMARKS[spec.function]
    lower, upper = function.bounds(spec.dim)
    result = optimize(
        spec.algorithm,
        function,
        lower,
        upper,
        population=spec.population,
        iterations=spec.iterations,
        rng=spec.rng(),
    )
    return RunRecord(spec, result)
