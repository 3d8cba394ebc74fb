"""Flights: bind a plan's UAVs to vehicles, upload, start, pause, abort, watch live."""

from __future__ import annotations

import asyncio
import contextlib
from typing import Any, Literal

from fastapi import APIRouter, Query, WebSocket, WebSocketDisconnect, status
from pydantic import BaseModel, ConfigDict, Field

from gcs.mission.build import DEFAULT_ALTITUDE_M
from gcs.mission.pacing import DEFAULT_MAX_SPEED_M_S, TURN_RADIUS_M
from gcs.service.api.deps import ServicesDep, get_services, mutating
from gcs.service.api.schemas import Problem, UtcDatetime
from gcs.service.storage.tables import FlightRow
from planner.live_replan import NewObject

router = APIRouter(prefix="/flights", tags=["flights"])
ANSWERS: dict[int | str, dict[str, Any]] = {
    404: {"model": Problem, "description": "no such flight, plan or vehicle"},
    409: {"model": Problem, "description": "not possible in the flight's state, or offline"},
}
ENDED = ("landed", "ended", "aborted", "upload_failed", "start_failed", "interrupted")


class FlightIn(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)

    plan_id: str = Field(max_length=40)
    bindings: dict[str, str] = Field(
        description="plan UAV id -> vehicle id, one vehicle per UAV",
        examples=[{"uav1": "3fa1b2c4d5e6"}],
    )
    altitude_m: float = Field(default=DEFAULT_ALTITUDE_M, gt=0, le=1000, description="above home")
    finish: Literal["land", "rtl"] = "land"
    max_speed_m_s: float = Field(
        default=DEFAULT_MAX_SPEED_M_S,
        gt=0,
        le=50,
        description="fly the plan no faster than this: the whole plan is slowed by one factor, "
        "keeping every relative position, so acceleration lag stays small",
    )
    turn_radius_m: float = Field(
        default=TURN_RADIUS_M, ge=0, le=50, description="waypoint acceptance radius"
    )


class AbortIn(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)

    mode: Literal["rtl", "land"] = "rtl"


class ObjectIn(BaseModel):
    """A non-UAV object (a bird, an aircraft) seen during the flight."""

    model_config = ConfigDict(extra="forbid", strict=True)

    cell: list[int] = Field(min_length=2, max_length=2, description="grid cell [x, y]")
    window: list[float] | None = Field(
        default=None,
        min_length=2,
        max_length=2,
        description="[t0, t1] on the flight's clock (`clock_s` of the live stream) while "
        "it is there; default: from now on",
    )


class ReplanOut(BaseModel):
    cell: list[int]
    window: list[float] | None
    plan_time_s: float = Field(description="the fleet's plan clock when it was reported")
    touched: list[str] = Field(description="UAVs whose remaining path the object touches")
    changed: list[str] = Field(description="UAVs given a new path and mission")
    unresolved: list[str] = Field(description="touched UAVs no safe path was found for")
    feasible: bool
    explanation: str
    uploads: list[VehicleAnswerOut]


class FlightOut(BaseModel):
    id: str
    plan_id: str
    state: str
    bindings: dict[str, str]
    options: dict[str, Any]
    created_at: UtcDatetime


class VehicleAnswerOut(BaseModel):
    uav_id: str
    vehicle_id: str
    ok: bool
    detail: str


class FlightAction(BaseModel):
    """The flight after an action, and what each vehicle did."""

    flight: FlightOut
    vehicles: list[VehicleAnswerOut]


class EventOut(BaseModel):
    id: int
    kind: str
    uav_id: str | None
    data: dict[str, Any]
    created_at: UtcDatetime


def _out(row: FlightRow) -> FlightOut:
    return FlightOut.model_validate(row, from_attributes=True)


def _action(services: ServicesDep, flight_id: str, answers: list[Any]) -> FlightAction:
    return FlightAction(
        flight=_out(services.flights.get(flight_id)),
        vehicles=[VehicleAnswerOut.model_validate(a, from_attributes=True) for a in answers],
    )


@router.post("", status_code=status.HTTP_201_CREATED, **mutating(ANSWERS))
def create_flight(flight: FlightIn, services: ServicesDep) -> FlightOut:
    """Bind every UAV of a feasible plan to a registered vehicle."""
    options = flight.model_dump(exclude={"plan_id", "bindings"})
    return _out(services.flight_service.create(flight.plan_id, flight.bindings, options))


