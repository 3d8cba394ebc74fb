"""Table III: per case, the paper's Dist(t0), #UAVs, deviation and J beside ours."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from planner.cases import PAPER_POPULATIONS, PAPER_TABLE_III, load_case
from planner.experiments.case_runs import CaseRecord

TIE = 1e-9  # mean J closer than this counts as a tie


@dataclass(frozen=True)
class Cell:
    """One case, algorithm and population over all seeds."""

    runs: int
    feasible: int
    mean_J: float
    std_J: float
    mean_deviation: float
    mean_length: float  # total over the UAVs
    mean_seconds: float
    start_distance: float


Key = tuple[str, str, int]
"""(case, algorithm, population)"""


@dataclass(frozen=True)
class CaseTable:
    cases: tuple[str, ...]
    algorithms: tuple[str, ...]
    populations: tuple[int, ...]
    cells: dict[Key, Cell]

    def mean_J(self, case: str, algorithm: str) -> float:
        """Mean J over every population (each weighted by its seeds)."""
        cells = [self.cells[case, algorithm, p] for p in self.populations]
        return sum(c.mean_J * c.runs for c in cells) / sum(c.runs for c in cells)

    def mean_deviation(self, case: str, algorithm: str) -> float:
        cells = [self.cells[case, algorithm, p] for p in self.populations]
        return sum(c.mean_deviation * c.runs for c in cells) / sum(c.runs for c in cells)

    def best(self, case: str) -> list[str]:
        """The algorithms (several on a tie) with the lowest mean J on `case`."""
        means = {a: self.mean_J(case, a) for a in self.algorithms}
        low = min(means.values())
        return [a for a, j in means.items() if j - low <= TIE]

    def mean_seconds(self, algorithm: str, population: int | None = None) -> float:
        pops = self.populations if population is None else (population,)
        cells = [self.cells[c, algorithm, p] for c in self.cases for p in pops]
        return sum(c.mean_seconds * c.runs for c in cells) / sum(c.runs for c in cells)

    def overall_J(self, algorithm: str) -> float:
        """Mean J over all cases and populations, each case weighted equally."""
        return float(np.mean([self.mean_J(c, algorithm) for c in self.cases]))


def build_case_table(records: Iterable[CaseRecord]) -> CaseTable:
    groups: dict[Key, list[CaseRecord]] = {}
    for r in records:
        groups.setdefault((r.spec.case, r.spec.algorithm, r.spec.population), []).append(r)
    cells = {key: _cell(group) for key, group in groups.items()}
    return CaseTable(
        cases=tuple(dict.fromkeys(c for c, _, _ in cells)),
        algorithms=tuple(dict.fromkeys(a for _, a, _ in cells)),
        populations=tuple(dict.fromkeys(p for _, _, p in cells)),
        cells=cells,
    )


def _cell(records: Sequence[CaseRecord]) -> Cell:
    js = np.array([r.J for r in records])
    return Cell(
        runs=len(records),
        feasible=sum(r.feasible for r in records),
        mean_J=float(js.mean()),
        std_J=float(js.std()),
        mean_deviation=float(np.mean([r.mean_deviation for r in records])),
        mean_length=float(np.mean([r.total_length for r in records])),
        mean_seconds=float(np.mean([r.seconds for r in records])),
        start_distance=float(np.mean([r.start_distance for r in records])),
    )


def case_label(case: str) -> str:
    """'case-4' -> 'IV', as the paper numbers them."""
    return ("I", "II", "III", "IV", "V", "VI")[int(case.split("-")[1]) - 1]


def render_table_iii(table: CaseTable, algorithm: str = "mvo") -> str:
    """Markdown: every paper value of Table III, 'paper / ours', ours from `algorithm`."""
    head = "| case | Dist(t0) | #UAVs | deviation | " + " | ".join(
        f"J, N = {p}" for p in PAPER_POPULATIONS
    )
    lines = [head + " |", "|---" * (4 + len(PAPER_POPULATIONS)) + "|"]
    for case in table.cases:
        paper = PAPER_TABLE_III[case]
        cells = [table.cells[case, algorithm, p] for p in table.populations]
        ours_j = {p: table.cells[case, algorithm, p].mean_J for p in table.populations}
        pairs = zip(PAPER_POPULATIONS, paper["J"], strict=True)
        js = (f"{j:.4f} / {_or_dash(ours_j.get(p))}" for p, j in pairs)
        lines.append(
            f"| {case_label(case)} | {paper['dist']:g} / {cells[0].start_distance:.2f} "
            f"| {paper['uavs']} / {_count(case)} "
            f"| {paper['deviation']:g} / {table.mean_deviation(case, algorithm):.2f} | "
            + " | ".join(js)
            + " |"
        )
    return "\n".join(lines)


def _or_dash(value: float | None) -> str:
    return "-" if value is None else f"{value:.4f}"


def _count(case: str) -> str:
    """#UAV of eq. (10) as the planner counts it: UAVs plus non-UAV objects."""
    scenario = load_case(case)
    uavs, objects = len(scenario.uavs), len(scenario.object_cells())
    return f"{uavs + objects} ({uavs} + {objects})" if objects else str(uavs)


def render_all_algorithms(table: CaseTable) -> str:
    """Markdown: mean J ± std per case and population for every algorithm, best in bold."""
    head = "| case | N | " + " | ".join(a.upper() for a in table.algorithms) + " |"
    lines = [head, "|---" * (len(table.algorithms) + 2) + "|"]
    for case in table.cases:
        for p in table.populations:
            cells = {a: table.cells[case, a, p] for a in table.algorithms}
            low = min(c.mean_J for c in cells.values())
            row = [_j_cell(c, c.mean_J - low <= TIE) for c in cells.values()]
            lines.append(f"| {case_label(case)} | {p} | " + " | ".join(row) + " |")
    return "\n".join(lines)


def _j_cell(cell: Cell, best: bool) -> str:
    text = f"{cell.mean_J:.4f} ± {cell.std_J:.4f}"
    if cell.feasible < cell.runs:
        text += f" ({cell.feasible}/{cell.runs} feasible)"
    return f"**{text}**" if best else text


def render_times(table: CaseTable) -> str:
    """Markdown: mean seconds per plan, per algorithm and population, over all cases."""
    head = "| algorithm | " + " | ".join(f"N = {p}" for p in table.populations) + " | all |"
    lines = [head, "|---" * (len(table.populations) + 2) + "|"]
    for a in table.algorithms:
        times = [table.mean_seconds(a, p) for p in table.populations]
        lines.append(
            f"| {a.upper()} | "
            + " | ".join(f"{t:.3f}" for t in times)
            + f" | {table.mean_seconds(a):.3f} |"
        )
    return "\n".join(lines)
