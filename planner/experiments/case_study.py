"""`mvo-gcs reproduce cases`: Table III and Figs. 3-5 of the paper, with a report."""

from __future__ import annotations

import csv
import time
from collections.abc import Sequence
from pathlib import Path

from planner.experiments.case_config import CaseStudyConfig
from planner.experiments.case_plots import (
    group_cases,
    plot_convergence,
    plot_final_costs,
    plot_times,
)
from planner.experiments.case_report import write_report
from planner.experiments.case_runs import CaseRecord, run_case
from planner.experiments.case_table import build_case_table
from planner.experiments.executor import run_all


def run_case_study(
    config: CaseStudyConfig,
    out: Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
) -> Path:
    """Plan every case with every algorithm, population and seed, then write runs.csv,
    the figures and REPORT.md."""
    started = time.perf_counter()
    records = run_all(run_case, config.runs(), workers=workers, scheduler=scheduler, desc="plans")
    wall = time.perf_counter() - started
    out.mkdir(parents=True, exist_ok=True)
    write_runs_csv(records, out / "runs.csv")
    table = build_case_table(records)
    groups = group_cases(records)
    pop = config.figure_population
    figures = [
        plot_convergence(groups, c, config.algorithms, pop, out / f"fig3_{c}.png")
        for c in config.cases
    ]
    figures.append(
        plot_final_costs(
            groups, config.cases, config.algorithms, config.populations, out / "fig4_final_J.png"
        )
    )
    figures.append(plot_times(table, out / "fig5_time.png"))
    return write_report(config, table, groups, figures, wall, out / "REPORT.md")


COLUMNS = (
    "case",
    "algorithm",
    "population",
    "seed",
    "planner_seed",
    "objective",
    "feasible",
    "J",
    "mean_deviation",
    "total_length",
    "conflicts",
    "nfe",
    "seconds",
)


def write_runs_csv(records: Sequence[CaseRecord], path: Path) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(COLUMNS)
        for r in records:
            s = r.spec
            writer.writerow(
                [
                    s.case,
                    s.algorithm,
                    s.population,
                    s.seed,
                    s.planner_seed(),
                    s.objective,
                    r.feasible,
                    repr(r.J),
                    repr(r.mean_deviation),
                    repr(r.total_length),
                    r.conflicts,
                    r.nfe,
                    f"{r.seconds:.4f}",
                ]
            )
