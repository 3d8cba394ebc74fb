"""Planning off the event loop: a pool of worker processes, progress and cancellation.

Planning is CPU-bound numpy work that holds the GIL for long stretches, so it runs
in processes, never on the service's event loop. Workers report progress through a
manager queue (throttled, so a fast plan does not flood it) and look at a shared
set of cancelled job ids between optimizer iterations.

`ThreadPlanner` (`plan_workers = 0`) plans in a thread of the service's own process
instead: no processes to start, and a simulated flight on a virtual clock stands still
while it plans (the tests' in-process service). It shares the GIL with the event loop,
so a long plan slows the vehicle links: it is not for a service flying real vehicles.

`gcs.service.dask_planner.DaskPlanner` (`dask_scheduler` set) plans on a Dask cluster
with the same interface.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import multiprocessing
import os
import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import asdict, dataclass
from multiprocessing.managers import SyncManager
from typing import Any, Protocol, TypedDict

from gcs.mission.flight_choice import WIDER_M, Trial, candidate, soonest_by_default
from gcs.service.parent_watch import exit_with_parent
from planner.model.scenario import Scenario, load_scenario
from planner.pipeline import PlannerSettings, PlanProgress, plan

PROGRESS_INTERVAL_S = 0.2


class PlanCancelled(Exception):
    """Raised inside a worker when its job was cancelled; `iterations_after`: how many
    optimizer iterations ran after the cancellation reached the worker, where counted."""

    def __init__(self, job_id: str, iterations_after: int | None = None) -> None:
        super().__init__(job_id, iterations_after)  # both in args: it pickles back whole
        self.job_id = job_id
        self.iterations_after = iterations_after


@dataclass(frozen=True)
class JobProgress:
    job_id: str
    percent: float  # of the time budget; without one, runs so far against one per UAV
    best_cost: float  # of the cheapest safe plan so far, else of the current search
    run: int
    uav: str
    first_safe_s: float | None = None  # when the first safe plan was found


ProgressSink = Callable[[JobProgress], None]


@dataclass(frozen=True)
class SoonestOf:
    """Plan `count` candidates (`gcs.mission.flight_choice`: the settings' seed and the next
    ones, `clearance_m` and wider) of `flown`, the scenario as flown, and keep the plan the
    vehicles fly soonest at `speed_m_s` (`soonest_by_default`)."""

    count: int
    speed_m_s: float
    flown: dict[str, Any]
    clearance_m: float


class PlanResult(TypedDict):
    """What a planning worker sends back: the plan's JSON and, when several candidates
    were planned (`SoonestOf`), what each came to (`candidates_json`), else None."""

    plan: dict[str, Any]
    candidates: list[dict[str, Any]] | None


class PlanRunner(Protocol):
    """Where plans are computed: worker processes (`PlanningPool`), a thread, or a Dask
    cluster (`DaskPlanner`). Started and shut down on the service's event loop."""

    async def start(self) -> None: ...

    def submit(
        self,
        job_id: str,
        scenario: dict[str, Any],
        settings: PlannerSettings,
        soonest_of: SoonestOf | None = None,
    ) -> asyncio.Future[PlanResult]: ...

    def cancel(self, job_id: str) -> None: ...

    def forget(self, job_id: str) -> None: ...

    async def shutdown(self) -> None: ...


class PlanningPool:
    """A fixed pool of planning processes shared by every request."""

    def __init__(self, workers: int, on_progress: ProgressSink) -> None:
        context = multiprocessing.get_context("spawn")  # no fork of a threaded server
        owner = (os.getpid(),)
        self._manager = SyncManager(ctx=context)
        self._manager.start(exit_with_parent, owner)
        self._progress = self._manager.Queue()
        self._cancelled = self._manager.dict()
        self._executor = ProcessPoolExecutor(
            max_workers=workers, mp_context=context, initializer=exit_with_parent, initargs=owner
        )
        self._on_progress = on_progress
        self._stop = threading.Event()
        self._reader = threading.Thread(target=self._read_progress, daemon=True)
        self._loop: asyncio.AbstractEventLoop | None = None

    async def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._reader.start()

    def submit(
        self,
        job_id: str,
        scenario: dict[str, Any],
        settings: PlannerSettings,
        soonest_of: SoonestOf | None = None,
    ) -> asyncio.Future[PlanResult]:
        """The worker's result when it is done; PlanCancelled if cancelled first."""
        future = self._executor.submit(
            run_plan, job_id, scenario, asdict(settings), self._progress, self._cancelled,
            soonest_of=soonest_of,
        )  # fmt: skip
        return asyncio.wrap_future(future)

    def cancel(self, job_id: str) -> None:
        self._cancelled[job_id] = True

    def forget(self, job_id: str) -> None:
        self._cancelled.pop(job_id, None)

    async def shutdown(self) -> None:
        self._stop.set()
        self._executor.shutdown(wait=False, cancel_futures=True)
        if self._reader.is_alive():
            self._reader.join(timeout=2)
        with contextlib.suppress(Exception):
            self._manager.shutdown()

    def _read_progress(self) -> None:
        while not self._stop.is_set():
            try:
                item = self._progress.get(timeout=0.2)
            except queue.Empty:
                continue
            except (EOFError, OSError, BrokenPipeError):
                return  # the manager is gone: the service is stopping
            if self._loop is not None and not self._loop.is_closed():
                self._loop.call_soon_threadsafe(self._on_progress, JobProgress(*item))


