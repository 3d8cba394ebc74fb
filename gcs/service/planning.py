"""Plan requests: stored as jobs, run in the worker pool, answered at once when quick.

A job moves through `JobState` only: a late progress report cannot reopen a finished
job, and a cancelled one stays cancelled.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any

from gcs.service.metrics import ServiceMetrics
from gcs.service.planning_pool import JobProgress, PlanCancelled, PlanRunner, SoonestOf
from gcs.service.states import JobState, StateConflict
from gcs.service.storage import JobRepository, PlanRepository, ScenarioRepository
from gcs.service.storage.tables import JobRow, PlanRow
from planner.model.scenario import Scenario
from planner.pipeline import PlannerSettings

log = logging.getLogger("mvo_gcs.planning")
J = JobState
CANCEL_WAIT_S = 10.0


@dataclass
class PlanningService:
    scenarios: ScenarioRepository
    plans: PlanRepository
    jobs: JobRepository
    metrics: ServiceMetrics
    pool: PlanRunner | None = None
    _tasks: dict[str, asyncio.Task[None]] = field(default_factory=dict)
    _watchers: dict[str, set[asyncio.Queue[JobRow]]] = field(default_factory=dict)
    _reports: set[asyncio.Task[None]] = field(default_factory=set)  # progress being stored
    _stopping: bool = False
    claim: Callable[[str], Awaitable[bool]] | None = None
    """Takes a queued job for this service (LeaseRepository.claim_job): run once."""

    async def request(
        self,
        scenario_id: str,
        settings: PlannerSettings,
        wait_s: float,
        clearance_m: float = 0.0,
        soonest_of: tuple[int, float] | None = None,
    ) -> JobRow:
        """Start a job; return it once done or after `wait_s`, whichever comes first. The
        plan keeps `clearance_m` beyond 2R between UAVs (room to stray in flight). With
        `soonest_of` (count, speed), that many seeds are planned and the plan flown soonest
        at that speed is kept."""
        scenario = await self.scenarios.get(scenario_id)
        chosen = {}
        if soonest_of is not None:
            chosen = {"candidates": soonest_of[0], "flight_speed_m_s": soonest_of[1]}
        job: JobRow = await self.jobs.add(
            JobRow(
                scenario_id=scenario_id,
                settings={**_settings_json(settings), "clearance_m": clearance_m, **chosen},
            )
        )
        if self.claim is not None and not await self.claim(job.id):
            return job  # another service runs it
        planned = Scenario(**scenario.body).with_clearance(clearance_m).model_dump(mode="json")
        choice = None
        if soonest_of is not None:
            choice = SoonestOf(*soonest_of, flown=scenario.body, clearance_m=clearance_m)
        task = asyncio.ensure_future(self._run(job.id, planned, settings, choice))
        self._tasks[job.id] = task
        task.add_done_callback(lambda _: self._tasks.pop(job.id, None))
        await asyncio.wait({task}, timeout=wait_s)
        row: JobRow = await self.jobs.get(job.id)
        return row

    async def _run(
        self,
        job_id: str,
        scenario: dict[str, Any],
        settings: PlannerSettings,
        soonest_of: SoonestOf | None,
    ) -> None:
        assert self.pool is not None, "the planning pool starts with the service"
        started = time.perf_counter()
        try:
            result = await self.pool.submit(job_id, scenario, settings, soonest_of)
        except (PlanCancelled, asyncio.CancelledError) as exc:
            if self._stopping:  # not the user's doing: as after a crash (Database.recover)
                await self._set(job_id, J.INTERRUPTED, error="the service stopped")
            else:
                await self._set(job_id, J.CANCELLED, error=_cancelled(exc))
                self.metrics.plans.labels("cancelled").inc()
        except Exception as exc:  # a planner bug must end the job, not the service
            await self._set(job_id, J.FAILED, error=f"{type(exc).__name__}: {exc}")
            self.metrics.plans.labels("failed").inc()
        else:
            job, body = await self.jobs.get(job_id), result["plan"]
            row = await self.plans.add(
                PlanRow(
                    scenario_id=job.scenario_id,
                    feasible=body["feasible"],
                    body=body,
                    candidates=result["candidates"],
                )
            )
            await self._set(job_id, J.DONE, percent=100.0, plan_id=row.id)
            self.metrics.plans.labels("feasible" if body["feasible"] else "infeasible").inc()
        finally:
            self.metrics.plan_seconds.observe(time.perf_counter() - started)
            if self.pool is not None:
                self.pool.forget(job_id)

    def on_progress(self, p: JobProgress) -> None:
        task = self._tasks.get(p.job_id)
        if task is not None and not task.done():
            report = self._set(
                p.job_id,
                J.RUNNING,
                percent=p.percent,
                best_cost=p.best_cost,
                first_safe_s=p.first_safe_s,
            )
            pending = asyncio.ensure_future(report)
            self._reports.add(pending)
            pending.add_done_callback(self._reports.discard)

    async def cancel(self, job_id: str) -> JobRow:
        job: JobRow = await self.jobs.get(job_id)
        if JobState(job.state).is_final:
            raise StateConflict(
                f"job {job.id} is {job.state}; only queued or running jobs can be cancelled"
            )
        if self.pool is not None:
            self.pool.cancel(job_id)
        return job

    async def cancel_for_scenario(self, scenario_id: str) -> None:
        """Cancel the scenario's unfinished jobs and wait (bounded) until they have ended,
        so that no worker goes on planning for a scenario that is gone."""
        jobs = await self.jobs.unfinished_for_scenario(scenario_id)
        for job in jobs:
            with contextlib.suppress(StateConflict):
                await self.cancel(job.id)
        tasks = [self._tasks[job.id] for job in jobs if job.id in self._tasks]
        if tasks:
            await asyncio.wait(tasks, timeout=CANCEL_WAIT_S)

    def watch(self, job_id: str) -> asyncio.Queue[JobRow]:
        queue: asyncio.Queue[JobRow] = asyncio.Queue(maxsize=100)
        self._watchers.setdefault(job_id, set()).add(queue)
        return queue

    def unwatch(self, job_id: str, queue: asyncio.Queue[JobRow]) -> None:
        self._watchers.get(job_id, set()).discard(queue)

    async def _set(self, job_id: str, state: JobState, **values: Any) -> None:
        try:
            job = await self.jobs.transition(job_id, state, **values)
        except StateConflict:
            return  # a late report (progress after the end) changes nothing
        for queue in self._watchers.get(job_id, ()):
            if queue.full():  # a slow watcher misses old progress, never the latest state
                queue.get_nowait()
            queue.put_nowait(job)

    async def shutdown(self) -> None:
        self._stopping = True
        for task in list(self._tasks.values()):
            task.cancel()
        if self._tasks:
            await asyncio.wait(list(self._tasks.values()), timeout=5.0)


def _cancelled(exc: BaseException) -> str:
    """The stored reason; a Dask worker counts the iterations it ran after the cancel."""
    after = getattr(exc, "iterations_after", None)
    if after is None:
        return "cancelled on request"
    return f"cancelled on request (its worker stopped {after} optimizer iteration(s) later)"


def _settings_json(settings: PlannerSettings) -> dict[str, Any]:
    return {
        "algorithm": settings.algorithm,
        "objective": settings.objective,
        "seed": settings.seed,
        "population": settings.population,
        "iterations": settings.iterations,
        "time_budget_s": settings.time_budget_s,
        "patience": settings.patience,
    }
