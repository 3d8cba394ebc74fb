"""The planner at a MAVLink network's scale, beside pymapf 0.9.0's LaCAM, in one run.

Families (fixed seeds; `planner.experiments.scenario_generator`):

- dense crossings through a centre: 17 UAVs on 41 x 41 and 40 on a ring of 81 x 81
  (`crossing_scenario`, 10 % obstacles, no non-UAV objects);
- dense short trips: 100 UAVs on 60 x 60, 12 % obstacles, goals at most 8 cells away
  (`short_trips_scenario`);
- random scatter at 10 % obstacles: 100 UAVs on 200 x 200 and 250 on 250 x 250
  (`random_scenario(..., objects=0, min_gap=2.0)`, issue 13's family);
- swaps through a corridor: 6 UAVs on 10 x 10 through a 2-cell gap in a wall
  (`gap_swap_scenario`).

Per plan: ours (`qos`, the default settings, `--budget` s), LaCAM (its first solution,
the same limit) and pymapf's prioritized planning (PP, stopped at the limit + 1 s), each
judged by our exact check (`planner.references.judge`). Then the anytime curve: ours
on the 100-UAV families again with 5 s more budget. Peak memory of ours on 250 UAVs on
500 x 500 (tracemalloc, and the process's peak RSS).

    .venv/bin/python bench/planner_scale.py --seeds 3 --budget 5 \\
        --out bench/results/planner_scale.md

The 1-minute load average is written before and after each family: the machine is
shared (2 cores).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import functools
import os
import platform
import resource
import shlex
import statistics
import sys
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from planner.experiments.fleet_bench import run_ours, run_reference
from planner.experiments.fleet_tables import OURS, Row, median_text, write_csv
from planner.experiments.scenario_generator import (
    crossing_scenario,
    gap_swap_scenario,
    random_scenario,
    short_trips_scenario,
)
from planner.model.scenario import Scenario
from planner.pipeline import PlannerSettings, plan
from planner.references.pymapf_solvers import plan_lacam, plan_pymapf_prioritized

LACAM = "LaCAM (pymapf), 4-connected"


@dataclass(frozen=True)
class Family:
    name: str
    build: Callable[[int], Scenario]
    time_target: float | None = None  # the target for ours, s
    dense: bool = False  # the issue asks ours to be no slower than LaCAM here


FAMILIES = [
    Family(
        "dense crossing, 17 UAVs, 41x41",
        lambda s: crossing_scenario(s, size=41, uavs=17, objects=0),
        dense=True,
    ),
    Family(
        "dense crossing, 40 UAVs on a ring, 81x81",
        lambda s: crossing_scenario(s, size=81, uavs=40, objects=0),
        dense=True,
    ),
    Family(
        "dense short trips, 100 UAVs, 60x60, 12 %",
        lambda s: short_trips_scenario(s, size=60, uavs=100, obstacle_share=0.12),
        dense=True,
    ),
    Family(
        "swaps through a corridor, 6 UAVs, 10x10",
        lambda s: gap_swap_scenario(s),
        dense=True,
    ),
    Family(
        "random, 100 UAVs, 200x200, 10 %",
        lambda s: random_scenario(s, size=200, uavs=100, objects=0, min_gap=2.0),
        time_target=2.0,
    ),
    Family(
        "random, 200 UAVs, 250x250, 10 %",
        lambda s: random_scenario(s, size=250, uavs=200, objects=0, min_gap=2.0),
    ),
    Family(
        "random, 250 UAVs, 250x250, 10 %",
        lambda s: random_scenario(s, size=250, uavs=250, objects=0, min_gap=2.0),
        time_target=5.0,
    ),
    Family(
        "random, 400 UAVs, 500x500, 10 % (planning only)",
        lambda s: random_scenario(s, size=500, uavs=400, objects=0, min_gap=2.0),
    ),
]


def load() -> float:
    return os.getloadavg()[0]


def run_family(
    family: Family, seeds: int, budget: float, pp: bool, safe_start_limit_s: float | None = None
) -> list[Row]:
    """Ours, LaCAM and (with `pp`) PP on each seed; `safe_start_limit_s` bounds our safe
    start (None: it runs to its end, the product's default)."""
    rows: list[Row] = []
    for seed in range(seeds):
        scenario = family.build(seed)
        runs: list[Callable[[], Row]] = [
            functools.partial(run_ours, scenario, seed, budget, safe_start_limit_s),
            functools.partial(
                run_reference, scenario, seed, functools.partial(plan_lacam, time_limit=budget)
            ),
        ]
        if pp:
            solve = functools.partial(plan_pymapf_prioritized, time_limit=budget)
            runs.append(functools.partial(run_reference, scenario, seed, solve))
        for run in runs:
            row = dataclasses.replace(run(), family=family.name)
            rows.append(row)
            print(
                family.name,
                seed,
                row.planner,
                row.feasible,
                f"{row.seconds:.2f}",
                row.length_ratio,
                f"load {load():.2f}",
                flush=True,
            )
    return rows


def anytime_curve(family: Family, seeds: int, budgets: list[float]) -> list[str]:
    """Total length of ours at each budget (seed = scenario seed), per seed."""
    lines = []
    for seed in range(seeds):
        scenario = family.build(seed)
        cells = []
        for budget in budgets:
            result = plan(scenario, PlannerSettings(seed=seed, time_budget_s=budget))
            m = result.metrics
            length = f"{m.total_length:.1f} / {m.cost:.1f}" if result.feasible else "unsafe"
            cells.append(f"{length} ({m.seconds:.1f} s, {result.stop_reason})")
            print(family.name, seed, budget, cells[-1], flush=True)
        lines.append(f"| {family.name} | {seed} | " + " | ".join(cells) + " |")
    return lines


def memory_run(size: int, uavs: int, budget: float) -> tuple[float, float, bool]:
    """Peak traced MiB and seconds of ours on `uavs` UAVs on size x size."""
    scenario = random_scenario(0, size=size, uavs=uavs, objects=0, min_gap=2.0)
    tracemalloc.start()
    started = time.perf_counter()
    try:
        result = plan(scenario, PlannerSettings(seed=0, time_budget_s=budget))
        return (
            tracemalloc.get_traced_memory()[1] / 2**20,
            time.perf_counter() - started,
            (result.feasible),
        )
    finally:
        tracemalloc.stop()


def read_csv(path: Path) -> list[Row]:
    """Rows as `write_csv` wrote them."""

    def number(text: str) -> float | None:
        return float(text) if text else None

    with path.open(newline="") as handle:
        return [
            Row(
                r["family"],
                int(r["seed"]),
                r["planner"],
                r["feasible"] == "True",
                number(r["first_safe_s"]),
                float(r["seconds"]),
                number(r["length_ratio"]),
                number(r["improvement"]),
                r["stop_reason"],
                r["note"],
                r["marked"] == "True",
            )
            for r in csv.DictReader(handle)
        ]


def summary(rows: list[Row], families: list[Family]) -> list[str]:
    lines = [
        "| family | ours safe | ours median s to first safe (max) | ours median s (max) | "
        "ours median ratio (max) | "
        "LaCAM safe | LaCAM median s | LaCAM median ratio | PP safe | PP median s | "
        "PP median ratio | ours no slower than LaCAM (dense) | target s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|",
    ]
    for family in families:
        mine = [r for r in rows if r.family == family.name]
        cells = []
        medians = {}
        for name in (OURS, LACAM, "PP"):
            runs = [
                r
                for r in mine
                if r.planner == name or (name == "PP" and r.planner.startswith("prioritized"))
            ]
            ok = [r for r in runs if r.feasible]
            ratio = [r.length_ratio for r in ok if r.length_ratio is not None]
            secs = [r.seconds for r in runs]
            timed = secs if name == OURS else [r.seconds for r in ok]
            medians[name] = statistics.median(timed) if timed else None
            if name == OURS:
                worst = f" ({max(secs):.2f})" if secs else ""
                worst_ratio = f" ({max(ratio):.3f})" if ratio else ""
                firsts = [r.first_safe_s for r in ok if r.first_safe_s is not None]
                first_worst = f" ({max(firsts):.2f})" if firsts else ""
                medians["first"] = statistics.median(firsts) if firsts else None
                cells += [
                    f"{len(ok)}/{len(runs)}",
                    median_text(firsts, 2) + first_worst,
                    median_text(secs, 2) + worst,
                    median_text(ratio) + worst_ratio,
                ]
            else:
                cells += [
                    f"{len(ok)}/{len(runs)}",
                    median_text([r.seconds for r in ok], 2),
                    median_text(ratio),
                ]
        first, ours_s, lacam_s = medians.get("first"), medians[OURS], medians[LACAM]
        faster = "-"
        if family.dense and first is not None and ours_s is not None and lacam_s is not None:
            faster = (
                f"first safe: {'yes' if first <= lacam_s else 'no'}; "
                f"plan: {'yes' if ours_s <= lacam_s else 'no'}"
            )
        target = f"{family.time_target:g}" if family.time_target else "-"
        lines.append(f"| {family.name} | " + " | ".join(cells) + f" | {faster} | {target} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--budget", type=float, default=5.0)
    parser.add_argument("--families", default="", help="comma-separated name prefixes")
    parser.add_argument("--no-pp", action="store_true", help="leave pymapf's PP out")
    parser.add_argument("--no-curve", action="store_true")
    parser.add_argument(
        "--curve-budgets",
        default="",
        help="comma-separated budgets (s) of the anytime curve (default: the budget and 5 s more)",
    )
    parser.add_argument("--no-memory", action="store_true")
    parser.add_argument("--out", type=Path, default=Path("bench/results/planner_scale.md"))
    parser.add_argument(
        "--rows", type=Path, help="tables from these per-run rows (a CSV this wrote), not runs"
    )
    args = parser.parse_args()
    wanted = [p.strip() for p in args.families.split(",") if p.strip()]
    families = [f for f in FAMILIES if not wanted or any(f.name.startswith(p) for p in wanted)]
    started, load_before = datetime.now(UTC), load()
    rows: list[Row] = []
    loads = []
    csv_path = args.out.with_suffix(".csv")
    if args.rows:
        rows = read_csv(args.rows)
        csv_path = args.rows
    else:
        for family in families:
            before = load()
            rows += run_family(family, args.seeds, args.budget, not args.no_pp)
            loads.append(f"| {family.name} | {before:.2f} | {load():.2f} |")
        write_csv(rows, csv_path)
    lines = [
        "# The planner at a MAVLink network's scale, beside LaCAM\n",
        f"- Run {started:%Y-%m-%d %H:%M} UTC on {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores shared with other work, Python {platform.python_version()}, "
        f"numpy {np.__version__}; 1-minute load average {load_before:.2f} at the start.",
        f"- Command: `.venv/bin/python bench/planner_scale.py {shlex.join(sys.argv[1:])}`"
        ". One planner at a time in one process.",
        f"- Ours: MVO `qos`, default settings, time budget {args.budget:g} s (it bounds only "
        "the improvement: the safe start runs to its end), seed = scenario seed. LaCAM: its "
        f"first solution, time limit {args.budget:g} s. PP: pymapf's prioritized planning, "
        f"stopped at {args.budget + 1:g} s.",
        "- Every plan judged by our exact continuous-time check (safe = no conflict, every UAV "
        "on its goal, never faster than its speed). Length ratio: total length over the sum "
        "of each UAV's 8-connected shortest path alone (below 1: ours are any-angle). Times: "
        "wall seconds until the plan was returned, medians over seeds "
        f"0..{args.seeds - 1}; for LaCAM and PP over their safe plans.\n",
        *summary(rows, families),
        "",
        *(
            [
                "Load average (1 minute) before and after each family:\n",
                "| family | before | after |",
                "|---|---:|---:|",
                *loads,
                "",
            ]
            if loads
            else []
        ),
        f"Per-run rows: `{csv_path.name}`.",
        "",
    ]
    if not args.no_curve:
        budgets = [float(b) for b in args.curve_budgets.split(",") if b.strip()] or [
            args.budget,
            args.budget + 5.0,
        ]
        curve = [f for f in families if "100 UAVs" in f.name]
        lines += [
            "## Anytime: the 100-UAV families at growing budgets\n",
            "Total length / cost (length + the hover price) of ours (wall seconds, stop reason) "
            "at each budget. Improvement lowers the cost: the length may rise a little where "
            "a hover is traded for a detour.\n",
            "| family | seed | " + " | ".join(f"{b:g} s" for b in budgets) + " |",
            "|---|---:|" + "---:|" * len(budgets),
        ]
        for family in curve:
            lines += anytime_curve(family, args.seeds, budgets)
        lines.append("")
    if not args.no_memory:
        mib, seconds, feasible = memory_run(500, 250, args.budget)
        lines += [
            "## Memory: 250 UAVs on 500 x 500\n",
            f"`random_scenario(0, size=500, uavs=250, objects=0, min_gap=2.0)`, ours with a "
            f"{args.budget:g} s budget: peak traced allocation {mib:.1f} MiB (tracemalloc: "
            f"Python and numpy), {seconds:.1f} s under tracing, feasible {feasible}. Peak RSS "
            f"of the whole benchmark process: "
            f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB.",
            "",
        ]
    args.out.write_text("\n".join(lines))
    print(args.out.read_text())


if __name__ == "__main__":
    main()
