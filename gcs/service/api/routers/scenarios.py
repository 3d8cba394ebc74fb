"""Scenarios: the planner's scenario JSON, stored under an id."""

from __future__ import annotations

import asyncio
import json
from collections.abc import Callable, Coroutine
from typing import Any

from fastapi import APIRouter, Query, Request, Response, status
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.routing import APIRoute
from pydantic import ValidationError
from starlette.concurrency import run_in_threadpool
from starlette.types import Message, Scope

from gcs.mission.area_imports import KML_MEDIA_TYPE, from_kml, is_kml
from gcs.mission.geographic import (
    GEOJSON_MEDIA_TYPE,
    GeographicError,
    derive_file,
    geojson_schema,
    is_geojson,
)
from gcs.service.api.deps import (
    FlightsDep,
    MissionFilesDep,
    PlanningDep,
    PlansDep,
    ScenariosDep,
    mutating,
)
from gcs.service.api.schemas import (
    MAX_PAGE,
    GeographicProblem,
    Problem,
    ScenarioOut,
    ScenarioSummary,
)
from gcs.service.states import OPEN, StateConflict
from gcs.service.storage.tables import ScenarioRow
from gcs.service.vehicle_starts import place_vehicle_starts
from planner.model.scenario import Scenario


class GeographicRoute(APIRoute):
    """`POST /scenarios` with `Content-Type: application/geo+json` (or a KML document,
    `application/vnd.google-earth.kml+xml`, made into that GeoJSON first): the file is made
    into its grid scenario first, off the event loop, and the endpoint then takes that
    as it takes a grid scenario in JSON, with the file kept beside it. A file that
    describes nothing plannable is a 422 naming the feature."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()
        if self.operation_id != "createScenario":
            return handler

        async def route(request: Request) -> Response:
            content_type = request.headers.get("content-type")
            kml = is_kml(content_type)
            if not (kml or is_geojson(content_type)):
                return await handler(request)
            body = await request.body()
            try:
                document = await run_in_threadpool(from_kml, body) if kml else json.loads(body)
                registry = request.app.state.services.registry
                now = asyncio.get_running_loop().time()
                document = place_vehicle_starts(document, registry, now)
                derived = await run_in_threadpool(derive_file, document)
            except UnicodeDecodeError:
                raise RequestValidationError(
                    [{"type": "json_invalid", "loc": ("body",), "msg": "not UTF-8 text"}]
                ) from None
            except json.JSONDecodeError as exc:
                raise RequestValidationError(
                    [{"type": "json_invalid", "loc": ("body", exc.pos), "msg": exc.msg}]
                ) from None
            except ValidationError as exc:
                errors = exc.errors(include_url=False, include_context=False)
                raise RequestValidationError(
                    [{**e, "loc": ("body", *e["loc"])} for e in errors]
                ) from None
            except GeographicError as exc:
                return JSONResponse({"detail": str(exc), "feature": exc.feature}, 422)
            grid = derived.scenario.model_dump_json().encode()
            derived_request = Request(_as_json(request.scope, len(grid)), _replay(grid))
            derived_request.state.geographic = document
            return await handler(derived_request)

        return route


def _as_json(scope: Scope, length: int) -> Scope:
    """The request's scope, its body now the derived grid scenario in JSON."""
    replaced = {b"content-type", b"content-length"}
    headers = [(k, v) for k, v in scope["headers"] if k.lower() not in replaced]
    headers += [(b"content-type", b"application/json"), (b"content-length", b"%d" % length)]
    return {**scope, "headers": headers}


def _replay(body: bytes) -> Callable[[], Coroutine[Any, Any, Message]]:
    async def receive() -> Message:
        return {"type": "http.request", "body": body, "more_body": False}

    return receive


router = APIRouter(prefix="/scenarios", tags=["scenarios"], route_class=GeographicRoute)
NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: {"model": Problem, "description": "no such scenario"}
}
SCENARIO_LINKS = {
    op: {"operationId": op, "parameters": {"scenario_id": "$response.body#/id"}}
    for op in ("getScenario", "requestPlan", "listPlans", "deleteScenario")
}


