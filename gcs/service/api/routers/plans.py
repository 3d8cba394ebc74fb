"""Plan requests, plans and the jobs that make them."""

from __future__ import annotations

import asyncio
from typing import Any

from fastapi import APIRouter, Query, WebSocket, status
from fastapi.responses import JSONResponse

from gcs.mission.geographic import frame_of, wgs84_trajectories
from gcs.service.api.deps import (
    FlightsDep,
    JobsDep,
    MissionFilesDep,
    PlanningDep,
    PlansDep,
    ScenariosDep,
    SettingsDep,
    get_services,
    mutating,
)
from gcs.service.api.live_sockets import send_until_done
from gcs.service.api.schemas import (
    MAX_PAGE,
    CandidateOut,
    JobOut,
    PlanOut,
    PlanRequest,
    PlanSummary,
    Problem,
)
from gcs.service.states import OPEN, JobState, StateConflict
from gcs.service.storage import ScenarioRepository
from gcs.service.storage.tables import JobRow, PlanRow
from planner.model.plan import Plan
from planner.model.scenario import Grid, Origin
from planner.pipeline import PlannerSettings

router = APIRouter(tags=["plans"])
NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": Problem}}
PLAN_LINKS = {
    op: {"operationId": op, "parameters": {"plan_id": "$response.body#/id"}}
    for op in ("getPlan", "deletePlan", "planMissions")
}
JOB_LINKS = {
    op: {"operationId": op, "parameters": {"job_id": "$response.body#/id"}}
    for op in ("getJob", "cancelJob")
}


async def plan_out(row: PlanRow, scenarios: ScenarioRepository) -> PlanOut:
    """The plan, with its trajectories in WGS84 too when its scenario has an origin."""
    plan = Plan(**row.body)
    scenario = (await scenarios.get(row.scenario_id)).body
    origin = scenario.get("origin")
    frame = frame_of(Grid(**scenario["grid"]), Origin(**origin) if origin else None)
    return PlanOut(
        id=row.id,
        scenario_id=row.scenario_id,
        created_at=row.created_at,
        plan=plan,
        candidates=None if row.candidates is None else [CandidateOut(**c) for c in row.candidates],
        trajectories_wgs84=None if frame is None else wgs84_trajectories(frame, plan),
    )


@router.post(
    "/scenarios/{scenario_id}/plans",
    status_code=status.HTTP_201_CREATED,
    response_model=PlanOut,
    operation_id="requestPlan",
    **mutating(
        {
            201: {"links": PLAN_LINKS},
            202: {
                "model": JobOut,
                "description": "still planning: poll or watch the job",
                "links": JOB_LINKS,
            },
            404: {"model": Problem, "description": "no such scenario"},
        }
    ),
)
async def request_plan(
    scenario_id: str,
    request: PlanRequest,
    settings: SettingsDep,
    planning: PlanningDep,
    plans: PlansDep,
    scenarios: ScenariosDep,
) -> PlanOut | JSONResponse:
    """Plan a stored scenario in the worker pool. A plan ready within `wait_s` is answered
    at once (201); otherwise the answer is the job (202), whose progress can be polled at
    `/jobs/{id}` or watched on `/jobs/{id}/live`, and which can be cancelled."""
    budget = settings.max_plan_evaluations
    evaluations = request.population * request.iterations * request.candidates
    if request.time_budget_s is None and evaluations > budget:
        detail = (
            f"population x iterations x candidates = {evaluations} exceeds this service's "
            f"limit of {budget} evaluations per request without a time budget (give "
            "`time_budget_s`)"
        )
        return JSONResponse({"detail": detail}, status_code=422)
    if request.time_budget_s is not None and request.time_budget_s > settings.max_plan_seconds:
        detail = (
            f"time_budget_s = {request.time_budget_s} exceeds this service's limit of "
            f"{settings.max_plan_seconds} s per plan"
        )
        return JSONResponse({"detail": detail}, status_code=422)
    soonest_of = None
    if request.candidates > 1:
        if (await scenarios.get(scenario_id)).body.get("origin") is None:
            detail = (
                f"candidates: scenario {scenario_id} has no origin, so its plans cannot be "
                "timed as flown; give it an origin or ask for one candidate"
            )
            return JSONResponse({"detail": detail}, status_code=422)
        soonest_of = request.candidates, request.flight_speed_m_s
    planner_settings = PlannerSettings(
        algorithm=request.algorithm,
        objective=request.objective,
        seed=request.seed,
        population=request.population,
        iterations=request.iterations,
        time_budget_s=request.time_budget_s,
        patience=request.patience,
        # The safe start ignores the time budget; a worker is still never held longer.
        safe_start_limit_s=settings.max_plan_seconds,
    )
    wait = settings.inline_plan_wait_s if request.wait_s is None else request.wait_s
    job = await planning.request(
        scenario_id, planner_settings, wait, request.clearance_m, soonest_of
    )
    if job.state == JobState.DONE and job.plan_id is not None:
        return await plan_out(await plans.get(job.plan_id), scenarios)
    final = JobState(job.state).is_final
    return JSONResponse(
        JobOut.model_validate(job).model_dump(mode="json"),
        status_code=200 if final else status.HTTP_202_ACCEPTED,
        headers={"Location": f"/jobs/{job.id}"},
    )


