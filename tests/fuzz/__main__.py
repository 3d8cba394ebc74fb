"""`python -m tests.fuzz --seed N` replays one flight; `--seeds A:B` runs a campaign."""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from tests.fuzz.cases import FuzzCase
from tests.fuzz.runner import Report, run


def fly_seed(seed: int, max_uavs: int) -> Report:
    with tempfile.TemporaryDirectory(prefix=f"fuzz-{seed}-") as tmp:
        return run(FuzzCase.draw(seed, max_uavs), Path(tmp) / "data")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.fuzz", description=__doc__)
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--seed", type=int, help="replay one flight and say what it saw")
    which.add_argument("--seeds", help="a campaign: A:B runs seeds A to B-1")
    parser.add_argument("--max-uavs", type=int, default=6)
    parser.add_argument("--trace", action="store_true", help="print every event of the flight")
    args = parser.parse_args(argv)
    if args.seed is not None:
        report = fly_seed(args.seed, args.max_uavs)
        if args.trace:
            print(report.trace())
        print(report.summary())
        return 1 if report.violations else 0
    first, last = (int(x) for x in args.seeds.split(":"))
    failed = 0
    started = time.perf_counter()
    for seed in range(first, last):
        report = fly_seed(seed, args.max_uavs)
        if report.violations:
            failed += 1
            print(report.summary(), flush=True)
    print(
        f"{last - first} flights, {failed} with violations, {time.perf_counter() - started:.0f} s"
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
