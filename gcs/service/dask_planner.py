"""Planning on a Dask cluster (`MVO_GCS_DASK_SCHEDULER=tcp://host:8786`).

The same interface as the local pool (`planning_pool.PlanRunner`), so jobs, their live
progress, cancellation and storage work as they do there. Dask is imported only when
this planner is used.

- The client is Dask's asynchronous one, made inside the service's running event loop
  and closed on its shutdown: nothing here blocks the loop, and the client's callbacks
  (progress, a worker gone) run on it.
- A job is one task, `plan_on_worker`, submitted with `pure=False` under the key
  `mvo-gcs-plan-<job id>`. Its result, the plan's JSON, is the future's result.
- Progress: the task logs each report (throttled as in the local pool) as a Dask event
  under a topic of this service's own; the client subscribes to it.
- Cancellation: a distributed `Event` per job. On the worker a thread waits on it and
  sets a local flag that the planner looks at every optimizer iteration, so a job stops
  within one iteration of the cancellation reaching its worker. A job not started yet is
  also taken off the scheduler.
- A worker lost mid-job (killed, crashed, or retired) ends the job `failed`
  (`WorkerLost`), and it is not re-run: the scheduler's `remove-worker` event names the
  tasks that were on it, and the planner cancels them (Dask would otherwise run them
  again elsewhere, or, with no worker left, leave them waiting for ever). Resubmit the
  plan request to run it again. A lost scheduler fails the jobs it held.
- Jobs wait for a free worker thread: a cluster without workers keeps them `queued`.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import uuid
from dataclasses import asdict, dataclass, field
from typing import Any

from gcs.service.planning_pool import (
    JobProgress,
    PlanCancelled,
    PlanResult,
    ProgressSink,
    SoonestOf,
    run_plan,
)
from planner.pipeline import PlannerSettings

log = logging.getLogger("mvo_gcs.planning")

CONNECT_TIMEOUT_S = 10.0
KEY_PREFIX = "mvo-gcs-plan-"
CANCEL_PREFIX = "mvo-gcs-cancel-"
WATCH_S = 1.0  # how long one wait of the worker's watcher lasts before it looks again


class DaskUnreachable(RuntimeError):
    """No Dask scheduler answered at the configured address."""


class WorkerLost(RuntimeError):
    """The Dask worker a job was on left the cluster; the job is not re-run."""


@dataclass
class _Job:
    job_id: str
    future: Any  # distributed.Future
    lost: asyncio.Future[str]  # the address of the worker that was lost with it
    started: bool = False
    control: list[asyncio.Task[Any]] = field(default_factory=list)  # set/clear of its Event


class DaskPlanner:
    """Plans on the Dask scheduler at `address`."""

    def __init__(
        self, address: str, on_progress: ProgressSink, connect_timeout_s: float = CONNECT_TIMEOUT_S
    ) -> None:
        self.address = address
        self._on_progress = on_progress
        self._timeout = connect_timeout_s
        self._topic = f"mvo-gcs-progress-{uuid.uuid4().hex}"  # this service's reports only
        self._client: Any = None
        self._jobs: dict[str, _Job] = {}  # by job id
        self._cancel_requested: set[str] = set()
        self._clearing: set[asyncio.Task[None]] = set()

    async def start(self) -> None:
        from distributed import Client

        try:
            self._client = await Client(
                self.address, asynchronous=True, set_as_default=False, timeout=self._timeout
            )
        except (OSError, TimeoutError) as exc:
            raise DaskUnreachable(
                f"no Dask scheduler answered at {self.address} within {self._timeout:g} s "
                f"(MVO_GCS_DASK_SCHEDULER): {exc}"
            ) from exc
        self._client.subscribe_topic(self._topic, self._on_report)
        self._client.subscribe_topic("all", self._on_cluster_event)
        log.info("planning on the Dask cluster at %s", self.address)

    def submit(
        self,
        job_id: str,
        scenario: dict[str, Any],
        settings: PlannerSettings,
        soonest_of: SoonestOf | None = None,
    ) -> asyncio.Future[PlanResult]:
        """The worker's result when done; PlanCancelled if cancelled first; WorkerLost if its
        worker left the cluster meanwhile."""
        assert self._client is not None, "start() first"
        future = self._client.submit(
            plan_on_worker,
            job_id,
            scenario,
            asdict(settings),
            self._topic,
            CANCEL_PREFIX + job_id,
            soonest_of,
            key=KEY_PREFIX + job_id,
            pure=False,
            retries=0,
        )
        lost: asyncio.Future[str] = asyncio.get_running_loop().create_future()
        self._jobs[job_id] = _Job(job_id, future, lost)
        return asyncio.ensure_future(self._result(self._jobs[job_id]))

    async def _result(self, job: _Job) -> PlanResult:
        from distributed.client import FutureCancelledError

        result = asyncio.ensure_future(job.future.result())
        try:
            await asyncio.wait({result, job.lost}, return_when=asyncio.FIRST_COMPLETED)
        except asyncio.CancelledError:  # the service is stopping: stop the worker too
            result.cancel()
            await self._abandon(job)
            raise
        if job.lost.done() and not result.done():
            result.cancel()
            await self._abandon(job)
            raise WorkerLost(
                f"the Dask worker {job.lost.result()} left the cluster while planning it; "
                "the job is not re-run"
            )
        try:
            body: PlanResult = result.result()
        except FutureCancelledError as exc:
            if job.job_id in self._cancel_requested:
                raise PlanCancelled(job.job_id) from exc
            raise WorkerLost(f"the Dask cluster dropped the job: {exc}") from exc
        return body

    async def _abandon(self, job: _Job) -> None:
        """Stop the task wherever it is: its worker stops at the next iteration, the
        scheduler forgets it (so that it does not run again elsewhere)."""
        from distributed import Event

        try:
            await asyncio.wait_for(Event(CANCEL_PREFIX + job.job_id, self._client).set(), 5.0)
            await asyncio.wait_for(self._client.cancel([job.future], force=True), 5.0)
        except Exception as exc:  # the scheduler gone too: nothing runs it any more
            log.warning("could not stop job %s on the Dask cluster: %r", job.job_id, exc)

    def cancel(self, job_id: str) -> None:
        from distributed import Event

        job = self._jobs.get(job_id)
        if job is None or self._client is None:
            return
        self._cancel_requested.add(job_id)
        job.control.append(asyncio.ensure_future(Event(CANCEL_PREFIX + job_id, self._client).set()))
        if not job.started:  # maybe still waiting for a worker: take it off the scheduler
            job.control.append(asyncio.ensure_future(self._client.cancel([job.future])))

    def forget(self, job_id: str) -> None:
        job = self._jobs.pop(job_id, None)
        self._cancel_requested.discard(job_id)
        if job is not None and self._client is not None:
            task = asyncio.ensure_future(self._clear(job))
            self._clearing.add(task)
            task.add_done_callback(self._clearing.discard)

    async def _clear(self, job: _Job) -> None:
        """Drop the job's Event from the scheduler, after any set of it has landed."""
        from distributed import Event

        with contextlib.suppress(Exception):
            if job.control:
                await asyncio.wait(job.control, timeout=5.0)
            await asyncio.wait_for(Event(CANCEL_PREFIX + job.job_id, self._client).clear(), 5.0)

    async def shutdown(self) -> None:
        for job in list(self._jobs.values()):
            await self._abandon(job)
        if self._clearing:
            await asyncio.wait(self._clearing, timeout=5.0)
        if self._client is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._client.close(), 10.0)
            self._client = None

    def _on_report(self, event: tuple[float, Any]) -> None:
        _, message = event
        kind, *item = message
        if kind == "started":
            job = self._jobs.get(item[0])
            if job is not None:
                job.started = True
        elif kind == "progress":
            self._on_progress(JobProgress(*item))

    def _on_cluster_event(self, event: tuple[float, Any]) -> None:
        _, message = event
        if not isinstance(message, dict) or message.get("action") != "remove-worker":
            return
        keys = set(message.get("processing-tasks") or ())
        for job in self._jobs.values():
            if job.future.key in keys and not job.lost.done():
                job.lost.set_result(str(message.get("worker", "?")))
                log.error("Dask worker %s lost with job %s", message.get("worker"), job.job_id)


