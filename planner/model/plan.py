"""The plan we return: per-UAV trajectories and the metrics that show it is safe."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field


class _Out(BaseModel):
    model_config = ConfigDict(extra="forbid")


class PlannedUAV(_Out):
    id: str
    trajectory: list[list[float]] = Field(description="[t, x, y] points, piecewise linear")
    length: float = Field(description="cells flown")
    deviation: float = Field(description="distance from the last point to the goal, cells")
    priority: float = Field(description="ImP, eq. (7), when planning started")
    moving_rate: float = Field(description="UMR, eq. (3): shortest distance to the goal, cells")
    threat: float = Field(description="OTP, eq. (4)")
    shortest_length: float = Field(description="8-connected shortest path, ignoring other UAVs")
    replanned: list[str] = Field(default_factory=list, description="why it was replanned")


class Metrics(_Out):
    conflicts: int
    min_separation: float | None = Field(description="closest centres of two UAVs; null: one UAV")
    mean_deviation: float
    total_length: float
    J: float = Field(description="eq. (10), mean over UAVs, weights 1")
    nfe: int
    seconds: float
    replans: int
    iterations_run: int | None = Field(
        default=None,
        description="optimizer iterations run, all runs together, and the safe start's "
        "and re-timing's steps (runs of one step)",
    )
    first_safe_s: float | None = Field(
        default=None, description="seconds until the first plan that passed the exact check"
    )
    first_safe_cost: float | None = Field(default=None, description="that plan's cost")
    cost: float | None = Field(
        default=None,
        description="the plan's cost: sum of length + hover price (qos), or mean J (paper)",
    )
    improvement: float | None = Field(
        default=None,
        description="share of the first safe plan's cost taken off afterwards (by the "
        "improvement phase, or by the safe start's plan replacing the complete start's)",
    )
    complete_start: str | None = Field(
        default=None,
        description="what the complete start did when the safe start left conflicts "
        "(null: it was not needed)",
    )


class Plan(_Out):
    feasible: bool
    stop_reason: Literal["converged", "budget", "iterations"] | None = Field(
        default=None,
        description="converged: nothing left to improve; budget: the time budget ended it; "
        "iterations: the iteration budget did",
    )
    time_budget_s: float | None = Field(default=None, description="null: iterations only")
    algorithm: str
    objective: str
    seed: int
    population: int
    iterations: int
    scenario: str
    uavs: list[PlannedUAV]
    non_uav_objects: list[list[int]]
    metrics: Metrics
    conflicts: list[dict[str, Any]] = Field(
        default_factory=list, description="what keeps an infeasible plan from being safe"
    )
    history: list[float] = Field(
        description="plan cost after every optimizer iteration and every safe-start or "
        "re-timing step"
    )

    def length_ratio(self) -> float:
        """Total length over the sum of each UAV's own shortest path (objects known)."""
        return self.metrics.total_length / sum(u.shortest_length for u in self.uavs)
