"""`python -m tests.fuzz --seed N` replays one flight; `--seeds A:B` runs a campaign, on
this machine's cores or (`--scheduler tcp://host:8786`) on a Dask cluster."""

from __future__ import annotations

import argparse
import functools
import sys
import time
from collections.abc import Iterable, Iterator

from tests.fuzz.cases import DEFAULT_MAX_UAVS
from tests.fuzz.runner import Report, fly_seed, fly_seed_quietly


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.fuzz", description=__doc__)
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--seed", type=int, help="replay one flight and say what it saw")
    which.add_argument("--seeds", help="a campaign: A:B flies seeds A to B-1")
    parser.add_argument("--max-uavs", type=int, default=DEFAULT_MAX_UAVS)
    parser.add_argument(
        "--link-drops", action="store_true", help="one vehicle's link silent for a while"
    )
    parser.add_argument("--trace", action="store_true", help="print every event of the flight")
    parser.add_argument("--workers", type=int, default=1, help="local processes (campaign)")
    parser.add_argument("--scheduler", help="a Dask scheduler's address (campaign)")
    args = parser.parse_args(argv)
    if args.seed is not None:
        report = fly_seed(args.seed, args.max_uavs, args.link_drops)
        if args.trace:
            print(report.trace())
        print(report.summary())
        return 1 if report.violations else 0
    first, last = (int(x) for x in args.seeds.split(":"))
    started = time.perf_counter()
    seeds = range(first, last)
    failed = 0
    for report in _campaign(seeds, args.max_uavs, args.link_drops, args.workers, args.scheduler):
        if report.violations:
            failed += 1
            print(report.summary(), flush=True)
    seconds = time.perf_counter() - started
    print(f"{len(seeds)} flights, {failed} with violations, {seconds:.0f} s")
    return 1 if failed else 0


def _campaign(
    seeds: Iterable[int], max_uavs: int, link_drops: bool, workers: int, scheduler: str | None
) -> Iterator[Report]:
    """Each seed's report as it comes (in any order off this process)."""
    fly = functools.partial(fly_seed_quietly, max_uavs=max_uavs, link_drops=link_drops)
    if scheduler is not None:
        from dask.distributed import Client, as_completed

        with Client(scheduler) as client:
            futures = [client.submit(fly, s, pure=False) for s in seeds]
            for future in as_completed(futures):
                yield future.result()
        return
    if workers > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(workers) as pool:
            yield from pool.map(fly, seeds)
        return
    for seed in seeds:
        yield fly(seed)


if __name__ == "__main__":
    sys.exit(main())
