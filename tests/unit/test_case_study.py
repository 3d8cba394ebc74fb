import csv
from pathlib import Path

import pytest

from gcs.cli.main import main
from planner.experiments.case_config import CaseStudyConfig
from planner.experiments.case_plots import padded_histories
from planner.experiments.case_runs import CaseRecord, CaseSpec, run_case
from planner.experiments.case_study import run_case_study
from planner.experiments.executor import run_all

TINY = CaseStudyConfig(
    seeds=2,
    iterations=20,
    populations=(10,),
    algorithms=("mvo", "gwo"),
    cases=("case-1", "case-3"),
)


def test_study_writes_runs_figures_and_report(tmp_path: Path) -> None:
    report = run_case_study(TINY, tmp_path, workers=1)
    with (tmp_path / "runs.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2 * 2 * 2  # cases x algorithms x seeds
    assert {r["objective"] for r in rows} == {"paper"}
    assert {r["mean_deviation"] for r in rows if r["case"] == "case-1"} == {"0.5"}
    figures = ["fig3_case-1.png", "fig3_case-3.png", "fig4_final_J.png", "fig5_time.png"]
    for name in figures:
        assert (tmp_path / name).read_bytes().startswith(b"\x89PNG")
        assert f"]({name})" in report.read_text()
    text = report.read_text()
    assert "## Table III: the paper / ours" in text
    for paper_value in ("2.0178", "1.9023", "11.3137", "11.1265", "2.83"):
        assert paper_value in text
    assert "0.152" in text and "33.686" in text
    assert "inconsistent with its own Table III" in text


def test_results_do_not_depend_on_the_executor() -> None:
    specs = TINY.runs()
    inline = run_all(run_case, specs, workers=1)
    pooled = run_all(run_case, specs, workers=2)
    assert [r.outcome() for r in inline] == [r.outcome() for r in pooled]
    assert len({s.planner_seed() for s in specs}) == len(specs)


def test_histories_are_padded_with_their_last_value() -> None:
    spec = CaseSpec("case-1", "mvo", 10, 2, "paper", 0)
    runs = [
        CaseRecord(spec, True, 1.0, 0.5, 8.0, 0, 20, 0.1, 4.0, (5.0, 3.0)),
        CaseRecord(spec, True, 1.0, 0.5, 8.0, 0, 40, 0.1, 4.0, (6.0, 4.0, 2.0, 1.0)),
    ]
    assert padded_histories(runs).tolist() == [[5, 3, 3, 3], [6, 4, 2, 1]]


def test_cli_reproduce_cases(tmp_path: Path) -> None:
    argv = ["reproduce", "cases", "--out", str(tmp_path), "--seeds", "1", "--iterations", "5"]
    argv += ["--populations", "10", "--algorithms", "woa", "--cases", "case-2", "--workers", "1"]
    assert main(argv) == 0
    assert (tmp_path / "REPORT.md").exists()
    with (tmp_path / "runs.csv").open() as handle:
        assert len(list(csv.DictReader(handle))) == 1


@pytest.mark.parametrize(
    "argv",
    [
        ["reproduce", "cases"],  # --out missing
        ["reproduce", "cases", "--out", "x", "--seeds", "0"],
        ["reproduce", "cases", "--out", "x", "--populations", "0"],
        ["reproduce", "cases", "--out", "x", "--algorithms", "pso"],
        ["reproduce", "cases", "--out", "x", "--objective", "fast"],
        ["reproduce", "cases", "--out", "x", "--cases", "case-7"],
        ["reproduce", "cases", "--out", "x", "--workers", "0"],
    ],
)
def test_cli_rejects_bad_arguments(argv: list[str], capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    assert "error" in capsys.readouterr().err
