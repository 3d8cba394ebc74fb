"""Plan requests: stored as jobs, run in the worker pool, answered at once when quick."""

from __future__ import annotations

import asyncio
import contextlib
import time
from dataclasses import dataclass, field
from typing import Any

from gcs.service.metrics import ServiceMetrics
from gcs.service.planning_pool import JobProgress, PlanCancelled, PlanningPool
from gcs.service.storage import JobRepository, PlanRepository, ScenarioRepository
from gcs.service.storage.tables import JobRow, PlanRow
from planner.pipeline import PlannerSettings


class JobNotCancellable(Exception):
    def __init__(self, job: JobRow) -> None:
        super().__init__(
            f"job {job.id} is {job.state}; only queued or running jobs can be cancelled"
        )


@dataclass
class PlanningService:
    scenarios: ScenarioRepository
    plans: PlanRepository
    jobs: JobRepository
    metrics: ServiceMetrics
    pool: PlanningPool | None = None
    _tasks: dict[str, asyncio.Task[None]] = field(default_factory=dict)
    _watchers: dict[str, set[asyncio.Queue[JobRow]]] = field(default_factory=dict)

    async def request(self, scenario_id: str, settings: PlannerSettings, wait_s: float) -> JobRow:
        """Start a job; return it once done or after `wait_s`, whichever comes first."""
        scenario = self.scenarios.get(scenario_id)
        job = self.jobs.add(JobRow(scenario_id=scenario_id, settings=_settings_json(settings)))
        task = asyncio.create_task(self._run(job.id, scenario.body, settings))
        self._tasks[job.id] = task
        task.add_done_callback(lambda _: self._tasks.pop(job.id, None))
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(asyncio.shield(task), timeout=wait_s)
        return self.jobs.get(job.id)

    async def _run(self, job_id: str, scenario: dict[str, Any], settings: PlannerSettings) -> None:
        assert self.pool is not None, "the planning pool starts with the service"
        started = time.perf_counter()
        try:
            body = await self.pool.submit(job_id, scenario, settings)
        except PlanCancelled:
            self._set(job_id, state="cancelled", error="cancelled on request")
            self.metrics.plans.labels("cancelled").inc()
        except asyncio.CancelledError:
            self._set(job_id, state="cancelled", error="cancelled on request")
            raise
        except Exception as exc:  # a planner bug must end the job, not the service
            self._set(job_id, state="failed", error=f"{type(exc).__name__}: {exc}")
            self.metrics.plans.labels("failed").inc()
        else:
            job = self.jobs.get(job_id)
            row = self.plans.add(
                PlanRow(scenario_id=job.scenario_id, feasible=body["feasible"], body=body)
            )
            self._set(job_id, state="done", percent=100.0, plan_id=row.id)
            self.metrics.plans.labels("feasible" if body["feasible"] else "infeasible").inc()
        finally:
            self.metrics.plan_seconds.observe(time.perf_counter() - started)
            if self.pool is not None:
                self.pool.forget(job_id)

    def on_progress(self, p: JobProgress) -> None:
        task = self._tasks.get(p.job_id)
        if task is not None and not task.done():  # a late report must not undo "done"
            self._set(p.job_id, state="running", percent=p.percent, best_cost=p.best_cost)

    def cancel(self, job_id: str) -> JobRow:
        job = self.jobs.get(job_id)
        if job.state not in ("queued", "running"):
            raise JobNotCancellable(job)
        if self.pool is not None:
            self.pool.cancel(job_id)
        return job

    def watch(self, job_id: str) -> asyncio.Queue[JobRow]:
        queue: asyncio.Queue[JobRow] = asyncio.Queue(maxsize=100)
        self._watchers.setdefault(job_id, set()).add(queue)
        return queue

    def unwatch(self, job_id: str, queue: asyncio.Queue[JobRow]) -> None:
        self._watchers.get(job_id, set()).discard(queue)

    def _set(self, job_id: str, **values: Any) -> None:
        job = self.jobs.update(job_id, **values)
        for queue in self._watchers.get(job_id, ()):
            if not queue.full():
                queue.put_nowait(job)

    async def shutdown(self) -> None:
        for task in list(self._tasks.values()):
            task.cancel()


def _settings_json(settings: PlannerSettings) -> dict[str, Any]:
    return {
        "algorithm": settings.algorithm,
        "objective": settings.objective,
        "seed": settings.seed,
        "population": settings.population,
        "iterations": settings.iterations,
    }
