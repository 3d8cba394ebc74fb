"""`mvo-gcs reproduce benchmarks`: Table II and Fig. 1 of the paper, with a report."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

from planner.experiments.benchmark_config import StudyConfig
from planner.experiments.benchmark_report import write_report
from planner.experiments.benchmark_runs import RunRecord, run_one
from planner.experiments.convergence_plot import group_runs, plot_convergence
from planner.experiments.executor import run_all
from planner.experiments.nfe_table import build_table


def run_study(
    config: StudyConfig,
    out: Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
) -> Path:
    """Run every (deduplicated) run, then write runs.csv, the figures and REPORT.md."""
    table_specs = config.table_runs()
    specs = list(dict.fromkeys(table_specs + config.figure_runs()))
    records = run_all(run_one, specs, workers=workers, scheduler=scheduler, desc="benchmark runs")
    by_spec = dict(zip(specs, records, strict=True))
    out.mkdir(parents=True, exist_ok=True)
    write_runs_csv(records, config.tolerances, out / "runs.csv")

    table_records = [by_spec[s] for s in table_specs]
    tables = [build_table(table_records, tol) for tol in config.tolerances]
    groups = group_runs(records)
    figures = [
        plot_convergence(
            groups,
            f,
            config.figure_dims,
            config.figure_populations,
            config.algorithms,
            out / f"fig1_{f}.png",
        )
        for f in config.figure_functions
    ]
    return write_report(config, tables, figures, groups, out / "REPORT.md")


def write_runs_csv(records: Sequence[RunRecord], tolerances: Sequence[float], path: Path) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(
            [
                "function",
                "algorithm",
                "dim",
                "population",
                "iterations",
                "seed",
                "best_cost",
                "nfe",
                "seconds",
            ]
            + [f"nfe_to_{tol:g}" for tol in tolerances]
        )
        for r in records:
            s = r.spec
            reached = [r.nfe_to_reach(tol) for tol in tolerances]
            writer.writerow(
                [
                    s.function,
                    s.algorithm,
                    s.dim,
                    s.population,
                    s.iterations,
                    s.seed,
                    repr(r.result.best_cost),
                    r.result.nfe,
                    f"{r.result.seconds:.4f}",
                ]
                + ["" if n is None else n for n in reached]
            )
