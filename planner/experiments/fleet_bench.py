"""Fleet-scale planning: our anytime MVO planner beside pymapf 0.9.0's LaCAM and
prioritized planning, side by side in one process, on generated scenario families with
fixed seeds. Every plan, ours and theirs, is judged by our exact continuous-time check
(`planner.references.judge`: no conflict, every UAV at its goal, never too fast).

Per planner and family: feasible share, time to the first safe plan, total time, length
against each UAV's own shortest path, and (ours) what the optimizer gained after the first
safe plan; issue 13's targets in one table; peak memory on the 50-UAV families; how far
past its budget ours returned.

Run by `mvo-gcs bench planner` as the last section of its report (`fleet_section`).
"""

from __future__ import annotations

import dataclasses
import functools
import os
import resource
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from planner.experiments.fleet_tables import (
    OURS,
    Row,
    family_table,
    summary_table,
    write_csv,
)
from planner.experiments.scenario_generator import crossing_scenario, random_scenario
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory
from planner.pipeline import PlannerSettings, plan
from planner.references import ReferenceResult, judge
from planner.references.cbs import MapfDependencyError, require_pymapf
from planner.references.pymapf_solvers import plan_lacam, plan_pymapf_prioritized


@dataclass(frozen=True)
class FleetConfig:
    budget: float = 5.0
    seed_scale: float = 1.0  # share of each family's seeds to run (1: all of them)


@dataclass(frozen=True)
class Family:
    name: str
    build: Callable[[int], Scenario]
    seeds: int  # seeds 0 .. seeds - 1
    time_target: float | None = None  # the median target for ours, s; None: extra

    def seed_count(self, config: FleetConfig) -> int:
        return max(1, round(self.seeds * config.seed_scale))

    @property
    def fleet(self) -> int:
        return len(self.build(0).uavs)


def spread(size: int, uavs: int) -> Callable[[int], Scenario]:
    """Issue 13's random family: 10 % obstacles, starts and goals at least 2 cells apart,
    every goal reachable alone, no non-UAV objects."""
    return lambda seed: random_scenario(seed, size=size, uavs=uavs, objects=0, min_gap=2.0)


FAMILIES = [
    Family("crossing, 6 UAVs, 20x20", lambda s: crossing_scenario(s), 10, 0.25),
    Family("random, 12 UAVs, 40x40", spread(40, 12), 10, 1.0),
    Family("random, 25 UAVs, 80x80", spread(80, 25), 10, 2.0),
    Family("random, 50 UAVs, 120x120", spread(120, 50), 5, 5.0),
    Family("random, 50 UAVs, 200x200", spread(200, 50), 5, 5.0),
    # The first round's harder families, as extra rows.
    Family(
        "random, 50 UAVs, 50x50, 5 objects",
        lambda s: random_scenario(s, size=50, uavs=50, objects=5),
        3,
    ),
    Family(
        "crossing, 50 UAVs, 64x64, 5 objects",
        lambda s: crossing_scenario(s, size=64, uavs=50, objects=5),
        3,  # seed 3 has no valid ring of 50 starts
    ),
]


def run_ours(
    scenario: Scenario, seed: int, budget: float, safe_start_limit_s: float | None = None
) -> Row:
    started = time.perf_counter()
    settings = PlannerSettings(
        seed=seed, time_budget_s=budget, safe_start_limit_s=safe_start_limit_s
    )
    result = plan(scenario, settings)
    seconds = time.perf_counter() - started
    paths = {u.id: Trajectory(np.array(u.trajectory)) for u in result.uavs}
    verdict = judge(scenario, ReferenceResult(OURS, paths, True, seconds))
    m = result.metrics
    return Row(
        "",
        seed,
        OURS,
        bool(verdict["feasible"]),
        m.first_safe_s if verdict["feasible"] else None,
        seconds,
        verdict["length_ratio"] if verdict["feasible"] else None,
        m.improvement,
        result.stop_reason or "",
        f"{m.replans} runs, {m.iterations_run} iterations, {m.conflicts} conflicts",
        result.feasible,
    )


def run_reference(
    scenario: Scenario, seed: int, solve: Callable[[Scenario], ReferenceResult]
) -> Row:
    result = solve(scenario)
    verdict = judge(scenario, result)
    feasible = bool(verdict["feasible"])
    note = result.note
    if result.solved and not feasible:
        speed = verdict["max_speed_ratio"]
        note = f"{verdict['conflicts']} conflicts by our check; speed ratio {speed}"
    return Row(
        "",
        seed,
        result.name,
        feasible,
        result.seconds if feasible else None,
        result.seconds,
        verdict["length_ratio"] if feasible else None,
        None,
        "",
        note,
        result.solved,
    )


def planners(budget: float) -> list[tuple[str, Callable[[Scenario, int], Row]]]:
    """Ours, then the pymapf planners when the `mapf` extra is installed."""
    ours: list[tuple[str, Callable[[Scenario, int], Row]]] = [
        (OURS, lambda s, seed: run_ours(s, seed, budget))
    ]
    try:
        require_pymapf()
    except MapfDependencyError:
        return ours
    return [
        *ours,
        ("LaCAM 4", lambda s, seed: run_reference(s, seed, lambda x: plan_lacam(x, budget))),
        (
            "PP 4",
            lambda s, seed: run_reference(s, seed, lambda x: plan_pymapf_prioritized(x, budget)),
        ),
    ]


