"""Our six optimizers against mealpy 3.0.3 and EvoloPy 4.0.6, side by side in one process.

Every (function, algorithm, seed) runs ours, then mealpy's, then EvoloPy's version of the
algorithm, one after another (no parallelism: this is a timing benchmark). Each run's wall
seconds, final best cost and number of objective evaluations go to a CSV; the medians, the
speed-ups and a Mann-Whitney test of ours against EvoloPy go to a markdown report.
"""

from __future__ import annotations

import contextlib
import csv
import importlib
import os
import platform
import random
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import astuple, dataclass, fields
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from planner.benchmarks import BENCHMARKS, BenchmarkFunction
from planner.experiments.machine import cpu_model
from planner.optimizers import ALGORITHMS, GWO, Algorithm, optimize

LIBRARIES = ("ours", "mealpy", "evolopy")
MEALPY_CLASSES = {
    "mvo": ("mealpy.physics_based.MVO", "OriginalMVO"),
    "alo": ("mealpy.swarm_based.ALO", "OriginalALO"),
    "da": ("mealpy.swarm_based.DO", "OriginalDO"),
    "gwo": ("mealpy.swarm_based.GWO", "OriginalGWO"),
    "mfo": ("mealpy.swarm_based.MFO", "OriginalMFO"),
    "woa": ("mealpy.swarm_based.WOA", "OriginalWOA"),
}
EVOLOPY_FUNCTIONS = {"mvo": "MVO", "gwo": "GWO", "mfo": "MFO", "woa": "WOA"}  # no ALO, no DA
# Variants of ours that adopt one of EvoloPy's own rules, to show where a difference comes from.
VARIANTS: dict[str, tuple[str, Algorithm]] = {
    "gwo": ("GWO with EvoloPy's leader demotion", GWO(demote_leaders=True)),
}
VARIANT = "ours-variant"
SPEED_TARGET = 10.0  # ours must be at least this many times faster than the faster library
ALPHA = 0.05  # Mann-Whitney significance level
INSTALL_HINT = "pip install -e '.[bench]'"


class BenchDependencyError(ImportError):
    """mealpy, EvoloPy or scipy (the 'bench' extra) is not installed."""


@dataclass(frozen=True)
class ComparisonConfig:
    """What to run: every algorithm on every function, `seeds` runs per library."""

    seeds: int = 10
    iterations: int = 1000
    population: int = 30
    dim: int = 30
    algorithms: tuple[str, ...] = tuple(ALGORITHMS)
    functions: tuple[str, ...] = ("rastrigin", "sphere")


@dataclass(frozen=True)
class Run:
    """One run of one library's algorithm: a row of the CSV."""

    function: str
    algorithm: str
    library: str
    seed: int
    seconds: float
    best_cost: float
    nfe: int


@dataclass(frozen=True)
class _Libraries:
    mealpy: ModuleType
    stats: ModuleType  # scipy.stats


class _ScalarObjective:
    """Our vectorised function seen one vector at a time, as both libraries call it.

    Counts its calls, which is the NFE of a library run.
    """

    def __init__(self, bench: BenchmarkFunction) -> None:
        self.__name__ = bench.name  # EvoloPy prints objf.__name__
        self._function = bench.function
        self.calls = 0

    def __call__(self, x: Any) -> float:
        self.calls += 1
        return float(self._function(np.asarray(x)[None, :])[0])


def run_comparison(
    config: ComparisonConfig, out_path: Path = Path("bench/results/optimizers.md")
) -> Path:
    """Run the whole comparison; write the markdown report and the raw CSV beside it."""
    _check_config(config)
    libs = _import_libraries()
    code = _code_version()  # the optimizers are imported by now: what the runs will measure
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    runs = _run_all(config, libs, out_path.with_suffix(".csv"))
    out_path.write_text(_report(config, runs, libs, out_path, code), encoding="utf-8")
    return out_path


def _check_config(config: ComparisonConfig) -> None:
    unknown = [a for a in config.algorithms if a not in ALGORITHMS]
    unknown += [f for f in config.functions if f not in BENCHMARKS]
    if unknown:
        raise ValueError(f"unknown algorithm or function: {', '.join(unknown)}")
    if min(config.seeds, config.iterations, config.population, config.dim) < 1:
        raise ValueError(f"seeds, iterations, population and dim must be positive: {config}")


def _import_libraries() -> _Libraries:
    """Import the 'bench' extra lazily; a missing one gets an install hint."""
    try:
        mealpy = importlib.import_module("mealpy")
        importlib.import_module("EvoloPy.optimizers")
        stats = importlib.import_module("scipy.stats")
    except ImportError as exc:
        raise BenchDependencyError(
            f"the optimizer benchmark needs mealpy, EvoloPy and scipy ({exc}); "
            f"install them with: {INSTALL_HINT}"
        ) from exc
    return _Libraries(mealpy=mealpy, stats=stats)