class _CancelWatch:
    """`cancelled.get(job_id)` for `run_plan`, asked every optimizer iteration: a local
    flag, set by a thread that waits on the job's distributed Event. It counts the
    iterations, to say how many ran after the cancellation arrived."""

    def __init__(self, event: Any) -> None:
        self._event = event
        self._set = threading.Event()
        self._stop = threading.Event()
        self.iterations = 0
        self.seen_at: int | None = None
        self._thread = threading.Thread(target=self._watch, daemon=True, name="cancel-watch")

    def __enter__(self) -> _CancelWatch:
        self._thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self._stop.set()

    def _watch(self) -> None:
        while not self._stop.is_set():
            try:
                if self._event.wait(timeout=WATCH_S):
                    self.seen_at = self.iterations
                    self._set.set()
                    return
            except Exception:  # scheduler unreachable: the job is lost anyway
                if self._stop.wait(WATCH_S):
                    return

    def get(self, job_id: str, default: bool = False) -> bool:
        self.iterations += 1
        return self._set.is_set()

    @property
    def iterations_after(self) -> int | None:
        return None if self.seen_at is None else self.iterations - self.seen_at


class _Reports:
    """The progress queue `run_plan` puts reports in: Dask events under the service's
    topic (sent by the worker's own event loop, so the planner never waits on them)."""

    def __init__(self, worker: Any, topic: str) -> None:
        self._worker = worker
        self._topic = topic

    def put(self, item: tuple[Any, ...]) -> None:
        self._worker.log_event(self._topic, ["progress", *item])


def plan_on_worker(
    job_id: str,
    scenario: dict[str, Any],
    settings: dict[str, Any],
    topic: str,
    cancel_event: str,
    soonest_of: SoonestOf | None = None,
) -> PlanResult:
    """The task on a Dask worker: `run_plan` with progress as events and the job's Event
    looked at every optimizer iteration."""
    from distributed import Event, get_client, get_worker

    worker = get_worker()
    worker.log_event(topic, ["started", job_id, worker.address])
    with _CancelWatch(Event(cancel_event, client=get_client())) as cancelled:
        try:
            return run_plan(
                job_id,
                scenario,
                settings,
                _Reports(worker, topic),
                cancelled,
                cancel_each_iteration=True,
                soonest_of=soonest_of,
            )
        except PlanCancelled:
            raise PlanCancelled(job_id, cancelled.iterations_after) from None
