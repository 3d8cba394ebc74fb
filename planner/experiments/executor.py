"""Run independent tasks on all local cores or on a Dask cluster, with a progress bar.

Each task carries its own seed, so the results do not depend on which worker runs
it or in which order tasks finish; they come back in task order.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import TypeVar

from tqdm import tqdm

Task = TypeVar("Task")
Result = TypeVar("Result")


def run_all(
    fn: Callable[[Task], Result],
    tasks: Sequence[Task],
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    desc: str = "runs",
) -> list[Result]:
    """`[fn(t) for t in tasks]`, in parallel: on the Dask scheduler at `scheduler` if given,
    else on `workers` local processes (default: one per core; 1 runs in this process)."""
    bar = tqdm(total=len(tasks), desc=desc, unit="run", dynamic_ncols=True)
    try:
        if scheduler is not None:
            return _on_dask(fn, tasks, scheduler, bar)
        workers = workers or os.cpu_count() or 1
        if workers == 1:
            results = []
            for task in tasks:
                results.append(fn(task))
                bar.update()
            return results
        return _on_processes(fn, tasks, workers, bar)
    finally:
        bar.close()


def _on_processes(
    fn: Callable[[Task], Result], tasks: Sequence[Task], workers: int, bar: tqdm
) -> list[Result]:
    results: list[Result | None] = [None] * len(tasks)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        pending = {pool.submit(fn, task): i for i, task in enumerate(tasks)}
        for future in as_completed(pending):
            results[pending[future]] = future.result()
            bar.update()
    return results  # type: ignore[return-value]


def _on_dask(
    fn: Callable[[Task], Result], tasks: Sequence[Task], address: str, bar: tqdm
) -> list[Result]:
    from distributed import Client
    from distributed import as_completed as dask_completed

    results: list[Result | None] = [None] * len(tasks)
    with Client(address) as client:
        futures = client.map(fn, list(tasks), pure=False)
        index = {future.key: i for i, future in enumerate(futures)}
        for future in dask_completed(futures):
            results[index[future.key]] = future.result()
            bar.update()
    return results  # type: ignore[return-value]
