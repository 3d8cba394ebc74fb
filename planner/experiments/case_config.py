"""What `mvo-gcs reproduce cases` runs: Table III's cases, algorithms, populations and
seeds (shared by the study and its report)."""

from __future__ import annotations

from dataclasses import dataclass

from planner.cases import CASES, PAPER_POPULATIONS
from planner.experiments.case_runs import CaseSpec
from planner.optimizers import ALGORITHMS
from planner.search.objectives import ObjectiveName


@dataclass(frozen=True)
class CaseStudyConfig:
    seeds: int = 30
    iterations: int = 1000
    populations: tuple[int, ...] = PAPER_POPULATIONS
    algorithms: tuple[str, ...] = tuple(ALGORITHMS)
    objective: ObjectiveName = "paper"
    cases: tuple[str, ...] = CASES

    @property
    def figure_population(self) -> int:
        """The population of Fig. 3: the paper's 30, else our largest."""
        return 30 if 30 in self.populations else max(self.populations)

    def runs(self) -> list[CaseSpec]:
        return [
            CaseSpec(c, a, p, self.iterations, self.objective, s)
            for c in self.cases
            for a in self.algorithms
            for p in self.populations
            for s in range(self.seeds)
        ]
