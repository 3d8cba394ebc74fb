"""A recorded set of plans: the six cases and generated scenarios, planned by every flow.

Each plan is reduced to a digest (sha256 of its JSON without the wall-clock fields,
trajectories and costs already rounded to 6 decimals by the plan model, plus the
reasons its progress reports gave); `tests/unit/data/plan_digests.json` holds the
digests recorded before the planner's flows were restructured (issue 24; the two
budgeted flows were added after, from the code before, f99b66a's planner), and
`tests/unit/test_plan_digests.py` plans everything again and compares. Every flow runs
without a time budget (`time_budget_s=None`) or with one that never runs out, so no
clock decides anything: the same seed gives the same plan on any machine, under any
load.

Record again (only for an intended change of behaviour, said so in the commit):

    .venv/bin/python -m tests.unit.plan_digests
"""

from __future__ import annotations

import functools
import hashlib
import json
from collections.abc import Callable
from pathlib import Path

from planner.cases import CASES, load_case
from planner.experiments.scenario_generator import (
    crossing_scenario,
    gap_swap_scenario,
    random_scenario,
)
from planner.live.replan import NewObject, replan_live
from planner.model.plan import Plan
from planner.model.scenario import Scenario
from planner.pipeline import PlannerSettings, PlanProgress, plan

RECORD = Path(__file__).parent / "data" / "plan_digests.json"
CLOCK_FIELDS = ("seconds", "first_safe_s")  # wall time: the only fields a clock decides
LATER_FIELDS = ("complete_start",)  # added after the record: left out where not used

BASE = PlannerSettings(population=10, iterations=20, time_budget_s=None)
FLOWS: dict[str, PlannerSettings] = {
    # Algorithm 1 as the paper runs it, both objectives.
    "paper": PlannerSettings(objective="paper", population=10, iterations=20).iterations_only(),
    "qos-algorithm-1": BASE.iterations_only(),
    # The paper's flow with qos: wait probes, then the improvement phase.
    "qos-probing": PlannerSettings(
        population=10, iterations=20, time_budget_s=None, patience=10, safe_start=False
    ),
    # The anytime flow: lone paths, safe start, improvement.
    "anytime": BASE,
    "anytime-gwo": PlannerSettings(
        algorithm="gwo", population=10, iterations=20, time_budget_s=None, improve_rounds=2
    ),
    # A budget that never runs out: the budgeted code paths (the others' cost without
    # sampled traffic, the runs' deadlines) taken, and still no clock decides anything.
    "anytime-budget": PlannerSettings(population=10, iterations=20, time_budget_s=1e6),
    "qos-probing-budget": PlannerSettings(
        population=10, iterations=20, time_budget_s=1e6, patience=10, safe_start=False
    ),
}

SCENARIOS: dict[str, Callable[[], Scenario]] = {
    **{name: functools.partial(load_case, name) for name in CASES},
    "crossing-1": lambda: crossing_scenario(1, size=12, uavs=5),
    "crossing-2": lambda: crossing_scenario(2, size=12, uavs=6, objects=3),
    "random-1": lambda: random_scenario(4, size=12, uavs=8, objects=3),
    "gap-swap-1": lambda: gap_swap_scenario(1),
    "gap-swap-2": lambda: gap_swap_scenario(2, size=10, uavs=6, gap=1),
}
LIVE_SCENARIOS = ("case-6", "crossing-1", "gap-swap-1")


def plan_digest(result: Plan, reasons: list[str]) -> str:
    data = result.model_dump(mode="json")
    for name in CLOCK_FIELDS:
        data["metrics"].pop(name, None)
    for name in LATER_FIELDS:
        if data["metrics"].get(name) is None:
            data["metrics"].pop(name, None)
    text = json.dumps({"plan": data, "reasons": reasons}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def planned(scenario: Scenario, settings: PlannerSettings) -> tuple[Plan, list[str]]:
    seen: list[PlanProgress] = []
    result = plan(scenario, settings, seen.append)
    reasons = [f"{p.run}:{p.uav}:{p.reason}:{p.iteration}" for p in seen]
    return result, reasons


def live_digest(scenario: Scenario, result: Plan) -> str:
    """A replan in flight: an object on the cell the first UAV would reach at half its
    flight, reported a quarter into it."""
    first = result.uavs[0].trajectory
    end = first[-1][0]
    half = min(first, key=lambda p: abs(p[0] - end / 2))
    cell = (round(half[1]), round(half[2]))
    settings = PlannerSettings(population=10, iterations=20, time_budget_s=None)
    live = replan_live(scenario, result, NewObject(cell), now=end / 4, settings=settings)
    text = json.dumps(live.to_json(), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def digests() -> dict[str, str]:
    out = {}
    for scenario_name, make in SCENARIOS.items():
        scenario = make()
        for flow, settings in FLOWS.items():
            result, reasons = planned(scenario, settings)
            out[f"{scenario_name}/{flow}"] = plan_digest(result, reasons)
            if flow == "anytime" and scenario_name in LIVE_SCENARIOS:
                out[f"{scenario_name}/{flow}/live"] = live_digest(scenario, result)
    return out


if __name__ == "__main__":
    RECORD.write_text(json.dumps(digests(), indent=1, sort_keys=True) + "\n")
    print(f"wrote {RECORD}")