def _out(row: ScenarioRow) -> ScenarioOut:
    return ScenarioOut(
        id=row.id,
        name=row.name,
        created_at=row.created_at,
        scenario=Scenario(**row.body),
        geographic=row.geographic,
    )


GEOGRAPHIC_BODY = {
    "requestBody": {
        "content": {
            GEOJSON_MEDIA_TYPE: {"schema": geojson_schema()},
            KML_MEDIA_TYPE: {"schema": {"type": "string", "format": "binary"}},
        }
    },
}


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    operation_id="createScenario",
    openapi_extra=GEOGRAPHIC_BODY,
    **mutating(
        {
            201: {"links": SCENARIO_LINKS},
            422: {
                "model": GeographicProblem,
                "description": "the request is invalid; `detail` says where, `feature` "
                "which feature of a geographic scenario",
            },
        }
    ),
)
async def create_scenario(
    scenario: Scenario, scenarios: ScenariosDep, request: Request
) -> ScenarioOut:
    """Store a scenario (validated: grid limits, cells inside the grid, reachable goals).

    Or a geographic scenario (`Content-Type: application/geo+json`): a GeoJSON
    FeatureCollection with the operating area, no-fly zones, starts and goals in WGS84
    and `cell_size_m` (docs/planner.md), a start with `"vehicle": "<id>"` and a null
    geometry placed where that registered vehicle is now; or the same drawn in KML
    (`application/vnd.google-earth.kml+xml`, placemarks named or tagged by role), stored
    as its GeoJSON. Its grid scenario is derived, stored with the
    file beside it and returned; a file that describes nothing plannable (a ring that
    crosses itself, a start in a zone, a goal outside the area, an area too large for
    the grid) is a 422 whose `feature` names the feature at fault."""
    geographic = getattr(request.state, "geographic", None)
    row = ScenarioRow(
        name=scenario.name, body=scenario.model_dump(mode="json"), geographic=geographic
    )
    return _out(await scenarios.add(row))


@router.get("", operation_id="listScenarios")
async def list_scenarios(
    scenarios: ScenariosDep,
    limit: int = Query(default=50, ge=1, le=MAX_PAGE),
    offset: int = Query(default=0, ge=0, le=10**9),
) -> list[ScenarioSummary]:
    """Oldest first, summarised (a page of whole scenarios could be megabytes)."""
    return [_summary(row) for row in await scenarios.page(limit, offset)]


def _summary(row: ScenarioRow) -> ScenarioSummary:
    grid = row.body.get("grid", {})
    return ScenarioSummary(
        id=row.id,
        name=row.name,
        created_at=row.created_at,
        grid=[grid.get("width", 0), grid.get("height", 0)],
        uavs=len(row.body.get("uavs", [])),
    )


@router.get("/{scenario_id}", operation_id="getScenario", responses=NOT_FOUND)
async def get_scenario(scenario_id: str, scenarios: ScenariosDep) -> ScenarioOut:
    return _out(await scenarios.get(scenario_id))


@router.delete(
    "/{scenario_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    operation_id="deleteScenario",
    **mutating(
        {**NOT_FOUND, 409: {"model": Problem, "description": "an open flight flies its plan"}}
    ),
)
async def delete_scenario(
    scenario_id: str,
    scenarios: ScenariosDep,
    plans: PlansDep,
    planning: PlanningDep,
    flights: FlightsDep,
    mission_files: MissionFilesDep,
) -> None:
    """Delete a scenario with its plans, jobs and ended flights. Refused while an open
    flight flies one of its plans; planning jobs still running are cancelled first."""
    await scenarios.get(scenario_id)
    await planning.cancel_for_scenario(scenario_id)
    async with flights.book.claims:  # no upload may claim one of its plans meanwhile
        plan_ids = await plans.ids_for_scenario(scenario_id)
        flying = [f for f in await flights.book.flights.for_plans(plan_ids) if f.state in OPEN]
        if flying:
            raise StateConflict(
                f"scenario {scenario_id}: flight {flying[0].id} ({flying[0].state}) "
                "flies one of its plans; abort or end it first"
            )
        await scenarios.delete(scenario_id)
    mission_files.forget(*plan_ids, scenario_id=scenario_id)
