"""Fig. 1: convergence curves, median and interquartile band over seeds."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from planner.experiments.benchmark_runs import RunRecord
from planner.optimizers.benchmarks import BENCHMARKS

FLOOR = 1e-16  # log axes cannot show an exact optimum


RunGroups = dict[tuple[str, str, int, int], list[RunRecord]]
"""Runs keyed by (function, algorithm, dimension, population)."""


def group_runs(records: Sequence[RunRecord]) -> RunGroups:
    groups: RunGroups = {}
    for r in records:
        key = (r.spec.function, r.spec.algorithm, r.spec.dim, r.spec.population)
        groups.setdefault(key, []).append(r)
    return groups


def plot_convergence(
    groups: RunGroups,
    function: str,
    dims: Sequence[int],
    populations: Sequence[int],
    algorithms: Sequence[str],
    out: Path,
) -> Path:
    """One panel per (dimension, population): best error so far against evaluations."""
    fig, axes = plt.subplots(
        len(dims),
        len(populations),
        figsize=(4.2 * len(populations), 3.2 * len(dims)),
        squeeze=False,
        sharey=True,
    )
    optimum = BENCHMARKS[function].optimum
    for row, dim in enumerate(dims):
        for col, pop in enumerate(populations):
            ax = axes[row, col]
            seeds = 0
            for algorithm in algorithms:
                runs = groups.get((function, algorithm, dim, pop), [])
                if not runs:
                    continue
                seeds = len(runs)
                errors = np.maximum(np.stack([r.result.history for r in runs]) - optimum, FLOOR)
                low, median, high = np.percentile(errors, [25, 50, 75], axis=0)
                iterations = np.arange(1, median.size + 1)
                (line,) = ax.plot(iterations, median, label=algorithm.upper(), lw=1.2)
                ax.fill_between(iterations, low, high, color=line.get_color(), alpha=0.2, lw=0)
            ax.set_yscale("log")
            ax.set_title(f"d = {dim}, population = {pop}, {seeds} seeds", fontsize=9)
            ax.grid(True, which="major", alpha=0.3)
            if row == len(dims) - 1:
                ax.set_xlabel("iteration")
            if col == 0:
                ax.set_ylabel(f"best f - f* (floor {FLOOR:g})")
    axes[0, 0].legend(fontsize=8, ncol=2)
    fig.suptitle(f"{function.capitalize()}: median and interquartile band over seeds")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