def _libraries_for(algorithm: str) -> tuple[str, ...]:
    libraries = [lib for lib in LIBRARIES if lib != "evolopy" or algorithm in EVOLOPY_FUNCTIONS]
    return (*libraries, VARIANT) if algorithm in VARIANTS else tuple(libraries)


def _plan(config: ComparisonConfig) -> list[tuple[str, str, int, str]]:
    """(function, algorithm, seed, library), the three libraries interleaved per seed."""
    return [
        (function, algorithm, seed, library)
        for function in config.functions
        for algorithm in config.algorithms
        for seed in range(config.seeds)
        for library in _libraries_for(algorithm)
    ]


def _run_all(config: ComparisonConfig, libs: _Libraries, csv_path: Path) -> list[Run]:
    """Every planned run, sequentially; each CSV row is written as soon as its run ends."""
    runs: list[Run] = []
    with csv_path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow([f.name for f in fields(Run)])
        bar = tqdm(_plan(config), desc="optimizers", unit="run")
        for function, algorithm, seed, library in bar:
            bar.set_postfix_str(f"{function} {algorithm} {library} seed={seed}")
            run = _run_one(libs, BENCHMARKS[function], algorithm, library, config, seed)
            runs.append(run)
            writer.writerow(astuple(run))
            handle.flush()
    return runs


def _run_one(
    libs: _Libraries,
    bench: BenchmarkFunction,
    algorithm: str,
    library: str,
    config: ComparisonConfig,
    seed: int,
) -> Run:
    runner: Callable[..., tuple[float, float, int]] = {
        "ours": _run_ours,
        "mealpy": _run_mealpy,
        "evolopy": _run_evolopy,
        VARIANT: _run_ours,
    }[library]
    chosen = VARIANTS[algorithm][1] if library == VARIANT else algorithm
    seconds, best, nfe = runner(libs, bench, chosen, config, seed)
    return Run(bench.name, algorithm, library, seed, seconds, best, nfe)


def _run_ours(
    libs: _Libraries,
    bench: BenchmarkFunction,
    algorithm: str | Algorithm,
    config: ComparisonConfig,
    seed: int,
) -> tuple[float, float, int]:
    lower, upper = bench.bounds(config.dim)
    rng = np.random.default_rng(seed)
    start = time.perf_counter()
    result = optimize(
        algorithm,
        bench.function,
        lower,
        upper,
        population=config.population,
        iterations=config.iterations,
        rng=rng,
    )
    return time.perf_counter() - start, result.best_cost, result.nfe


def _run_mealpy(
    libs: _Libraries, bench: BenchmarkFunction, algorithm: str, config: ComparisonConfig, seed: int
) -> tuple[float, float, int]:
    module, name = MEALPY_CLASSES[algorithm]
    model = getattr(importlib.import_module(module), name)(
        epoch=config.iterations, pop_size=config.population
    )
    objective = _ScalarObjective(bench)
    lower, upper = bench.bounds(config.dim)
    problem = {
        "obj_func": objective,
        "bounds": libs.mealpy.FloatVar(lb=lower, ub=upper),
        "minmax": "min",
        "log_to": None,
    }
    start = time.perf_counter()
    best = model.solve(problem, seed=seed)
    return time.perf_counter() - start, float(best.target.fitness), objective.calls


def _run_evolopy(
    libs: _Libraries, bench: BenchmarkFunction, algorithm: str, config: ComparisonConfig, seed: int
) -> tuple[float, float, int]:
    name = EVOLOPY_FUNCTIONS[algorithm]
    function = getattr(importlib.import_module(f"EvoloPy.optimizers.{name}"), name)
    objective = _ScalarObjective(bench)
    lb, ub = (bound.tolist() for bound in bench.bounds(config.dim))
    args = (objective, lb, ub, config.dim, config.population, config.iterations)
    random.seed(seed)  # EvoloPy draws from both global generators
    np.random.seed(seed)  # noqa: NPY002
    with _silenced_stdout():  # it prints every iteration
        start = time.perf_counter()
        solution = function(*args)
        seconds = time.perf_counter() - start
    # The last convergence entry is the best-so-far (`solution.best` is only set by WOA).
    return seconds, float(solution.convergence[-1]), objective.calls


@contextlib.contextmanager
def _silenced_stdout() -> Iterator[None]:
    with open(os.devnull, "w", encoding="utf-8") as sink, contextlib.redirect_stdout(sink):
        yield


# --- report -------------------------------------------------------------------------------


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


def _p_value(libs: _Libraries, ours: NDArray[np.float64], evo: NDArray[np.float64]) -> float:
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


def _table_row(libs: _Libraries, runs: list[Run], function: str, algorithm: str) -> str:
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


def _variant_rows(
    libs: _Libraries, runs: list[Run], config: ComparisonConfig, function: str
) -> str:
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
    libs: _Libraries, runs: list[Run], config: ComparisonConfig, function: str
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


_MEASURED = ("planner/optimizers", "planner/benchmarks.py")


def _code_version() -> str:
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


def _report(
    config: ComparisonConfig, runs: list[Run], libs: _Libraries, out_path: Path, code: str
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
