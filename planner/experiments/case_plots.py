"""Figs. 3-5 of the case study: convergence, final J over seeds, execution time."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from planner.experiments.case_runs import CaseRecord
from planner.experiments.case_table import CaseTable, case_label

STYLES = ("-", "--", "-.", ":", (0, (5, 1)), (0, (3, 1, 1, 1, 1, 1)))
"""Line styles in turn, so that algorithms with identical curves stay visible."""

CaseGroups = dict[tuple[str, str, int], list[CaseRecord]]
"""Runs keyed by (case, algorithm, population)."""


def group_cases(records: Sequence[CaseRecord]) -> CaseGroups:
    groups: CaseGroups = {}
    for r in records:
        groups.setdefault((r.spec.case, r.spec.algorithm, r.spec.population), []).append(r)
    return groups


def padded_histories(runs: Sequence[CaseRecord]) -> np.ndarray:
    """(runs, longest history): aligned by iteration, a shorter one held at its last value."""
    longest = max(len(r.history) for r in runs)
    return np.stack([np.pad(r.history, (0, longest - len(r.history)), mode="edge") for r in runs])


def plot_convergence(
    groups: CaseGroups, case: str, algorithms: Sequence[str], population: int, out: Path
) -> Path:
    """Fig. 3: plan cost per iteration, median and interquartile band over seeds."""
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    seeds = 0
    for k, algorithm in enumerate(algorithms):
        runs = [r for r in groups.get((case, algorithm, population), []) if r.history]
        if not runs:
            continue
        seeds = len(runs)
        low, median, high = np.percentile(padded_histories(runs), [25, 50, 75], axis=0)
        iterations = np.arange(1, median.size + 1)
        style, width = STYLES[k % len(STYLES)], 2.4 - 1.2 * k / max(len(algorithms) - 1, 1)
        (line,) = ax.plot(iterations, median, label=algorithm.upper(), lw=width, ls=style)
        ax.fill_between(iterations, low, high, color=line.get_color(), alpha=0.2, lw=0)
        final = float(np.median([r.J for r in runs]))
        ax.plot([median.size], [final], marker="o", color=line.get_color(), ls="none")
    ax.set_yscale("symlog", linthresh=1.0)
    ax.set_xlabel("iteration (the plan's optimizer runs one after another)")
    ax.set_ylabel("plan cost (mean over UAVs, penalties included)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, ncol=3)
    ax.set_title(
        f"Case {case_label(case)}: population {population}, {seeds} seeds; dot: median final J",
        fontsize=10,
    )
    return _save(fig, out)


def plot_final_costs(
    groups: CaseGroups,
    cases: Sequence[str],
    algorithms: Sequence[str],
    populations: Sequence[int],
    out: Path,
) -> Path:
    """Fig. 4: box plots of the final J over the seeds (all populations pooled), one panel
    per case; every run is a dot coloured by its population."""
    fig, axes = _panels(len(cases))
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.85, len(populations)))
    for ax, case in zip(axes, cases, strict=False):
        runs = {a: [groups.get((case, a, p), []) for p in populations] for a in algorithms}
        ax.boxplot([[r.J for g in runs[a] for r in g] for a in algorithms], showmeans=True)
        for k, a in enumerate(algorithms, start=1):
            _dots(ax, k, [[r.J for r in g] for g in runs[a]], colours, populations)
        ax.set_xticks(range(1, len(algorithms) + 1), [a.upper() for a in algorithms])
        ax.set_title(f"Case {case_label(case)}", fontsize=10)
        ax.set_ylabel("final J, eq. (10)")
        ax.grid(True, axis="y", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    axes[0].legend(handles[: len(populations)], labels[: len(populations)], fontsize=7)
    fig.suptitle("Final J over the seeds, all populations (triangle: mean; dots: runs)")
    return _save(fig, out)


def _dots(
    ax: Axes,
    x: int,
    js: list[list[float]],
    colours: np.ndarray,
    populations: Sequence[int],
) -> None:
    """The runs of one box, spread sideways by population so that none hides another."""
    offsets = np.linspace(-0.3, 0.3, len(populations))
    for offset, values, colour, p in zip(offsets, js, colours, populations, strict=True):
        ax.plot(np.full(len(values), x + offset), values, ".", color=colour, ms=4, label=f"N = {p}")


def plot_times(table: CaseTable, out: Path) -> Path:
    """Fig. 5: mean execution time per algorithm and population, one panel per case."""
    fig, axes = _panels(len(table.cases))
    width = 0.8 / len(table.algorithms)
    x = np.arange(len(table.populations))
    for ax, case in zip(axes, table.cases, strict=False):
        for k, a in enumerate(table.algorithms):
            times = [table.cells[case, a, p].mean_seconds for p in table.populations]
            ax.bar(x + (k - (len(table.algorithms) - 1) / 2) * width, times, width, label=a.upper())
        ax.set_xticks(x, [str(p) for p in table.populations])
        ax.set_xlabel("population")
        ax.set_ylabel("mean seconds per plan")
        ax.set_title(f"Case {case_label(case)}", fontsize=10)
        ax.grid(True, axis="y", alpha=0.3)
    axes[0].legend(fontsize=7, ncol=2)
    fig.suptitle("Mean execution time of one plan")
    return _save(fig, out)


def _panels(count: int) -> tuple[Figure, list[Axes]]:
    cols = min(count, 3)
    rows = -(-count // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 3.4 * rows), squeeze=False)
    flat = list(axes.flat)
    for ax in flat[count:]:
        ax.set_visible(False)
    return fig, flat[:count]


def _save(fig: Figure, out: Path) -> Path:
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