def peak_mib(fn: Callable[[], Row]) -> tuple[str, float]:
    """The planner's name and its peak traced allocation in MiB."""
    tracemalloc.start()
    try:
        row = fn()
        return row.planner, tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def run_fleet(config: FleetConfig) -> tuple[list[Row], list[tuple[str, str, float]]]:
    """Every family, seed and planner in turn, then the memory runs; printing as it goes."""
    rows: list[Row] = []
    memory: list[tuple[str, str, float]] = []
    for family in FAMILIES:
        for seed in range(family.seed_count(config)):
            scenario = family.build(seed)
            for _, run in planners(config.budget):
                row = run(scenario, seed)
                rows.append(dataclasses.replace(row, family=family.name))
                print(
                    family.name, seed, row.planner, row.feasible, f"{row.seconds:.2f}", flush=True
                )
        if family.fleet >= 50:
            scenario = family.build(0)
            for _, run in planners(config.budget):
                memory.append((family.name, *peak_mib(functools.partial(run, scenario, 0))))
    return rows, memory


def fleet_section(config: FleetConfig, csv_path: Path) -> str:
    """The fleet benchmark as a section of the planner report; per-run rows to `csv_path`."""
    load_before, started = os.getloadavg(), datetime.now(UTC)
    rows, memory = run_fleet(config)
    load_after = os.getloadavg()
    write_csv(rows, csv_path)
    ours = [r for r in rows if r.planner == OURS]
    overrun = max(r.seconds - config.budget for r in ours)
    marked = [r for r in ours if r.marked]
    lines = [
        "## Fleet scale, beside pymapf's LaCAM and prioritized planning\n",
        f"- Run {started:%Y-%m-%d %H:%M} UTC, one planner at a time in one process; load "
        f"average {load_before[0]:.2f} before and {load_after[0]:.2f} after (the 1-minute "
        "figure, of the whole 2-core machine).",
        f"- Ours: MVO, `qos`, population 30, at most 1000 iterations a run, the default time "
        f"budget of {config.budget:g} s, seed = scenario seed. LaCAM (its first solution) with "
        f"a {config.budget:g} s limit; pymapf's prioritized planning (PP, scenario order) "
        f"stopped at {config.budget + 1:g} s.",
        "- Families: issue 13's random ones (`random_scenario(seed, size, uavs, objects=0, "
        "min_gap=2.0)`: 10 % obstacles, starts and goals at least 2 cells apart, every goal "
        "reachable alone) and the 20x20 crossing ones of the 100-scenario table "
        "(`crossing_scenario(seed)`, 2 non-UAV objects); the last two are extra rows.",
        "- Every plan is judged by our exact continuous-time check: feasible = no conflict, "
        "every UAV on its goal, never faster than its speed. pymapf steps are timed one "
        "cell time per 4-connected step, so no UAV is too fast.",
        "- Time to first safe plan: ours, when the fleet first passed the exact check; the "
        "references, their whole run. Time to plan: until the plan was returned.",
        "- Length ratio: total length over the sum of each UAV's 8-connected shortest "
        "path (no corner cutting, objects blocked, other UAVs ignored); below 1 because "
        "our paths are any-angle. Medians over the feasible plans.",
        f"- Ours marked {len(marked)} of {len(ours)} plans feasible; the check found "
        f"{sum(r.feasible for r in marked)} of those safe (and {sum(r.feasible for r in ours)} "
        "in all).",
        f"- Ours returned at most {overrun:+.3f} s past its {config.budget:g} s budget "
        f"(over {len(ours)} runs). Per-run rows: `{csv_path.name}`.\n",
        "### Targets of issue 13, family by family\n",
        *summary_table(rows, FAMILIES),
        "",
    ]
    for family in FAMILIES:
        mine = [r for r in rows if r.family == family.name]
        lines += [f"### {family.name} (seeds 0..{family.seed_count(config) - 1})\n"]
        lines += [*family_table(mine), ""]
    lines += [
        "### Peak memory on the 50-UAV families (seed 0)\n",
        "Python and numpy allocations traced by tracemalloc during one more run "
        "(tracing slows pure-Python code, so these runs are not timed).\n",
        "| family | planner | peak MiB |",
        "|---|---|---:|",
        *(f"| {f} | {p} | {mib:.1f} |" for f, p, mib in memory),
        "",
        f"Peak RSS of the whole benchmark process: "
        f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB.",
        "",
    ]
    if len(planners(config.budget)) == 1:
        lines.append("pymapf did not run: install the `mapf` extra (`pip install -e '.[mapf]'`).\n")
    failures = [r for r in ours if not r.feasible]
    if failures:
        lines.append("Our runs without a feasible plan:\n")
        lines += [
            f"- {r.family}, seed {r.seed}: {r.note}; stopped by {r.stop_reason}" for r in failures
        ]
    return "\n".join(lines) + "\n"
