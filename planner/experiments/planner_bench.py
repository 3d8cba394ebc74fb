"""`mvo-gcs bench planner`: the path planner's targets, measured.

- the six paper cases with both objectives (safety, deviation, length, J, time);
- speed and peak memory on case VI and on 12 UAVs over a 40x40 grid with obstacles;
- 100 generated crossing scenarios (20x20, 6 UAVs, 10 % obstacles, 2 non-UAV
  objects): how many plans are feasible, their length against each UAV's own
  shortest path, and why any plan was refused; beside the classic reference
  planners where they are available;
- fleet scale (`planner.experiments.fleet_bench`): up to 50 UAVs beside pymapf's LaCAM
  and prioritized planning, with the time to the first safe plan and peak memory.
"""

from __future__ import annotations

import contextlib
import csv
import statistics
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planner.cases import CASES, PAPER_TABLE_III, load_case
from planner.experiments.executor import run_all
from planner.experiments.fleet_bench import FleetConfig, fleet_section
from planner.experiments.machine import describe_machine
from planner.experiments.scenario_generator import crossing_scenario
from planner.model.plan import Plan
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory
from planner.pipeline import PlannerSettings, plan
from planner.references import ReferenceResult, judge
from planner.references.cbs import MapfDependencyError, plan_cbs
from planner.references.prioritized import plan_prioritized
from planner.search.objectives import ObjectiveName

FLEET = FleetConfig()


@dataclass(frozen=True)
class PlannerBenchConfig:
    scenarios: int = 100
    first_seed: int = 0
    algorithm: str = "mvo"
    population: int = 30
    iterations: int = 1000
    speed_repeats: int = 7
    large_repeats: int = 3
    workers: int | None = None  # for the generated scenarios only; timings run alone
    fleet: FleetConfig | None = FLEET  # None: leave the fleet section out

    def settings(self, objective: ObjectiveName = "qos", seed: int = 1) -> PlannerSettings:
        return PlannerSettings(self.algorithm, objective, seed, self.population, self.iterations)


@dataclass(frozen=True)
class ScenarioOutcome:
    """One generated scenario, planned by one planner: a row of the 100-scenario table."""

    seed: int
    planner: str
    feasible: bool  # by our exact check, every UAV at its goal, never too fast
    length_ratio: float
    seconds: float
    conflicts: list[str]


def plan_generated(task: tuple[int, PlannerSettings]) -> list[ScenarioOutcome]:
    """Our planner and the reference planners on one generated scenario."""
    seed, settings = task
    scenario = crossing_scenario(seed)
    result = plan(scenario, settings)
    name = f"{settings.algorithm.upper()} {settings.objective}"
    messages = [c["message"] for c in result.conflicts]
    paths = {u.id: Trajectory(np.array(u.trajectory)) for u in result.uavs}
    verdict = judge(scenario, ReferenceResult(name, paths, True, result.metrics.seconds))
    if result.feasible and not verdict["feasible"]:  # never expected; the report would say
        messages = ["marked feasible but not by the judge", *verdict["conflict_messages"]]
    outcomes = [
        ScenarioOutcome(
            seed,
            name,
            bool(verdict["feasible"]),
            result.length_ratio(),
            result.metrics.seconds,
            messages,
        )
    ]
    for reference in _references(scenario):
        verdict = judge(scenario, reference)
        ratio = verdict["length_ratio"] if reference.solved else float("nan")
        notes = verdict["conflict_messages"] or ([] if reference.solved else [reference.note])
        outcomes.append(
            ScenarioOutcome(
                seed, reference.name, bool(verdict["feasible"]), ratio, reference.seconds, notes
            )
        )
    return outcomes


def _references(scenario: Scenario) -> list[ReferenceResult]:
    results = [plan_prioritized(scenario)]
    with contextlib.suppress(MapfDependencyError):  # optional: the report says it did not run
        results.append(plan_cbs(scenario, time_limit=10.0))
    return results


def measure(
    fn: Callable[[int], Plan], repeats: int
) -> tuple[list[float], list[float], float, Plan]:
    """Wall seconds of `repeats` runs (seeds 1, 2, ...) and their times to the first safe
    plan, then the peak traced memory (MiB) of one more run."""
    seconds, firsts, result = [], [], None
    for seed in range(1, repeats + 1):
        start = time.perf_counter()
        result = fn(seed)
        seconds.append(time.perf_counter() - start)
        if result.metrics.first_safe_s is not None:
            firsts.append(result.metrics.first_safe_s)
    tracemalloc.start()
    fn(repeats + 1)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert result is not None
    return seconds, firsts, peak / 2**20, result


def run_planner_bench(config: PlannerBenchConfig, out: Path) -> Path:
    out.parent.mkdir(parents=True, exist_ok=True)
    sections = [_header(config), _cases_section(config), _speed_section(config)]
    sections.append(_generated_section(config, out.with_suffix(".csv")))
    if config.fleet is not None:
        sections.append(fleet_section(config.fleet, out.with_name(f"{out.stem}_fleet.csv")))
    out.write_text("\n".join(sections))
    return out


def _header(config: PlannerBenchConfig) -> str:
    return f"""# Path planner benchmark

- Command: `mvo-gcs bench planner --scenarios {config.scenarios} --first-seed \
{config.first_seed} --algorithm {config.algorithm} --population {config.population} \
--iterations {config.iterations}{_workers(config)}`
- Machine: {describe_machine()}
- Every plan is judged by the exact continuous-time check (`planner.check.safety`).
- Ours run with the default time budget of 5 s unless a section says otherwise; a
  plan ends when improving its first safe plan stops paying (converged), at the latest
  at the budget.
"""


