"""When each waypoint is reached: the product's timing against the mock's flight.

The product times every flight on its own model of the copters
(`gcs.mission.flight_timing`): it says when each vehicle reaches each NAV item of its
mission (`ItemReached.scheduled_s`) and when the last one is over its goal, what flights
are judged against (at most 1.15 times that, issue 22). This flies one vehicle at a time
through the in-process service, on the ArduCopter-flavoured mock and the virtual clock
(`tests/fuzz/runner.py`: the same flight on every run), nobody else in its way, and
compares: the error at every waypoint before the landing item (reached at touch-down) and
the mission time over the timed one. With `--fleet N` every scenario has N UAVs flown
together (and the gap swap too), so that the timing of the waits the passing order makes
is measured as well. Run, from the repository root:

    .venv/bin/python bench/waypoint_timing.py [--fleet N] [--out FILE.md]

To measure an older tree, run its copy of this file from that tree.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from planner.experiments.machine import describe_machine  # noqa: E402
from tests.fuzz.cases import FuzzCase  # noqa: E402
from tests.fuzz.runner import run  # noqa: E402

FAMILIES = ("crossing", "random")
SEEDS = range(6)
SPEEDS = (5.0, 10.0)
SIZE = 20  # cells of 10 m a side


@dataclass
class Row:
    family: str
    seed: int
    speed: float
    errors: list[float]  # flown minus timed, s, at each waypoint before the landing
    mission_s: float
    timed_s: float


def fly(family: str, seed: int, speed: float, uavs: int = 1) -> Row | None:
    """The flight's row; None if the product refused its speed (a fleet's plan may be)."""
    size = 9 if family == "gap-swap" else SIZE  # the gap swap's own size, as fuzzed
    with tempfile.TemporaryDirectory(prefix="waypoints-") as tmp:
        report = run(FuzzCase(seed, family, size, uavs, speed), Path(tmp) / "data")
    if report.outcome == "refused" and not report.violations:
        return None
    if report.violations or report.mission_s is None or report.timed_s is None:
        raise RuntimeError(report.summary())
    return Row(family, seed, speed, report.waypoint_errors(), report.mission_s, report.timed_s)


def table(rows: list[Row]) -> list[str]:
    lines = [
        "| family | seed | m/s | waypoints | largest error s | mean abs error s | "
        "mission s | timed s | mission / timed |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        worst = max(r.errors, key=abs, default=0.0)
        mean = statistics.fmean(abs(e) for e in r.errors) if r.errors else 0.0
        lines.append(
            f"| {r.family} | {r.seed} | {r.speed:g} | {len(r.errors)} | {worst:+.2f} | "
            f"{mean:.2f} | {r.mission_s:.1f} | {r.timed_s:.1f} | {r.mission_s / r.timed_s:.3f} |"
        )
    errors = [abs(e) for r in rows for e in r.errors]
    ratios = [r.mission_s / r.timed_s for r in rows]
    lines += [
        "",
        f"All {len(rows)} flights, {len(errors)} waypoints: largest error "
        f"{max(errors):.2f} s, mean {statistics.fmean(errors):.2f} s; mission / timed "
        f"{min(ratios):.3f} to {max(ratios):.3f}.",
    ]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write the table (markdown) here too")
    parser.add_argument("--fleet", type=int, default=1, help="UAVs per flight (default 1)")
    args = parser.parse_args()
    started = time.perf_counter()
    families = FAMILIES if args.fleet == 1 else (*FAMILIES, "gap-swap")
    flown = [
        fly(family, seed, speed, args.fleet)
        for family in families
        for seed in SEEDS
        for speed in SPEEDS
    ]
    rows = [row for row in flown if row is not None]
    commit = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
        capture_output=True,
        text=True,
        check=False,
    ).stdout.strip()
    lines = [
        f"Run {datetime.now(UTC):%Y-%m-%d %H:%M} UTC at {commit or '?'} (plus the working "
        f"tree's changes, if any), {args.fleet} UAV(s) per flight, on {describe_machine()}, "
        f"{time.perf_counter() - started:.0f} s.",
        "",
        *table(rows),
        f"Refused (a speed the plan cannot be flown at safely): {len(flown) - len(rows)}.",
    ]
    print("\n".join(lines))
    if args.out:
        args.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
