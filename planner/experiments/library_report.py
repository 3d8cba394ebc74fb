"""The markdown report of the optimizer benchmark against mealpy and EvoloPy.

Medians per (function, algorithm, library), the speed-ups, a Mann-Whitney test of ours
against EvoloPy, the NFE table, the machine and the command; what differs in the
libraries and why.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from planner.experiments.library_config import (
    ALPHA,
    LIBRARIES,
    SPEED_TARGET,
    VARIANT,
    VARIANTS,
    ComparisonConfig,
    Libraries,
    Run,
)
from planner.experiments.machine import cpu_model


def _values(
    runs: list[Run], function: str, algorithm: str, library: str, attr: str
) -> NDArray[np.float64]:
    return np.array(
        [
            getattr(r, attr)
            for r in runs
            if (r.function, r.algorithm, r.library) == (function, algorithm, library)
        ],
        dtype=np.float64,
    )


def _median(values: NDArray[np.float64]) -> float | None:
    return float(np.median(values)) if values.size else None


def _fmt(value: float | None, spec: str = ".3g") -> str:
    return "—" if value is None else format(value, spec)


def _speedup(ours_s: float, libs_s: dict[str, float | None]) -> tuple[float, str]:
    """Ratio of medians against the faster library, and that library's name."""
    available = {lib: s for lib, s in libs_s.items() if s is not None}
    lib = min(available, key=lambda k: available[k])
    return available[lib] / ours_s, lib


def _p_value(libs: Libraries, ours: NDArray[np.float64], evo: NDArray[np.float64]) -> float:
    return float(libs.stats.mannwhitneyu(ours, evo, alternative="two-sided").pvalue)


def _verdict(speedup: float, faster: str, p: float | None, ours: float, evo: float | None) -> str:
    met = "met" if speedup >= SPEED_TARGET else "**NOT met**"
    speed = (
        f"speed {speedup:.1f}x vs {_LIB_NAMES[faster]} "
        f"({'≥' if speedup >= SPEED_TARGET else '<'} {SPEED_TARGET:g}x): {met}"
    )
    if p is None or evo is None:
        return f"{speed}; quality: no EvoloPy version to test against"
    if p >= ALPHA:
        return f"{speed}; quality: indistinguishable from EvoloPy (p ≥ {ALPHA:g})"
    side = "lower (better)" if ours < evo else "higher (worse)"
    return f"{speed}; quality: **differs** from EvoloPy (p < {ALPHA:g}; our median is {side})"


_LIB_NAMES = {"ours": "ours", "mealpy": "mealpy", "evolopy": "EvoloPy"}


_TABLE_HEADER = (
    "| algorithm | ours median s | mealpy median s | EvoloPy median s "
    "| speed-up vs faster library | ours median best | mealpy median best "
    "| EvoloPy median best | Mann-Whitney p (ours vs EvoloPy) | verdict |\n"
    "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|"
)


def _table_row(libs: Libraries, runs: list[Run], function: str, algorithm: str) -> str:
    seconds = {
        lib: _median(_values(runs, function, algorithm, lib, "seconds")) for lib in LIBRARIES
    }
    costs = {lib: _values(runs, function, algorithm, lib, "best_cost") for lib in LIBRARIES}
    best = {lib: _median(v) for lib, v in costs.items()}
    ours_s, ours_best = seconds.pop("ours"), best["ours"]
    assert ours_s is not None and ours_best is not None
    speedup, faster = _speedup(ours_s, seconds)
    p = _p_value(libs, costs["ours"], costs["evolopy"]) if costs["evolopy"].size else None
    cells = [
        algorithm.upper(),
        _fmt(ours_s),
        _fmt(seconds["mealpy"]),
        _fmt(seconds["evolopy"]),
        f"{speedup:.1f}x ({_LIB_NAMES[faster]})",
        _fmt(ours_best, ".4g"),
        _fmt(best["mealpy"], ".4g"),
        _fmt(best["evolopy"], ".4g"),
        _fmt(p),
        _verdict(speedup, faster, p, ours_best, best["evolopy"]),
    ]
    return "| " + " | ".join(cells) + " |"


