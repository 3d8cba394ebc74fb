"""REPORT.md of the case study: our Table III beside the paper's, and what differs."""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.cases import PAPER_POPULATIONS, PAPER_TABLE_III, load_case
from planner.experiments.case_comparison import compare_with_paper, lead_algorithm
from planner.experiments.case_plots import CaseGroups
from planner.experiments.case_table import (
    CaseTable,
    case_label,
    render_all_algorithms,
    render_table_iii,
    render_times,
)
from planner.experiments.machine import describe_machine
from planner.pipeline import PlannerSettings, plan
from planner.references import judge
from planner.references.cbs import MapfDependencyError, plan_cbs
from planner.references.prioritized import plan_prioritized

if TYPE_CHECKING:
    from planner.experiments.case_config import CaseStudyConfig


def write_report(
    config: CaseStudyConfig,
    table: CaseTable,
    groups: CaseGroups,
    figures: Sequence[Path],
    wall_seconds: float,
    path: Path,
) -> Path:
    lead = lead_algorithm(table)
    parts = [
        _header(config, len(config.runs()), wall_seconds),
        "## Table III: the paper / ours\n",
        f"Each cell is 'paper / ours'. Ours: {lead.upper()}'s mean over {config.seeds} seeds "
        "(Dist(t0) of the UAV that replans first; #UAV of eq. (10) as the planner counts it, "
        "UAVs plus non-UAV objects; deviation averaged over every population we ran; "
        "'-' where we did not run that population).\n",
        render_table_iii(table, lead) + "\n",
        "## Our J for every algorithm\n",
        f"Mean ± standard deviation over {config.seeds} seeds; the lowest mean of a row "
        "in bold (ties all bold); infeasible plans, if any, are counted in brackets.\n",
        render_all_algorithms(table) + "\n",
        "## Path lengths behind J\n",
        render_path_lengths(table, lead) + "\n",
        "## Execution time (Fig. 5)\n",
        "Mean seconds of one `plan(...)` over all cases, as measured inside the planner.\n",
        render_times(table) + "\n",
        "## Classic references on the same cases\n",
        render_references(config.cases),
        "## Where we agree with the paper and where we do not\n",
        "\n".join(f"- {line}" for line in compare_with_paper(config, table, groups)) + "\n",
        "## Figures\n",
        _figure_notes(config),
    ]
    parts.extend(f"![{fig.stem}]({fig.name})\n" for fig in figures)
    path.write_text("\n".join(parts))
    return path


def render_references(cases: Sequence[str]) -> str:
    """Prioritized space-time A* and CBS (pymapf) on each case, judged by our exact check.

    They reach every goal (deviation 0), which the paper's one-grid turn never does, so
    they are set beside our `qos` planner: length against each UAV's own shortest path,
    success by our check, and time.
    """
    rows = [
        "Judged by our exact continuous-time check (MAPF solvers count neither diagonal "
        "crossings as collisions nor a diagonal step as √2 long). Ours: MVO, `qos`, "
        "population 30, 1000 iterations, seed 1.\n",
        "| case | planner | feasible | length / shortest | mean deviation | seconds |",
        "|---|---|---|---:|---:|---:|",
    ]
    for case in cases:
        scenario = load_case(case)
        ours = plan(scenario, PlannerSettings().iterations_only())
        ratio = ours.length_ratio()
        rows.append(
            f"| {case} | MVO qos | {ours.feasible} | {ratio:.3f} | "
            f"{ours.metrics.mean_deviation:.2f} | {ours.metrics.seconds:.3f} |"
        )
        references = [plan_prioritized(scenario)]
        with contextlib.suppress(MapfDependencyError):
            references.append(plan_cbs(scenario))
        for reference in references:
            verdict = judge(scenario, reference)
            ratio_text = f"{verdict['length_ratio']:.3f}" if reference.solved else "-"
            deviation = f"{verdict['mean_deviation']:.2f}" if reference.solved else "-"
            rows.append(
                f"| {case} | {reference.name} | {verdict['feasible']} | {ratio_text} | "
                f"{deviation} | {reference.seconds:.3f} |"
            )
    return "\n".join(rows) + "\n"


def _header(config: CaseStudyConfig, runs: int, wall_seconds: float) -> str:
    pops = " ".join(str(p) for p in config.populations)
    return f"""# Reproduction of the paper's case study (Table III, Figs. 3-5)

- Command: `mvo-gcs reproduce cases --seeds {config.seeds} --iterations {config.iterations} \
--populations {pops} --algorithms {" ".join(config.algorithms)} \
--objective {config.objective} --out DIR`
- Machine: {describe_machine()}
- Settings: cases {", ".join(config.cases)}; algorithms {", ".join(config.algorithms)}; \
populations {pops}; {config.iterations} iterations per optimizer run; {config.seeds} seeds; \
objective `{config.objective}`. {runs} plans in {wall_seconds:.1f} s of wall-clock time.
- One plan is Algorithm 1 of the paper (`planner.pipeline.plan`): every UAV in conflict, \
then every UAV a non-UAV object touches, gets one optimizer run of {config.iterations} \
iterations. J is eq. (10) with all weights 1, averaged over the UAVs of the final plan.
- Each plan's seed is derived from its case, algorithm, population, iterations, objective \
and seed index (`planner_seed` in `runs.csv`), so results do not depend on the executor; \
`mvo-gcs plan case-K --objective {config.objective} --seed PLANNER_SEED ...` repeats one.
- The cases are small grids rebuilt from the paper's description (`planner/cases/README.md`).
- Every plan's figures are in `runs.csv`.
"""


def render_path_lengths(table: CaseTable, algorithm: str) -> str:
    """Markdown: the path per UAV the paper's J implies by eq. (10), beside ours."""
    lines = [
        "Eq. (10) is J = #UAV² · sp · deviation / Dist(t0), so the paper's own Dist(t0), "
        "#UAVs and deviation imply a path length sp = J · Dist(t0) / (#UAV² · deviation) "
        "(approximately: J is a mean over UAVs). Ours: mean path flown per UAV.\n",
        "| case | sp implied by the paper, N = "
        + " / ".join(str(p) for p in PAPER_POPULATIONS)
        + f" | ours ({algorithm.upper()}), cells per UAV |",
        "|---|---|---|",
    ]
    for case in table.cases:
        paper = PAPER_TABLE_III[case]
        factor = paper["dist"] / (paper["uavs"] ** 2 * paper["deviation"])
        implied = " / ".join(f"{j * factor:.2f}" for j in paper["J"])
        uavs = len(load_case(case).uavs)
        ours = np.mean([table.cells[case, algorithm, p].mean_length for p in table.populations])
        lines.append(f"| {case_label(case)} | {implied} | {ours / uavs:.2f} |")
    return "\n".join(lines)


def _figure_notes(config: CaseStudyConfig) -> str:
    return (
        f"Fig. 3 (one per case) is at population {config.figure_population}. "
        "Fig. 3: median and interquartile band over seeds of the plan cost after every "
        "iteration, the plan's optimizer runs one after another (a plan with fewer runs is "
        "held at its last value), symmetric-log axis; the dot is the median final J. "
        "Fig. 4: final J over the seeds, all populations pooled in the box and each run "
        "a dot coloured by its population. Fig. 5: mean seconds per plan.\n"
    )
