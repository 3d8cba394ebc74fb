"""Liveness, readiness and Prometheus metrics."""

from __future__ import annotations

from fastapi import APIRouter, Response
from fastapi.responses import JSONResponse
from sqlalchemy import text

from gcs.service.api.deps import ServicesDep

router = APIRouter(tags=["health"])


@router.get("/health/live")
async def live() -> dict[str, str]:
    """The process answers."""
    return {"status": "ok"}


@router.get("/health/ready", responses={503: {"description": "not ready; says what is not"}})
async def ready(services: ServicesDep) -> JSONResponse:
    """Storage answers and the planning pool runs. `warnings`: what works less than it
    should while the service is still ready (no vehicle discovery: its port is taken)."""
    problems = []
    try:
        await services.db.run(_select_one, services)
    except Exception as exc:  # any storage failure means not ready
        problems.append(f"storage: {exc}")
    if services.planning.pool is None:
        problems.append("planning pool not started")
    discovery = services.discovery
    warnings = [discovery.error] if discovery is not None and discovery.error else []
    body = {
        "status": "ready" if not problems else "not ready",
        "problems": problems,
        "warnings": warnings,
    }
    return JSONResponse(body, status_code=503 if problems else 200)


def _select_one(services: ServicesDep) -> None:
    with services.db.session() as s:
        s.execute(text("SELECT 1"))


@router.get("/metrics", response_class=Response, responses={200: {"content": {"text/plain": {}}}})
async def metrics(services: ServicesDep) -> Response:
    return Response(services.metrics.render(), media_type="text/plain; version=0.0.4")