@router.get("/scenarios/{scenario_id}/plans", operation_id="listPlans", responses=NOT_FOUND)
async def list_plans(
    scenario_id: str,
    scenarios: ScenariosDep,
    plans: PlansDep,
    limit: int = Query(default=50, ge=1, le=MAX_PAGE),
) -> list[PlanSummary]:
    """Oldest first, without paths or histories (GET /plans/{id} has them)."""
    await scenarios.get(scenario_id)
    return [_summary(row) for row in await plans.for_scenario(scenario_id, limit)]


def _summary(row: PlanRow) -> PlanSummary:
    body = row.body
    return PlanSummary(
        id=row.id,
        scenario_id=row.scenario_id,
        created_at=row.created_at,
        feasible=row.feasible,
        algorithm=body["algorithm"],
        objective=body["objective"],
        metrics=body["metrics"],
    )


@router.get("/plans/{plan_id}", operation_id="getPlan", responses=NOT_FOUND)
async def get_plan(plan_id: str, plans: PlansDep, scenarios: ScenariosDep) -> PlanOut:
    return await plan_out(await plans.get(plan_id), scenarios)


@router.delete(
    "/plans/{plan_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    operation_id="deletePlan",
    **mutating({**NOT_FOUND, 409: {"model": Problem, "description": "an open flight flies it"}}),
)
async def delete_plan(
    plan_id: str, plans: PlansDep, flights: FlightsDep, mission_files: MissionFilesDep
) -> None:
    """Delete a plan and its ended flights; refused while an open flight flies it."""
    await plans.get(plan_id)
    async with flights.book.claims:
        flying = [f for f in await flights.book.flights.for_plans([plan_id]) if f.state in OPEN]
        if flying:
            raise StateConflict(
                f"plan {plan_id}: flight {flying[0].id} ({flying[0].state}) flies it; "
                "abort or end it first"
            )
        await plans.delete(plan_id)
    mission_files.forget(plan_id)


@router.get("/jobs", tags=["jobs"], operation_id="listJobs")
async def list_jobs(
    jobs: JobsDep,
    limit: int = Query(default=50, ge=1, le=MAX_PAGE),
    offset: int = Query(default=0, ge=0, le=10**9),
) -> list[JobOut]:
    return [JobOut.model_validate(row) for row in await jobs.page(limit, offset)]


@router.get("/jobs/{job_id}", tags=["jobs"], operation_id="getJob", responses=NOT_FOUND)
async def get_job(job_id: str, jobs: JobsDep) -> JobOut:
    return JobOut.model_validate(await jobs.get(job_id))


@router.post(
    "/jobs/{job_id}/cancel",
    tags=["jobs"],
    status_code=status.HTTP_202_ACCEPTED,
    operation_id="cancelJob",
    **mutating({**NOT_FOUND, 409: {"model": Problem, "description": "finished"}}),
)
async def cancel_job(job_id: str, planning: PlanningDep) -> JobOut:
    """Ask a queued or running job to stop; it ends `cancelled` within one iteration."""
    return JobOut.model_validate(await planning.cancel(job_id))


@router.websocket("/jobs/{job_id}/live")
async def watch_job(websocket: WebSocket, job_id: str) -> None:
    """The job as JSON after every progress report, closing once it has finished. The
    socket only sends: a client message closes it (1008); beyond the service's caps it is
    closed at once (1013)."""
    services = get_services(websocket)
    async with services.live.admitted(websocket, f"job {job_id}") as admitted:
        if not admitted:
            return
        try:
            job = await services.jobs.get(job_id)
        except LookupError as exc:
            await websocket.close(code=4404, reason=str(exc))
            return
        queue = services.planning.watch(job_id)
        try:
            await send_until_done(websocket, _follow(websocket, job, queue))
        finally:
            services.planning.unwatch(job_id, queue)


async def _follow(websocket: WebSocket, job: JobRow, queue: asyncio.Queue[JobRow]) -> None:
    jobs = get_services(websocket).jobs
    await _send_job(websocket, job)
    while not JobState(job.state).is_final:
        try:
            async with asyncio.timeout(1.0):
                job = await queue.get()
        except TimeoutError:  # a quiet second: read it back, and send it if it has ended
            job = await jobs.get(job.id)
            if not JobState(job.state).is_final:
                continue
        await _send_job(websocket, job)
    await websocket.close()


async def _send_job(websocket: WebSocket, job: JobRow) -> None:
    await websocket.send_json(JobOut.model_validate(job).model_dump(mode="json"))
