"""Table II: evaluations each algorithm needs to reach a function's optimum, and R."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from planner.experiments.benchmark_runs import RunRecord

# Table II of the paper: F1..F6 at dimension 30, NFE per algorithm.
PAPER_ALGORITHMS = ("alo", "da", "gwo", "mfo", "woa", "mvo")
PAPER_TABLE_II: dict[str, tuple[int, ...]] = {
    "sphere": (9557760, 12131320, 6731920, 5268560, 4356840, 3306560),
    "rosenbrock": (13605648, 11074686, 8473668, 7398132, 4839702, 3676848),
    "step": (10272350, 4063910, 8164946, 6082508, 4901620, 3560524),
    "rastrigin": (8730070, 7786691, 9891208, 6290994, 3942183, 4117529),
    "ackley": (9463230, 7215985, 8433320, 6708380, 4007360, 3782765),
    "griewank": (9801220, 6467760, 6854640, 6856850, 3932075, 3358843),
}
PAPER_TOTALS = (61430278, 48740352, 48549702, 38605424, 25979782, 21803068)  # as printed
PAPER_R = dict(zip(PAPER_ALGORITHMS, (0.3549, 0.4473, 0.4490, 0.5647, 0.8392, 1.0), strict=True))


@dataclass(frozen=True)
class Cell:
    """One function and algorithm over all seeds."""

    runs: int
    successes: int
    budget: int  # evaluations of a run that never reaches the target
    median_to_target: float | None  # over successful runs only
    successful_total: int  # evaluations of the successful runs, up to the target

    @property
    def charged_total(self) -> int:
        """Total evaluations, a failed run charged its whole budget (so a lower bound)."""
        return self.successful_total + (self.runs - self.successes) * self.budget


@dataclass(frozen=True)
class NfeTable:
    tolerance: float
    functions: tuple[str, ...]
    algorithms: tuple[str, ...]
    cells: dict[tuple[str, str], Cell]

    @property
    def paper_functions(self) -> tuple[str, ...]:
        """The functions of the paper's Table II; totals and R are over these only."""
        return tuple(f for f in self.functions if f in PAPER_TABLE_II)

    def total(self, algorithm: str) -> int:
        return sum(self.cells[f, algorithm].charged_total for f in self.paper_functions)

    def acceleration(self, algorithm: str) -> float:
        """The paper's R: total NFE of MVO over total NFE of `algorithm` (> 1: MVO needs more)."""
        return self.total("mvo") / self.total(algorithm)

    def fewest(self, function: str) -> list[str]:
        """The algorithms (several on a tie) with the smallest charged total on `function`."""
        totals = {a: self.cells[function, a].charged_total for a in self.algorithms}
        low = min(totals.values())
        return [a for a, n in totals.items() if n == low]


def build_table(records: Iterable[RunRecord], tolerance: float) -> NfeTable:
    groups: dict[tuple[str, str], list[RunRecord]] = {}
    for record in records:
        groups.setdefault((record.spec.function, record.spec.algorithm), []).append(record)
    cells = {key: _cell(group, tolerance) for key, group in groups.items()}
    functions = tuple(dict.fromkeys(f for f, _ in cells))
    algorithms = tuple(dict.fromkeys(a for _, a in cells))
    return NfeTable(tolerance, functions, algorithms, cells)


def _cell(records: Sequence[RunRecord], tolerance: float) -> Cell:
    reached = [n for n in (r.nfe_to_reach(tolerance) for r in records) if n is not None]
    return Cell(
        runs=len(records),
        successes=len(reached),
        budget=max(r.result.nfe for r in records),
        median_to_target=float(np.median(reached)) if reached else None,
        successful_total=sum(reached),
    )


def render_ours(table: NfeTable) -> str:
    """Markdown: charged total NFE per cell with successes, the totals and R."""
    head = "| function | " + " | ".join(a.upper() for a in table.algorithms) + " |"
    rule = "|---" * (len(table.algorithms) + 1) + "|"
    lines = [head, rule]
    for f in table.functions:
        cells = (table.cells[f, a] for a in table.algorithms)
        lines.append(
            f"| {f} | "
            + " | ".join(f"{c.charged_total:,} ({c.successes}/{c.runs})" for c in cells)
            + " |"
        )
    totals = " | ".join(f"{table.total(a):,}" for a in table.algorithms)
    lines.append(f"| **total** (paper's six functions) | {totals} |")
    if "mvo" in table.algorithms:
        r = " | ".join(f"{table.acceleration(a):.4f}" for a in table.algorithms)
        lines.append(f"| **R** | {r} |")
    return "\n".join(lines)


def render_medians(table: NfeTable) -> str:
    """Markdown: median NFE to the target over the runs that reached it."""
    head = "| function | " + " | ".join(a.upper() for a in table.algorithms) + " |"
    lines = [head, "|---" * (len(table.algorithms) + 1) + "|"]
    for f in table.functions:
        medians = (table.cells[f, a].median_to_target for a in table.algorithms)
        lines.append(
            f"| {f} | " + " | ".join("never" if m is None else f"{m:,.0f}" for m in medians) + " |"
        )
    return "\n".join(lines)


def render_paper() -> str:
    head = "| function | " + " | ".join(a.upper() for a in PAPER_ALGORITHMS) + " |"
    lines = [head, "|---" * (len(PAPER_ALGORITHMS) + 1) + "|"]
    for f, row in PAPER_TABLE_II.items():
        lines.append(f"| {f} | " + " | ".join(f"{n:,}" for n in row) + " |")
    totals = PAPER_TOTALS
    lines.append("| **total** | " + " | ".join(f"{n:,}" for n in totals) + " |")
    lines.append("| **R** | " + " | ".join(f"{PAPER_R[a]:.4f}" for a in PAPER_ALGORITHMS) + " |")
    return "\n".join(lines)