def _nfe_table(runs: list[Run], config: ComparisonConfig, function: str) -> str:
    lines = [
        "| algorithm | ours NFE | mealpy NFE | EvoloPy NFE |",
        "|---|---:|---:|---:|",
    ]
    for algorithm in config.algorithms:
        nfe = [_median(_values(runs, function, algorithm, lib, "nfe")) for lib in LIBRARIES]
        lines.append(f"| {algorithm.upper()} | " + " | ".join(_fmt(n, ".0f") for n in nfe) + " |")
    return "\n".join(lines)


def _variant_rows(libs: Libraries, runs: list[Run], config: ComparisonConfig, function: str) -> str:
    """Diagnostic rows: our variants that adopt an EvoloPy rule, against EvoloPy."""
    rows = []
    for algorithm in (a for a in config.algorithms if a in VARIANTS):
        variant = _values(runs, function, algorithm, VARIANT, "best_cost")
        evo = _values(runs, function, algorithm, "evolopy", "best_cost")
        p = _p_value(libs, variant, evo)
        verdict = "indistinguishable" if p >= ALPHA else "**differs**"
        rows.append(
            f"| {VARIANTS[algorithm][0]} | {_fmt(_median(variant), '.4g')} | "
            f"{_fmt(_median(evo), '.4g')} | {_fmt(p)} | {verdict} |"
        )
    if not rows:
        return ""
    return (
        "\nDiagnostic: ours with one EvoloPy rule adopted, against EvoloPy (same seeds):\n\n"
        "| variant | ours-variant median best | EvoloPy median best | Mann-Whitney p | verdict |\n"
        "|---|---:|---:|---:|---|\n" + "\n".join(rows) + "\n"
    )


def _function_section(
    libs: Libraries, runs: list[Run], config: ComparisonConfig, function: str
) -> str:
    rows = "\n".join(_table_row(libs, runs, function, a) for a in config.algorithms)
    return (
        f"## {function.capitalize()} (dim {config.dim})\n\n{_TABLE_HEADER}\n{rows}\n"
        f"{_variant_rows(libs, runs, config, function)}\n"
        "Objective evaluations per run (median; mealpy also evaluates its initial population "
        f"before its {config.iterations} iterations):\n\n{_nfe_table(runs, config, function)}\n"
    )


def _package_version(name: str) -> str:
    try:
        return version(name)
    except PackageNotFoundError:
        return "not installed"


_MEASURED = ("planner/optimizers", "planner/optimizers/benchmarks.py")


def code_version() -> str:
    """The git commit of this checkout, flagged if the measured code has uncommitted changes."""
    root = Path(__file__).resolve().parents[2]
    try:
        commit = _git(root, "rev-parse", "--short", "HEAD")
        dirty = _git(root, "status", "--porcelain", "--", *_MEASURED)
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"
    return f"git {commit}" + (
        f" with uncommitted changes in {', '.join(_MEASURED)}" if dirty else ""
    )


def _git(root: Path, *args: str) -> str:
    return subprocess.run(
        ["git", *args], cwd=root, capture_output=True, text=True, check=True
    ).stdout.strip()


def _machine(code: str) -> str:
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else "?"
    items = {
        "platform": platform.platform(),
        "CPU": cpu_model(),
        "cores": f"{os.cpu_count()} logical ({usable} usable by this process)",
        "Python": sys.version.split()[0],
        "numpy": np.__version__,
        "scipy": _package_version("scipy"),
        "mealpy": _package_version("mealpy"),
        "EvoloPy": _package_version("evolopy"),
        "code": code,
    }
    return "\n".join(f"- {key}: {value}" for key, value in items.items())


def _command(config: ComparisonConfig, out_path: Path) -> str:
    command = (
        f"mvo-gcs bench optimizers --seeds {config.seeds} --iterations {config.iterations} "
        f"--population {config.population} --dim {config.dim} "
        f"--algorithms {' '.join(config.algorithms)} --out {out_path}"
    )
    if config.functions != ComparisonConfig.functions:
        command += f"  # functions: {', '.join(config.functions)} (not a CLI option)"
    return command


