"""The FastAPI application: its parts are built in the lifespan, routers hold the endpoints."""

from __future__ import annotations

import logging
import re
from collections.abc import AsyncIterator, Awaitable, Callable
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.exception_handlers import http_exception_handler
from fastapi.responses import JSONResponse, Response
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match, Mount

from gcs.mavlink.connection import Signing
from gcs.mavlink.endpoint import EndpointError
from gcs.mavlink.errors import GcsError
from gcs.mavlink.transport import TransportOpener, open_transport
from gcs.mission.flight_plan import UnsafeSpeed
from gcs.service.api.auth import ensure_token
from gcs.service.api.deps import Services
from gcs.service.api.request_guard import RequestGuard
from gcs.service.api.routers import (
    cases,
    flights,
    health,
    missions,
    plans,
    scenarios,
    vehicles,
)
from gcs.service.console import mount_console
from gcs.service.flights.service import BadBindings, BadObject
from gcs.service.planning_pool import PlanRunner, ProgressSink, planner_for
from gcs.service.settings import Settings
from gcs.service.states import StateConflict
from gcs.service.storage import Database, NotFound
from gcs.service.vehicle_registry import VehicleOffline

log = logging.getLogger("mvo_gcs")

DESCRIPTION = """Plans collision-free paths for several UAVs with the multi-verse optimizer
(MVO) or one of five other metaheuristics, turns them into MAVLink missions, uploads them
to the vehicles, flies the fleet together and streams its telemetry.

Reading is open; every request that changes state needs `Authorization: Bearer <token>`.
"""

HTTP_METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE")


def create_app(
    settings: Settings | None = None, *, opener: TransportOpener = open_transport
) -> FastAPI:
    """The service. `opener` opens vehicles' connection strings: sockets, or in-memory
    ports of simulated vehicles (a flight on one virtual clock, in the tests)."""
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        _private_directory(settings.data_dir)
        db = Database(settings.resolved_database_url)
        token, token_file = ensure_token(settings)
        services = Services.build(settings, db, opener)
        holder = services.control.holder
        recovered = await db.run(db.recover, (holder.id, holder.url), settings.lease_s)
        if any(recovered.values()):
            log.warning("marked unfinished work from the last run as interrupted: %s", recovered)
        services.events.start()
        services.loop_lag.start()
        if services.discovery is not None:
            await services.discovery.start()
        pool = _planner(settings, services.planning.on_progress)
        await pool.start()
        services.planning.pool = pool
        for vehicle in await services.vehicles.page(limit=10_000):
            signing = Signing.from_text(vehicle.signing_key) if vehicle.signing_key else None
            services.registry.add(vehicle.id, vehicle.connection, vehicle.sysid, signing)
        await services.operator.after_restart(holder.id)
        services.control.start()
        app.state.token, app.state.token_file, app.state.services = token, token_file, services
        _announce(settings, token, token_file)
        try:
            yield
        finally:
            await services.control.stop()
            await services.operator.close()
            await services.flights.close()
            await services.control.release()
            await services.registry.close()
            if services.discovery is not None:
                await services.discovery.close()
            await services.events.close()
            await services.planning.shutdown()
            await services.missions.close()
            services.loop_lag.stop()
            await pool.shutdown()
            db.close()

    app = FastAPI(
        title="mvo-gcs",
        version="0.1.0",
        description=DESCRIPTION,
        lifespan=lifespan,
    )
    app.add_middleware(
        RequestGuard,
        token=lambda: app.state.token,
        hosts=settings.host_names,
        max_bytes=settings.max_body_bytes,
        body_timeout_s=settings.body_timeout_s,
    )
    routers = (scenarios, plans, missions, vehicles, flights, cases, health)
    for module in routers:
        app.include_router(module.router)
    _add_error_handlers(app)
    mount_console(app, settings)
    return app


