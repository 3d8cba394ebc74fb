"""Fleet-scale planning: our anytime MVO planner beside pymapf 0.9.0's LaCAM and
prioritized planning, side by side in one process, on generated scenario families with
fixed seeds. Every plan, ours and theirs, is judged by our exact continuous-time check
(`planner.references.judge`: no conflict, every UAV at its goal, never too fast).

Per planner and family: feasible share, time to the first safe plan, total time, length
against each UAV's own shortest path, and (ours) what the optimizer gained after the first
safe plan; peak memory on the 50-UAV families; how far past its budget ours returned.

Run by `mvo-gcs bench planner` as the last section of its report (`fleet_section`).
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import os
import resource
import statistics
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from planner.experiments.scenario_generator import crossing_scenario, random_scenario
from planner.pipeline import PlannerSettings, plan
from planner.references import ReferenceResult, judge
from planner.references.cbs import MapfDependencyError, require_pymapf
from planner.references.pymapf_solvers import plan_lacam, plan_pymapf_prioritized
from planner.scenario import Scenario
from planner.trajectory import Trajectory

OURS = "MVO qos (ours)"


@dataclass(frozen=True)
class FleetConfig:
    budget: float = 5.0
    seeds_small: int = 10
    seeds_large: int = 5


@dataclass(frozen=True)
class Family:
    name: str
    build: Callable[[int], Scenario]
    large: bool  # fewer seeds; memory measured if it has 50 UAVs
    most_seeds: int | None = None  # seeds that give a valid scenario, if fewer

    def seeds(self, config: FleetConfig) -> int:
        count = config.seeds_large if self.large else config.seeds_small
        return count if self.most_seeds is None else min(count, self.most_seeds)


FAMILIES = [
    Family("crossing, 6 UAVs, 20x20", lambda s: crossing_scenario(s), False),
    Family("crossing, 12 UAVs, 40x40", lambda s: crossing_scenario(s, size=40, uavs=12), False),
    Family("crossing, 24 UAVs, 48x48", lambda s: crossing_scenario(s, size=48, uavs=24), True),
    Family(
        "random, 20 UAVs, 30x30", lambda s: random_scenario(s, size=30, uavs=20, objects=3), False
    ),
    Family(
        "random, 50 UAVs, 50x50", lambda s: random_scenario(s, size=50, uavs=50, objects=5), True
    ),
    Family(
        "crossing, 50 UAVs, 64x64",
        lambda s: crossing_scenario(s, size=64, uavs=50, objects=5),
        True,
        3,  # seed 3 has no valid ring of 50 starts
    ),
]


@dataclass(frozen=True)
class Row:
    family: str
    seed: int
    planner: str
    feasible: bool
    first_safe_s: float | None  # None: no safe plan
    seconds: float
    length_ratio: float | None
    improvement: float | None
    stop_reason: str
    note: str


def run_ours(scenario: Scenario, seed: int, budget: float) -> Row:
    started = time.perf_counter()
    result = plan(scenario, PlannerSettings(seed=seed, time_budget_s=budget))
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
        ("LaCAM 8", lambda s, seed: run_reference(s, seed, lambda x: plan_lacam(x, budget, True))),
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


def median_text(values: list[float], digits: int = 3) -> str:
    return f"{statistics.median(values):.{digits}f}" if values else "-"


def family_table(rows: list[Row]) -> list[str]:
    lines = [
        "| planner | feasible | median s to first safe plan (max) | median total s | "
        "median length ratio | median gain after first safe |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name in dict.fromkeys(r.planner for r in rows):
        mine = [r for r in rows if r.planner == name]
        ok = [r for r in mine if r.feasible]
        firsts = [r.first_safe_s for r in ok if r.first_safe_s is not None]
        gains = [100 * r.improvement for r in ok if r.improvement is not None]
        worst = f" ({max(firsts):.2f})" if firsts else ""
        lines.append(
            f"| {name} | {len(ok)}/{len(mine)} ({100 * len(ok) / len(mine):.0f} %) | "
            f"{median_text(firsts)}{worst} | {median_text([r.seconds for r in mine])} | "
            f"{median_text([r.length_ratio for r in ok if r.length_ratio is not None])} | "
            f"{median_text(gains, 1) + ' %' if gains else '-'} |"
        )
    return lines


def write_csv(rows: list[Row], path: Path) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(list(Row.__dataclass_fields__))
        for r in rows:
            writer.writerow(list(vars(r).values()))


def run_fleet(config: FleetConfig) -> tuple[list[Row], list[tuple[str, str, float]]]:
    """Every family, seed and planner in turn, then the memory runs; printing as it goes."""
    rows: list[Row] = []
    memory: list[tuple[str, str, float]] = []
    for family in FAMILIES:
        for seed in range(family.seeds(config)):
            scenario = family.build(seed)
            for _, run in planners(config.budget):
                row = run(scenario, seed)
                rows.append(dataclasses.replace(row, family=family.name))
                print(
                    family.name, seed, row.planner, row.feasible, f"{row.seconds:.2f}", flush=True
                )
        if family.large and len(family.build(0).uavs) >= 50:
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
    lines = [
        "## Fleet scale, beside pymapf's LaCAM and prioritized planning\n",
        f"- Run {started:%Y-%m-%d %H:%M} UTC, one planner at a time in one process; load "
        f"average {load_before[0]:.2f} before and {load_after[0]:.2f} after (the 1-minute "
        "figure; other work shared the 2 cores).",
        f"- Ours: MVO, `qos`, population 30, at most 1000 iterations a run, time budget "
        f"{config.budget:g} s, seed = scenario seed. LaCAM (its first solution) with a "
        f"{config.budget:g} s limit; pymapf's prioritized planning (scenario order) stopped "
        f"at {config.budget + 1:g} s.",
        "- Every plan is judged by our exact continuous-time check: feasible = no conflict, "
        "every UAV on its goal, never faster than its speed. pymapf steps are timed one "
        "cell time per straight step (4-connected) and √2 cell times per step "
        "(8-connected), so no UAV is too fast; pymapf does not see two UAVs crossing on "
        "a diagonal, our check does.",
        "- Time to first safe plan: ours, when the fleet first passed the exact check "
        "during the run; the references, their whole run when their plan is feasible.",
        "- Length ratio: total length over the sum of each UAV's 8-connected shortest "
        "path with objects blocked (ours may be below 1: waypoints need not sit on cell "
        "centres). Gain: the share of the first safe plan's cost (length + hover price) "
        "the optimizer removed within the budget.",
        f"- Ours returned at most {overrun:+.3f} s past its {config.budget:g} s budget "
        f"(over {len(ours)} runs). Per-run rows: `{csv_path.name}`.\n",
    ]
    for family in FAMILIES:
        mine = [r for r in rows if r.family == family.name]
        lines += [f"### {family.name} (seeds 0..{family.seeds(config) - 1})\n"]
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
