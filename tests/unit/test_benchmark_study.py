import csv
from pathlib import Path

import numpy as np
import pytest

from gcs.cli.main import main
from planner.experiments.benchmark_config import StudyConfig
from planner.experiments.benchmark_runs import RunRecord, RunSpec, run_one
from planner.experiments.benchmark_study import run_study
from planner.experiments.executor import run_all
from planner.experiments.nfe_table import build_table
from planner.optimizers import OptimizeResult


def fake_record(function: str, algorithm: str, seed: int, history: list[float]) -> RunRecord:
    """A run of population 10 whose best cost follows `history`."""
    n = len(history)
    result = OptimizeResult(
        algorithm,
        np.zeros(2),
        history[-1],
        np.array(history),
        10 * np.arange(1, n + 1),
        10 * n,
        0.1,
    )
    return RunRecord(RunSpec(function, algorithm, 2, 10, n, seed), result)


def test_nfe_table_counts_failures_at_full_budget() -> None:
    records = [
        fake_record("sphere", "mvo", 0, [5.0, 1e-9, 0.0]),  # reaches 1e-8 after 20 evaluations
        fake_record("sphere", "mvo", 1, [5.0, 4.0, 3.0]),  # never: charged 30
        fake_record("sphere", "gwo", 0, [1e-9, 0.0, 0.0]),  # 10
        fake_record("sphere", "gwo", 1, [1.0, 1e-10, 0.0]),  # 20
    ]
    table = build_table(records, tolerance=1e-8)
    mvo, gwo = table.cells["sphere", "mvo"], table.cells["sphere", "gwo"]
    assert (mvo.successes, mvo.runs, mvo.charged_total, mvo.median_to_target) == (1, 2, 50, 20)
    assert (gwo.successes, gwo.charged_total, gwo.median_to_target) == (2, 30, 15)
    assert table.acceleration("gwo") == pytest.approx(50 / 30)
    assert table.fewest("sphere") == ["gwo"]


SPECS = [
    RunSpec(f, a, 3, 6, 15, s)
    for f in ("rastrigin", "ackley")
    for a in ("mvo", "alo")
    for s in range(2)
]


def summary(records: list[RunRecord]) -> list[tuple]:
    return [(r.spec, r.result.best_cost, r.result.history.tobytes()) for r in records]


def test_results_do_not_depend_on_the_executor() -> None:
    inline = run_all(run_one, SPECS, workers=1)
    pooled = run_all(run_one, SPECS, workers=2)
    assert summary(inline) == summary(pooled)


def test_dask_cluster_gives_the_same_results() -> None:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:
        on_dask = run_all(run_one, SPECS, scheduler=cluster.scheduler_address)
    assert summary(on_dask) == summary(run_all(run_one, SPECS, workers=1))


def test_study_writes_table_figures_csv_and_report(tmp_path: Path) -> None:
    config = StudyConfig(
        seeds=2,
        iterations=20,
        quick=True,
        figure_seeds=2,
        table_functions=("sphere", "step", "weierstrass"),
        figure_functions=("rastrigin", "ackley"),
    )
    report = run_study(config, tmp_path, workers=1)
    text = report.read_text()
    assert "## Table II, ours: tolerance 1e-08" in text
    assert "## Table II, the paper" in text
    assert "The paper's headline, that MVO needs the fewest evaluations" in text
    assert "![fig1_rastrigin](fig1_rastrigin.png)" in text
    for name in ("fig1_rastrigin.png", "fig1_ackley.png"):
        assert (tmp_path / name).read_bytes().startswith(b"\x89PNG")
    with (tmp_path / "runs.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    table_rows = 3 * 6 * 2  # functions x algorithms x seeds
    figure_rows = 2 * 2 * 2 * 6 * 2  # functions x dims x populations x algorithms x seeds
    assert len(rows) == table_rows + figure_rows
    assert {r["nfe"] for r in rows if r["dim"] == "30" and r["population"] == "30"} == {"600"}


def test_cli_reproduce_benchmarks(tmp_path: Path) -> None:
    code = main(
        [
            "reproduce",
            "benchmarks",
            "--out",
            str(tmp_path),
            "--seeds",
            "2",
            "--iterations",
            "5",
            "--quick",
            "--workers",
            "1",
            "--algorithms",
            "mvo",
            "woa",
        ]
    )
    assert code == 0
    assert (tmp_path / "REPORT.md").exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["reproduce", "benchmarks"],  # --out missing
        ["reproduce", "benchmarks", "--out", "x", "--seeds", "0"],
        ["reproduce", "benchmarks", "--out", "x", "--algorithms", "pso"],
        ["reproduce", "nothing"],
    ],
)
def test_cli_rejects_bad_arguments(argv: list[str], capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    assert "error" in capsys.readouterr().err


def test_table_runs_are_reused_by_the_figure_grid() -> None:
    config = StudyConfig(
        seeds=2,
        iterations=5,
        figure_seeds=2,
        figure_dims=(10, 30),
        figure_populations=(10, 30),
        table_functions=("rastrigin",),
        figure_functions=("rastrigin",),
    )
    table, figure = config.table_runs(), config.figure_runs()
    assert set(table) <= set(figure)
    assert len(set(table + figure)) == len(figure) == 4 * 6 * 2
