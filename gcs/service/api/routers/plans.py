"""Plan requests, plans and the jobs that make them."""

from __future__ import annotations

import asyncio
import contextlib

from fastapi import APIRouter, Query, WebSocket, WebSocketDisconnect, status
from fastapi.responses import JSONResponse

from gcs.service.api.deps import ServicesDep, get_services, mutating
from gcs.service.api.schemas import JobOut, PlanOut, PlanRequest, Problem
from gcs.service.storage.tables import JobRow, PlanRow
from planner.pipeline import PlannerSettings
from planner.plan import Plan

router = APIRouter(tags=["plans"])
FINISHED = ("done", "failed", "cancelled", "interrupted")


def plan_out(row: PlanRow) -> PlanOut:
    return PlanOut(
        id=row.id, scenario_id=row.scenario_id, created_at=row.created_at, plan=Plan(**row.body)
    )


@router.post(
    "/scenarios/{scenario_id}/plans",
    status_code=status.HTTP_201_CREATED,
    response_model=PlanOut,
    **mutating(
        {
            202: {"model": JobOut, "description": "still planning: poll or watch the job"},
            404: {"model": Problem, "description": "no such scenario"},
        }
    ),
)
async def request_plan(
    scenario_id: str, request: PlanRequest, services: ServicesDep
) -> PlanOut | JSONResponse:
    """Plan a stored scenario in the worker pool. A plan ready within `wait_s` is answered
    at once (201); otherwise the answer is the job (202), whose progress can be polled at
    `/jobs/{id}` or watched on `/jobs/{id}/live`, and which can be cancelled."""
    budget = services.settings.max_plan_evaluations
    if request.population * request.iterations > budget:
        detail = (
            f"population x iterations = {request.population * request.iterations} exceeds "
            f"this service's limit of {budget} evaluations per optimizer run"
        )
        return JSONResponse({"detail": detail}, status_code=422)
    settings = PlannerSettings(
        algorithm=request.algorithm,
        objective=request.objective,
        seed=request.seed,
        population=request.population,
        iterations=request.iterations,
    )
    wait = services.settings.inline_plan_wait_s if request.wait_s is None else request.wait_s
    job = await services.planning.request(scenario_id, settings, wait)
    if job.state == "done" and job.plan_id is not None:
        return plan_out(services.plans.get(job.plan_id))
    code = status.HTTP_202_ACCEPTED if job.state in ("queued", "running") else 200
    return JSONResponse(
        JobOut.model_validate(job).model_dump(mode="json"),
        status_code=code,
        headers={"Location": f"/jobs/{job.id}"},
    )


@router.get("/scenarios/{scenario_id}/plans", responses={404: {"model": Problem}})
def list_plans(scenario_id: str, services: ServicesDep) -> list[PlanOut]:
    services.scenarios.get(scenario_id)
    return [plan_out(row) for row in services.plans.for_scenario(scenario_id)]


@router.get("/plans/{plan_id}", responses={404: {"model": Problem}})
def get_plan(plan_id: str, services: ServicesDep) -> PlanOut:
    return plan_out(services.plans.get(plan_id))


@router.get("/jobs", tags=["jobs"])
def list_jobs(
    services: ServicesDep,
    limit: int = Query(default=100, ge=1, le=1000),
    offset: int = Query(default=0, ge=0, le=10**9),
) -> list[JobOut]:
    return [JobOut.model_validate(row) for row in services.jobs.list(limit, offset)]


@router.get("/jobs/{job_id}", tags=["jobs"], responses={404: {"model": Problem}})
def get_job(job_id: str, services: ServicesDep) -> JobOut:
    return JobOut.model_validate(services.jobs.get(job_id))


@router.post(
    "/jobs/{job_id}/cancel",
    tags=["jobs"],
    status_code=status.HTTP_202_ACCEPTED,
    **mutating({404: {"model": Problem}, 409: {"model": Problem, "description": "finished"}}),
)
def cancel_job(job_id: str, services: ServicesDep) -> JobOut:
    """Ask a queued or running job to stop; it ends `cancelled` within one iteration."""
    return JobOut.model_validate(services.planning.cancel(job_id))


@router.websocket("/jobs/{job_id}/live")
async def watch_job(websocket: WebSocket, job_id: str) -> None:
    """The job as JSON after every progress report, closing once it has finished."""
    services = get_services(websocket)
    await websocket.accept()
    try:
        job = services.jobs.get(job_id)
    except LookupError as exc:
        await websocket.close(code=4404, reason=str(exc))
        return
    queue = services.planning.watch(job_id)
    try:
        await _send_job(websocket, job)
        while job.state not in FINISHED:
            with contextlib.suppress(TimeoutError):
                job = await asyncio.wait_for(queue.get(), timeout=1.0)
                await _send_job(websocket, job)
                continue
            job = services.jobs.get(job_id)  # a quiet second: read it back anyway
        await websocket.close()
    except WebSocketDisconnect:
        pass
    finally:
        services.planning.unwatch(job_id, queue)


async def _send_job(websocket: WebSocket, job: JobRow) -> None:
    await websocket.send_json(JobOut.model_validate(job).model_dump(mode="json"))