def report(
    config: ComparisonConfig, runs: list[Run], libs: Libraries, out_path: Path, code: str
) -> str:
    sections = "\n".join(_function_section(libs, runs, config, f) for f in config.functions)
    return f"""# Our optimizers against mealpy and EvoloPy

Each algorithm: population {config.population}, {config.iterations} iterations, \
{config.seeds} seeds (0..{config.seeds - 1}) per library, minimising each function at \
dimension {config.dim}. All runs happen in one process, one after another; for every seed \
ours, mealpy's and EvoloPy's versions run back to back. Times are wall seconds \
(`time.perf_counter()`) around `planner.optimize`, mealpy's `solve` and EvoloPy's optimizer \
function. The libraries get the same benchmark function one vector at a time. "best" is each \
run's final best cost; raw rows are in `{out_path.with_suffix(".csv").name}`.

Targets: ours at least {SPEED_TARGET:g}x faster than the faster library (ratio of medians); \
best costs not significantly different from EvoloPy's (two-sided Mann-Whitney rank-sum test, \
p ≥ {ALPHA:g}). EvoloPy has no ALO or DA, so those two are timed against mealpy only and \
their quality is not tested.

## Machine

{_machine(code)}

## Command

```
{_command(config, out_path)}
```

{sections}
{_EXPLANATIONS}"""


_EXPLANATIONS = """## Why mealpy's figures differ

mealpy 3.0.3's `Original*` classes are not line-for-line ports of the authors' MATLAB code,
so their best costs are not expected to match ours or EvoloPy's. Read from its source:

- **Greedy selection.** MVO, GWO, MFO, WOA and DO evaluate every new candidate as soon as
  it is made and keep it only if it beats the agent it came from (`get_better_agent`); an
  agent never gets worse. The original algorithms move every agent unconditionally.
- **MVO.** The normalised inflation rate is `(f - min f) / sum(f - min f)` (`normalize__`),
  not MATLAB's `normr`, `f / ||f||`; the exchange probabilities are therefore much smaller.
- **WOA.** The "random whale" of the search phase is a fresh uniform point in the box
  (`self.problem.generate_solution()`), not a member of the population; `A` and `C` share one
  random number, and `l` is drawn in [-1, 1].
- **MFO.** There is no flame archive: the flames are the current (greedily kept) population,
  sorted, instead of the best of the previous flames and the moths; one spiral `t` per moth
  instead of per coordinate; moths beyond the flame count spiral around the best flame.
- **ALO.** The roulette (`get_index_roulette_wheel_selection`) weights antlion i by
  `max f - f_i`, so the worst antlion has weight 0 and can never be picked (ALO.m weights by
  `1/f`); the elite overwrites the last, worst, antlion. Each walk is a Python loop over
  dimensions, each a full `epoch`-step cumulative sum, which is why it is so slow.
- **DO (DA).** The step vectors are themselves evaluated as candidate solutions, clipped to
  the search box and kept greedily by their own cost: every iteration costs 2 x population
  evaluations (plus 2 x population at the start), so its NFE is twice the others'. The enemy
  is the current population's worst, and the Lévy step is one scalar per dragonfly.

## What to keep in mind about EvoloPy

- Its MFO loop runs `while Iteration < Max_iteration`, one iteration fewer than asked (see the
  NFE table), and beyond the flame count it uses flame `Flame_no` (0-based), one more than
  MFO.m.
- Its GWO demotes the old alpha to beta (and beta to delta) when a new alpha is found; GWO.m,
  which ours follows, does not. That rule alone is enough to make GWO's best costs differ
  from ours: with the demotion removed, EvoloPy's GWO matches ours.
- Its WOA moves whales one at a time in place, so a whale searching around a lower-index
  partner reads that partner's new position; ours reproduces that exactly (see
  `planner/optimizers/woa.py`). In MVO, GWO and MFO no agent reads another's new position,
  so the order does not matter there.
- It prints one line per iteration; that printing (to `/dev/null` here) is part of its time.
"""
