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
import random
import time
from collections.abc import Callable, Iterator
from dataclasses import astuple, fields
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from planner.experiments.library_config import (
    EVOLOPY_FUNCTIONS,
    INSTALL_HINT,
    LIBRARIES,
    MEALPY_CLASSES,
    VARIANT,
    VARIANTS,
    BenchDependencyError,
    ComparisonConfig,
    Libraries,
    Run,
)
from planner.experiments.library_report import code_version, report
from planner.optimizers import ALGORITHMS, Algorithm, optimize
from planner.optimizers.benchmarks import BENCHMARKS, BenchmarkFunction

__all__ = ["BenchDependencyError", "ComparisonConfig", "Run", "run_comparison"]


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
    code = code_version()  # the optimizers are imported by now: what the runs will measure
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    runs = _run_all(config, libs, out_path.with_suffix(".csv"))
    out_path.write_text(report(config, runs, libs, out_path, code), encoding="utf-8")
    return out_path


def _check_config(config: ComparisonConfig) -> None:
    unknown = [a for a in config.algorithms if a not in ALGORITHMS]
    unknown += [f for f in config.functions if f not in BENCHMARKS]
    if unknown:
        raise ValueError(f"unknown algorithm or function: {', '.join(unknown)}")
    if min(config.seeds, config.iterations, config.population, config.dim) < 1:
        raise ValueError(f"seeds, iterations, population and dim must be positive: {config}")


def _import_libraries() -> Libraries:
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
    return Libraries(mealpy=mealpy, stats=stats)


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


def _run_all(config: ComparisonConfig, libs: Libraries, csv_path: Path) -> list[Run]:
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
    libs: Libraries,
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
    libs: Libraries,
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
    libs: Libraries, bench: BenchmarkFunction, algorithm: str, config: ComparisonConfig, seed: int
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
    libs: Libraries, bench: BenchmarkFunction, algorithm: str, config: ComparisonConfig, seed: int
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