class ThreadPlanner:
    """The same interface as `PlanningPool`, planning in one thread of this process."""

    def __init__(self, on_progress: ProgressSink) -> None:
        self._on_progress = on_progress
        self._cancelled: dict[str, bool] = {}
        self._threads = ThreadPoolExecutor(1, thread_name_prefix="planning")
        self._loop: asyncio.AbstractEventLoop | None = None

    async def start(self) -> None:
        self._loop = asyncio.get_running_loop()

    def submit(
        self,
        job_id: str,
        scenario: dict[str, Any],
        settings: PlannerSettings,
        soonest_of: SoonestOf | None = None,
    ) -> asyncio.Future[PlanResult]:
        assert self._loop is not None, "start() first"
        self._cancelled.setdefault(job_id, False)  # so that shutdown() can cancel it
        work = functools.partial(
            run_plan, job_id, scenario, asdict(settings), self, self._cancelled,
            soonest_of=soonest_of,
        )  # fmt: skip
        return self._loop.run_in_executor(self._threads, work)

    def put(self, item: tuple[Any, ...]) -> None:
        """A progress report from the planning thread (the worker's queue interface)."""
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._on_progress, JobProgress(*item))

    def cancel(self, job_id: str) -> None:
        self._cancelled[job_id] = True

    def forget(self, job_id: str) -> None:
        self._cancelled.pop(job_id, None)

    async def shutdown(self) -> None:
        self._cancelled.update(dict.fromkeys(self._cancelled, True))
        self._threads.shutdown(wait=False, cancel_futures=True)


def planner_for(workers: int, on_progress: ProgressSink) -> PlanRunner:
    """Worker processes, or (0 workers) a thread of this process."""
    return PlanningPool(workers, on_progress) if workers > 0 else ThreadPlanner(on_progress)


def run_plan(
    job_id: str,
    scenario: dict[str, Any],
    settings: dict[str, Any],
    progress: Any,
    cancelled: Any,
    *,
    cancel_each_iteration: bool = False,
    soonest_of: SoonestOf | None = None,
) -> PlanResult:
    """The worker: plan one scenario (or, `soonest_of`, its candidates, keeping the plan
    flown soonest), reporting progress and honouring cancellation.
    `cancelled.get(job_id)` is asked with every report, or with every optimizer iteration
    when it is cheap (`cancel_each_iteration`: a local flag, as on a Dask worker)."""
    if soonest_of is None:
        scenarios = [load_scenario(scenario)]
    else:  # (`scenario` is then the first candidate's; each is made from `flown` here)
        flown = Scenario(**soonest_of.flown)
        scenarios = [candidate(flown, soonest_of.clearance_m, k) for k in range(soonest_of.count)]
    expected_runs = len(scenarios[0].uavs)
    last = 0.0
    planned = 0  # candidates done

    def on_progress(p: PlanProgress) -> None:
        nonlocal last
        if cancel_each_iteration and cancelled.get(job_id):
            raise PlanCancelled(job_id)
        at = time.monotonic()
        if at - last < PROGRESS_INTERVAL_S and p.iteration < p.iterations:
            return
        last = at
        if cancelled.get(job_id):
            raise PlanCancelled(job_id)
        if p.budget_percent is not None:
            percent = p.budget_percent
        else:
            percent = 100 * (p.run - 1 + p.iteration / p.iterations) / max(expected_runs, p.run)
        percent = (100 * planned + min(100.0, percent)) / len(scenarios)
        cost = p.best_cost if p.best_cost is not None else p.plan_cost
        progress.put((job_id, round(min(99.0, percent), 1), cost, p.run, p.uav, p.first_safe_s))

    plans = []
    for planned, each in enumerate(scenarios):
        if cancelled.get(job_id):
            raise PlanCancelled(job_id)
        seeded = PlannerSettings(**settings).candidate(planned, len(scenarios))
        plans.append(plan(each, seeded, progress=on_progress))
    if soonest_of is None:
        return {"plan": plans[0].model_dump(mode="json"), "candidates": None}
    flown = Scenario(**soonest_of.flown)
    chosen, trials = soonest_by_default(plans, flown, soonest_of.speed_m_s)
    return {
        "plan": chosen.model_dump(mode="json"),
        "candidates": candidates_json(trials, chosen.seed, soonest_of.clearance_m),
    }


def candidates_json(
    trials: list[Trial], kept_seed: int, clearance_m: float
) -> list[dict[str, Any]]:
    """Each candidate in the order planned (the k-th keeps `clearance_m` and k steps of
    `WIDER_M`), with its timed flight (to the hundredth, as `/plans/{id}/timing` gives
    it) or why it cannot be flown, and which was kept."""
    return [
        {
            "seed": trial.seed,
            "clearance_m": round(clearance_m + k * WIDER_M, 6),
            "duration_s": None if trial.duration_s is None else round(trial.duration_s, 2),
            "refusal": trial.refusal,
            "same_as": trial.same_as,
            "kept": trial.seed == kept_seed,
        }
        for k, trial in enumerate(trials)
    ]
