"""The fleet benchmark's rows and tables (`planner.experiments.fleet_bench` runs it).

One `Row` per plan (ours or a reference's, judged by our exact check), written to a CSV;
per family, a table of every planner's medians; and issue 13's targets, family by family.
"""

from __future__ import annotations

import csv
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

OURS = "MVO qos (ours)"
LACAM = "LaCAM (pymapf), 4-connected"


class Target(Protocol):
    """A family as the summary table reads it."""

    @property
    def name(self) -> str: ...

    @property
    def time_target(self) -> float | None: ...


@dataclass(frozen=True)
class Row:
    family: str
    seed: int
    planner: str
    feasible: bool
    first_safe_s: float | None  # None: no safe plan
    seconds: float
    length_ratio: float | None
    improvement: float | None
    stop_reason: str
    note: str
    marked: bool = False  # what the planner itself said: feasible (ours) or solved (theirs)


def median_text(values: list[float], digits: int = 3) -> str:
    return f"{statistics.median(values):.{digits}f}" if values else "-"


def family_table(rows: list[Row]) -> list[str]:
    lines = [
        "| planner | feasible | median s to first safe plan (max) | median total s | "
        "median length ratio | median gain after first safe |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name in dict.fromkeys(r.planner for r in rows):
        mine = [r for r in rows if r.planner == name]
        ok = [r for r in mine if r.feasible]
        firsts = [r.first_safe_s for r in ok if r.first_safe_s is not None]
        gains = [100 * r.improvement for r in ok if r.improvement is not None]
        worst = f" ({max(firsts):.2f})" if firsts else ""
        lines.append(
            f"| {name} | {len(ok)}/{len(mine)} ({100 * len(ok) / len(mine):.0f} %) | "
            f"{median_text(firsts)}{worst} | {median_text([r.seconds for r in mine])} | "
            f"{median_text([r.length_ratio for r in ok if r.length_ratio is not None])} | "
            f"{median_text(gains, 1) + ' %' if gains else '-'} |"
        )
    return lines


def write_csv(rows: list[Row], path: Path) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(list(Row.__dataclass_fields__))
        for r in rows:
            writer.writerow(list(vars(r).values()))


def summary_table(rows: list[Row], families: Sequence[Target]) -> list[str]:
    """Issue 13's targets, family by family: ours against its time target and LaCAM."""
    lines = [
        "| family | ours feasible | ours s to first safe | ours s to plan | target s | "
        "LaCAM s | 3 x LaCAM + 0.5 s | ours length ratio | LaCAM length ratio | "
        "ours shorter by | PP (pymapf) s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for family in families:
        mine = [r for r in rows if r.family == family.name]
        ours = [r for r in mine if r.planner == OURS]
        lacam = [r for r in mine if r.planner == LACAM]
        pp = [r for r in mine if r.planner.startswith("prioritized (pymapf)")]
        ok = [r for r in ours if r.feasible]
        ratio = [r.length_ratio for r in ok if r.length_ratio is not None]
        lacam_ok = [r for r in lacam if r.feasible]
        lacam_ratio = [r.length_ratio for r in lacam_ok if r.length_ratio is not None]
        bound = "-"
        if lacam_ok:
            bound = f"{3 * statistics.median(r.seconds for r in lacam_ok) + 0.5:.2f}"
        shorter = "-"
        if ratio and lacam_ratio:
            shorter = (
                f"{100 * (1 - statistics.median(ratio) / statistics.median(lacam_ratio)):.0f} %"
            )
        target = f"{family.time_target:g}" if family.time_target is not None else "(extra)"
        lines.append(
            f"| {family.name} | {len(ok)}/{len(ours)} | "
            f"{median_text([r.first_safe_s for r in ok if r.first_safe_s is not None])} | "
            f"{median_text([r.seconds for r in ours])} | {target} | "
            f"{median_text([r.seconds for r in lacam_ok])} ({len(lacam_ok)}/{len(lacam)}) | "
            f"{bound} | {median_text(ratio)} | {median_text(lacam_ratio)} | {shorter} | "
            f"{median_text([r.seconds for r in pp if r.feasible])} "
            f"({sum(r.feasible for r in pp)}/{len(pp)}) |"
        )
    return lines
