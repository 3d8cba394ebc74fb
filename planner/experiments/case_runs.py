"""One plan of one of the paper's cases: the unit of work of the case study."""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from planner.cases import load_case
from planner.model.plan import Plan
from planner.pipeline import PlannerSettings, plan
from planner.search.objectives import ObjectiveName


@dataclass(frozen=True)
class CaseSpec:
    case: str
    algorithm: str
    population: int
    iterations: int
    objective: ObjectiveName
    seed: int  # index of the repetition, 0 .. seeds - 1

    def planner_seed(self) -> int:
        """A seed that depends only on this spec, so any worker gives the same plan."""
        key = f"{self.case}/{self.algorithm}/{self.population}/{self.iterations}/{self.objective}"
        return zlib.crc32(f"{key}/{self.seed}".encode())

    def settings(self) -> PlannerSettings:
        """Algorithm 1 as the paper runs it: every run all its iterations, no time budget
        (so any executor, on any machine, gives the same record)."""
        return PlannerSettings(
            algorithm=self.algorithm,
            objective=self.objective,
            seed=self.planner_seed(),
            population=self.population,
            iterations=self.iterations,
        ).iterations_only()


@dataclass(frozen=True)
class CaseRecord:
    spec: CaseSpec
    feasible: bool
    J: float
    mean_deviation: float
    total_length: float
    conflicts: int
    nfe: int
    seconds: float
    start_distance: float  # Dist(t0) of the UAV that replans first, as in Table III
    history: tuple[float, ...]  # plan cost after every optimizer iteration, all runs in turn

    def outcome(self) -> tuple[object, ...]:
        """Everything but the wall-clock time: equal whichever executor ran the spec."""
        return (
            self.spec,
            self.feasible,
            self.J,
            self.mean_deviation,
            self.total_length,
            self.conflicts,
            self.nfe,
            self.start_distance,
            self.history,
        )


def run_case(spec: CaseSpec) -> CaseRecord:
    result = plan(load_case(spec.case), spec.settings())
    m = result.metrics
    return CaseRecord(
        spec=spec,
        feasible=result.feasible,
        J=m.J,
        mean_deviation=m.mean_deviation,
        total_length=m.total_length,
        conflicts=m.conflicts,
        nfe=m.nfe,
        seconds=m.seconds,
        start_distance=first_start_distance(result),
        history=tuple(result.history),
    )


def first_start_distance(result: Plan) -> float:
    """Start distance from the highest-priority UAV to the next one (the pipeline's Dist(t0))."""
    order = sorted(result.uavs, key=lambda u: -u.priority)  # stable: ties keep order
    if len(order) < 2:
        return 1.0
    (a, b) = (np.array(u.trajectory[0][1:]) for u in order[:2])
    return round(float(np.hypot(*(a - b))), 6)