def _workers(config: PlannerBenchConfig) -> str:
    return f" --workers {config.workers}" if config.workers else ""


def _cases_section(config: PlannerBenchConfig) -> str:
    rows = [
        "## The six paper cases (seed 1)\n",
        "| case | objective | feasible | conflicts | mean deviation (paper) | length / "
        "shortest | J | seconds |",
        "|---|---|---|---:|---:|---:|---:|---:|",
    ]
    for case in CASES:
        for objective in ("qos", "paper"):
            r = plan(load_case(case), config.settings(objective))
            paper = PAPER_TABLE_III[case]["deviation"]
            rows.append(
                f"| {case} | {objective} | {r.feasible} | {r.metrics.conflicts} | "
                f"{r.metrics.mean_deviation:.2f} ({paper}) | {r.length_ratio():.3f} | "
                f"{r.metrics.J:.3f} | {r.metrics.seconds:.2f} |"
            )
    return "\n".join(rows) + "\n"


def _speed_section(config: PlannerBenchConfig) -> str:
    rows = [
        "## Speed and memory\n",
        "Runs one after another in one process; peak memory is what tracemalloc saw "
        "(Python and numpy allocations) during one more run.\n",
        "| scenario | objective | runs | median s to first safe plan | median s | min s | "
        "max s | peak MiB | feasible |",
        "|---|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    jobs: list[tuple[str, Scenario, ObjectiveName, int]] = [
        ("case-6", load_case("case-6"), "qos", config.speed_repeats),
        ("case-6", load_case("case-6"), "paper", config.speed_repeats),
        (
            "crossing, 12 UAVs, 40x40, 10 % obstacles",
            crossing_scenario(1, size=40, uavs=12),
            "qos",
            config.large_repeats,
        ),
    ]
    for name, scenario, objective, repeats in jobs:
        seconds, firsts, peak, result = measure(_runner(config, scenario, objective), repeats)
        first = f"{statistics.median(firsts):.3f}" if firsts else "-"
        rows.append(
            f"| {name} | {objective} | {repeats} | {first} | {statistics.median(seconds):.3f} | "
            f"{min(seconds):.3f} | {max(seconds):.3f} | {peak:.1f} | {result.feasible} |"
        )
    return "\n".join(rows) + "\n"


def _runner(
    config: PlannerBenchConfig, scenario: Scenario, objective: ObjectiveName
) -> Callable[[int], Plan]:
    """Plan `scenario` with the given seed (what `measure` repeats)."""
    return lambda seed: plan(scenario, config.settings(objective, seed))


def _generated_section(config: PlannerBenchConfig, csv_path: Path) -> str:
    seeds = range(config.first_seed, config.first_seed + config.scenarios)
    tasks = [(seed, config.settings("qos", seed)) for seed in seeds]
    outcomes = [
        o
        for batch in run_all(plan_generated, tasks, workers=config.workers, desc="scenarios")
        for o in batch
    ]
    with csv_path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["seed", "planner", "feasible", "length_ratio", "seconds", "conflicts"])
        for o in outcomes:
            writer.writerow(
                [
                    o.seed,
                    o.planner,
                    o.feasible,
                    f"{o.length_ratio:.4f}",
                    f"{o.seconds:.3f}",
                    " | ".join(o.conflicts),
                ]
            )
    lines = [
        f"## {config.scenarios} generated crossing scenarios\n",
        f"Seeds {seeds.start}..{seeds.stop - 1} of `crossing_scenario` (20x20, 6 UAVs "
        "crossing near the centre, 10 % obstacles, 2 non-UAV objects); ours with "
        f"population {config.population} and {config.iterations} iterations. Plans run "
        f'{config.workers or "one per core"} at a time. "Feasible" is judged by our exact '
        "check for every planner: no conflict, every UAV at its goal, never faster than "
        f"its speed. Targets for ours (issue 13): at least 98 % feasible, median at most "
        f"0.25 s, median length ratio at most 0.99. Per-scenario rows: `{csv_path.name}`.\n",
        "| planner | feasible | median length ratio (feasible plans) | median seconds |",
        "|---|---:|---:|---:|",
    ]
    for name in dict.fromkeys(o.planner for o in outcomes):
        mine = [o for o in outcomes if o.planner == name]
        ok = [o.length_ratio for o in mine if o.feasible]
        median = f"{statistics.median(ok):.3f}" if ok else "-"
        lines.append(
            f"| {name} | {len(ok)} of {len(mine)} | {median} | "
            f"{statistics.median(o.seconds for o in mine):.3f} |"
        )
    if not any(o.planner.startswith("CBS") for o in outcomes):
        lines.append("\nCBS did not run: install the `mapf` extra (`pip install -e '.[mapf]'`).")
    ours = outcomes[0].planner
    wrong = sum(o.conflicts[:1] == ["marked feasible but not by the judge"] for o in outcomes)
    lines.append(f"\n{ours} plans it marked feasible that the judge found unsafe: {wrong}.")
    refused = [o for o in outcomes if o.planner == ours and not o.feasible]
    if refused:
        lines.append(f"\n{ours} plans refused, and why:\n")
        lines.extend(f"- seed {o.seed}: " + "; ".join(o.conflicts) for o in refused)
    return "\n".join(lines) + "\n"