def _planner(settings: Settings, on_progress: ProgressSink) -> PlanRunner:
    """Local processes (or a thread), or the Dask cluster when one is configured (Dask is
    imported only then)."""
    if settings.dask_scheduler:
        from gcs.service.dask_planner import DaskPlanner

        return DaskPlanner(settings.dask_scheduler, on_progress)
    return planner_for(settings.plan_workers, on_progress)


def _private_directory(path: Path) -> None:
    """The data directory holds every plan, flight and the token: its owner's only."""
    path.mkdir(parents=True, exist_ok=True, mode=0o700)
    if path.stat().st_mode & 0o077:
        path.chmod(0o700)


def _methods_at(request: Request) -> list[str]:
    """The methods the request's path answers: as the API document says (its most
    specific path: `/vehicles/discovered`, not `/vehicles/{vehicle_id}`), else as the
    routes outside it do (the console, the docs; a mount serves files: GET, HEAD)."""
    path = request.url.path
    documented = _documented_methods(request.app.openapi().get("paths", {}), path)
    if documented:
        return documented
    methods: set[str] = set()
    scope = {"type": "http", "path": path, "root_path": "", "method": "GET"}
    for route in request.app.router.routes:
        if isinstance(route, Mount):
            if route.matches(scope)[0] == Match.FULL:
                methods |= {"GET", "HEAD"}
            continue
        for method in HTTP_METHODS:
            if route.matches({**scope, "method": method})[0] == Match.FULL:
                methods.add(method)
    return sorted(methods)


def _documented_methods(paths: dict[str, dict[str, object]], path: str) -> list[str]:
    matching = [
        (template.count("{"), template)
        for template in paths
        if re.fullmatch(re.sub(r"\\\{[^}]*\\\}", "[^/]+", re.escape(template)), path)
    ]
    if not matching:
        return []
    _, template = min(matching)
    return sorted(m.upper() for m in paths[template] if m.upper() in HTTP_METHODS)


def _announce(settings: Settings, token: str, token_file: Path | None) -> None:
    """Where the docs are and where the token is, on the terminal that started us."""
    print(f"mvo-gcs: API docs at http://{settings.host}:{settings.port}/docs", flush=True)
    where = f"in {token_file}" if token_file else "from the MVO_GCS_TOKEN setting"
    print(f"mvo-gcs: bearer token {where}", flush=True)
    if settings.show_token:
        print(f"mvo-gcs: token {token}", flush=True)


async def _unsafe_speed(_: Request, exc: Exception) -> JSONResponse:
    """422, with the highest speed the ground station can keep safe, for a client to offer."""
    highest = exc.highest_safe_m_s if isinstance(exc, UnsafeSpeed) else None
    return JSONResponse({"detail": str(exc), "highest_safe_speed_m_s": highest}, status_code=422)


def _add_error_handlers(app: FastAPI) -> None:
    def problem(status: int) -> Callable[[Request, Exception], Awaitable[JSONResponse]]:
        async def handler(_: Request, exc: Exception) -> JSONResponse:
            return JSONResponse({"detail": str(exc)}, status_code=status)

        return handler

    async def http_error(request: Request, exc: Exception) -> Response:
        response = await http_exception_handler(request, exc)  # type: ignore[arg-type]
        if response.status_code == 405:  # one path, several routes: name all their methods
            response.headers["Allow"] = ", ".join(_methods_at(request))
        return response

    app.add_exception_handler(StarletteHTTPException, http_error)
    app.add_exception_handler(NotFound, problem(404))
    app.add_exception_handler(StateConflict, problem(409))
    app.add_exception_handler(missions.UnflyablePlan, problem(409))
    app.add_exception_handler(vehicles.AlreadyRegistered, problem(409))
    app.add_exception_handler(VehicleOffline, problem(409))
    app.add_exception_handler(BadBindings, problem(422))
    app.add_exception_handler(UnsafeSpeed, _unsafe_speed)
    app.add_exception_handler(BadObject, problem(422))
    app.add_exception_handler(EndpointError, problem(422))
    app.add_exception_handler(vehicles.BadConnection, problem(422))
    app.add_exception_handler(GcsError, problem(502))  # the vehicle, not the request
