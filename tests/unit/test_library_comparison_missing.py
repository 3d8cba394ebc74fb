"""Without the 'bench' extra the comparison says what to install instead of failing deep inside."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from gcs.cli.main import main
from planner.experiments.library_comparison import BenchDependencyError

HAVE_BENCH = all(importlib.util.find_spec(m) for m in ("mealpy", "EvoloPy", "scipy"))


@pytest.mark.skipif(HAVE_BENCH, reason="the 'bench' extra is installed here")
def test_missing_libraries_give_an_install_hint(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["bench", "optimizers", "--out", str(tmp_path / "x.md"), "--seeds", "1"])
    assert exit_info.value.code == 2
    assert "pip install -e '.[bench]'" in capsys.readouterr().err
    assert issubclass(BenchDependencyError, ImportError)
