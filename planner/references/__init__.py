"""Classic reference planners the metaheuristic planner is compared against.

* `planner.references.prioritized.plan_prioritized`: prioritized planning with a
  space-time A* whose every move is checked exactly against the UAVs already planned.
* `planner.references.cbs.plan_cbs`: the optimal CBS solver of `pymapf` (extra `mapf`).

MAPF solvers such as CBS live in a discrete world: agents move one cell per time
step, a diagonal move takes one step like a straight one (not √2), and only two
agents on the same cell or swapping cells collide, so two UAVs crossing each other
on a diagonal, or a UAV entering a cell as another leaves it at a right angle, pass.
That is why every reference is judged here by OUR exact continuous-time check,
never by the solver's own notion of a valid plan.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from planner.check.safety import check_plan
from planner.geometry.grid_search import shortest_lengths
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory

__all__ = ["ReferenceResult", "judge", "shortest_lengths"]

SPEED_TOLERANCE = 1e-5
"""Relative: plans are written to 6 decimals, which can make a leg look 1e-6 too fast."""


@dataclass(frozen=True)
class ReferenceResult:
    """What a reference planner produced; `trajectories` is None when it found no plan."""

    name: str
    trajectories: dict[str, Trajectory] | None
    solved: bool
    seconds: float
    note: str = ""
    expansions: int | None = None


def judge(scenario: Scenario, result: ReferenceResult) -> dict[str, Any]:
    """The reference's plan measured the way our own plans are.

    `safe` is the verdict of `planner.check.safety.check_plan`; `feasible` also asks that
    no UAV flies faster than its speed (MAPF charges a diagonal one step, so a plan
    timed by the solver's clock may break it) and that every UAV ends on its goal.
    """
    out: dict[str, Any] = {
        "name": result.name,
        "solved": result.solved,
        "seconds": round(result.seconds, 4),
        "note": result.note,
    }
    paths = result.trajectories
    if paths is None:
        return out | dict.fromkeys(_METRICS) | {"safe": False, "feasible": False}
    specs = {u.id: u for u in scenario.uavs}
    report = check_plan(
        paths,
        {u: specs[u].radius for u in paths},
        scenario.blocked(),
        scenario.object_cells(),
    )
    total = sum(t.length for t in paths.values())
    shortest = sum(shortest_lengths(scenario).values())
    deviation = [float(np.hypot(*(paths[u].end - specs[u].goal))) for u in paths]
    speed_ratio = max(t.max_speed() / specs[u].speed for u, t in paths.items())
    reaches = len(paths) == len(specs) and max(deviation) < 1e-9
    within_speed = speed_ratio <= 1 + SPEED_TOLERANCE
    closest = report.min_separation
    return out | {
        "conflicts": len(report.conflicts),
        "conflict_messages": [c.describe() for c in report.conflicts],
        "min_separation": round(closest, 6) if np.isfinite(closest) else None,
        "total_length": round(total, 6),
        "shortest_total": round(shortest, 6),
        "length_ratio": round(total / shortest, 6) if shortest > 0 else 1.0,
        "mean_deviation": round(float(np.mean(deviation)), 6),
        "makespan": round(max(t.end_time for t in paths.values()), 6),
        "max_speed_ratio": round(speed_ratio, 6),
        "safe": report.safe,
        "feasible": report.safe and within_speed and reaches,
    }


_METRICS = (
    "conflicts",
    "conflict_messages",
    "min_separation",
    "total_length",
    "shortest_total",
    "length_ratio",
    "mean_deviation",
    "makespan",
    "max_speed_ratio",
)
