"""The side-by-side benchmark against mealpy and EvoloPy, at a tiny size."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

pytest.importorskip("mealpy", reason="needs the 'bench' extra: pip install -e '.[bench]'")
pytest.importorskip("EvoloPy", reason="needs the 'bench' extra: pip install -e '.[bench]'")
pytest.importorskip("scipy", reason="needs the 'bench' extra: pip install -e '.[bench]'")

from planner.experiments.library_comparison import (
    ComparisonConfig,
    run_comparison,
)


def test_tiny_comparison_writes_markdown_and_csv(tmp_path: Path) -> None:
    config = ComparisonConfig(seeds=2, iterations=20, dim=5, algorithms=("mvo", "gwo"))
    out = run_comparison(config, tmp_path / "results" / "optimizers.md")

    assert out == tmp_path / "results" / "optimizers.md"
    text = out.read_text(encoding="utf-8")
    assert "mvo-gcs bench optimizers --seeds 2 --iterations 20 --population 30 --dim 5" in text
    assert "## Rastrigin (dim 5)" in text
    assert "## Sphere (dim 5)" in text
    table_rows = [line for line in text.splitlines() if line.startswith(("| MVO |", "| GWO |"))]
    assert len(table_rows) == 2 * 2 * 2  # quality table and NFE table, per function
    assert "mealpy: 3.0.3" in text and "EvoloPy: 4.0.6" in text
    assert text.count("| GWO with EvoloPy's leader demotion |") == 2

    with out.with_suffix(".csv").open(newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    # functions x seeds x (3 libraries x 2 algorithms + GWO's EvoloPy-rule variant)
    assert len(rows) == 2 * 2 * (3 * 2 + 1)
    keys = {(r["function"], r["algorithm"], r["library"], r["seed"]) for r in rows}
    assert ("rastrigin", "mvo", "evolopy", "1") in keys
    assert ("sphere", "gwo", "mealpy", "0") in keys
    assert ("sphere", "gwo", "ours-variant", "1") in keys
    for row in rows:
        assert float(row["seconds"]) > 0
        assert float(row["best_cost"]) >= 0
    ours = [r for r in rows if r["library"] == "ours"]
    assert {int(r["nfe"]) for r in ours} == {30 * 20}