@router.get("")
def list_flights(
    services: ServicesDep,
    limit: int = Query(default=100, ge=1, le=1000),
    offset: int = Query(default=0, ge=0, le=10**9),
) -> list[FlightOut]:
    return [_out(row) for row in services.flights.list(limit, offset)]


@router.get("/{flight_id}", responses=ANSWERS)
def get_flight(flight_id: str, services: ServicesDep) -> FlightOut:
    return _out(services.flights.get(flight_id))


@router.post("/{flight_id}/upload", **mutating(ANSWERS))
async def upload(flight_id: str, services: ServicesDep) -> FlightAction:
    """Upload every UAV's mission at once, each verified by reading it back."""
    answers = await services.flight_service.upload(flight_id)
    return _action(services, flight_id, answers)


@router.post("/{flight_id}/start", **mutating(ANSWERS))
async def start(flight_id: str, services: ServicesDep) -> FlightAction:
    """Arm, take off and hold every vehicle; when all hold, start every mission together.
    If one vehicle fails before the start, none starts."""
    answers = await services.flight_service.start(flight_id)
    return _action(services, flight_id, answers)


@router.post("/{flight_id}/pause", **mutating(ANSWERS))
async def pause(flight_id: str, services: ServicesDep) -> FlightAction:
    return _action(services, flight_id, await services.flight_service.pause(flight_id, True))


@router.post("/{flight_id}/continue", **mutating(ANSWERS))
async def resume(flight_id: str, services: ServicesDep) -> FlightAction:
    return _action(services, flight_id, await services.flight_service.pause(flight_id, False))


@router.post("/{flight_id}/abort", **mutating(ANSWERS))
async def abort(flight_id: str, request: AbortIn, services: ServicesDep) -> FlightAction:
    """Every vehicle returns to launch, or lands where it is."""
    answers = await services.flight_service.abort(flight_id, request.mode)
    return _action(services, flight_id, answers)


@router.post("/{flight_id}/objects", **mutating(ANSWERS))
async def report_object(flight_id: str, request: ObjectIn, services: ServicesDep) -> ReplanOut:
    """Report a non-UAV object during the flight: only the UAVs whose remaining path it
    touches are replanned (from where they are) and get a new mission; the answer says
    who changed and whether the whole fleet is still separated."""
    answer = await services.flight_service.report_object(
        flight_id,
        NewObject(
            (request.cell[0], request.cell[1]),
            (request.window[0], request.window[1]) if request.window else None,
        ),
    )
    return ReplanOut(**answer)


@router.get("/{flight_id}/events", responses=ANSWERS)
def events(
    flight_id: str,
    services: ServicesDep,
    after: int = Query(default=0, ge=0, le=2**62, description="only events after this id"),
    limit: int = Query(default=1000, ge=1, le=10_000),
) -> list[EventOut]:
    services.flights.get(flight_id)
    return [
        EventOut.model_validate(e, from_attributes=True)
        for e in services.flights.events(flight_id, after, limit)
    ]


@router.get("/{flight_id}/live-state", responses=ANSWERS)
def live_state(flight_id: str, services: ServicesDep) -> dict[str, Any]:
    """What the live stream sends as its periodic `state` message, once."""
    return services.flight_service.snapshot(flight_id)


@router.websocket("/{flight_id}/live")
async def live(websocket: WebSocket, flight_id: str) -> None:
    """`state` messages at the service's live rate (positions, modes, progress, schedule
    lag) and every fleet event as it happens, until the flight has ended."""
    services = get_services(websocket)
    await websocket.accept()
    flights = services.flight_service
    try:
        queue = flights.listen(flight_id)
    except LookupError as exc:
        await websocket.close(code=4404, reason=str(exc))
        return
    period = 1.0 / services.settings.live_rate_hz
    try:
        while True:
            snapshot = flights.snapshot(flight_id)
            await websocket.send_json(snapshot)
            if snapshot["state"] in ENDED and queue.empty():
                break
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(period):
                    while True:
                        await websocket.send_json(await queue.get())
        await websocket.close()
    except WebSocketDisconnect:
        pass
    finally:
        flights.unlisten(flight_id, queue)
