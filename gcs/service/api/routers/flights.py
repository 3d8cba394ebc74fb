"""Flights: bind a plan's UAVs to vehicles, upload, start, hold, continue, abort, watch live.

Flight states and what each request may do in which: docs/service.md ("Flights").
"""

from __future__ import annotations

import asyncio
import contextlib
import json
from typing import Any, Literal

from fastapi import APIRouter, Query, WebSocket, status
from fastapi.responses import PlainTextResponse
from pydantic import BaseModel, ConfigDict, Field

from gcs.fleet.events import EventKind
from gcs.fleet.route_tracker import VehicleProgress
from gcs.mavlink.mission_item import Mission
from gcs.mission.files import parse_plan, plan_text, waypoints_text
from gcs.service.api.deps import (
    Controlled,
    FlightRecordsDep,
    FlightsDep,
    OperatorDep,
    get_services,
    mutating,
)
from gcs.service.api.live_sockets import send_until_done
from gcs.service.api.schemas import (
    MAX_PAGE,
    UNSAFE_SPEED,
    MissionShape,
    Problem,
    UtcDatetime,
    VehicleLive,
    VehicleUnheard,
)
from gcs.service.flights.active import VehicleAnswer
from gcs.service.flights.live_queue import LiveQueue
from gcs.service.flights.service import FlightService
from gcs.service.states import FlightState, StateConflict
from gcs.service.storage import NotFound
from gcs.service.storage.tables import FlightRow
from planner.live.replan import NewObject

router = APIRouter(prefix="/flights", tags=["flights"])
ANSWERS: dict[int | str, dict[str, Any]] = {
    404: {"model": Problem, "description": "no such flight, plan or vehicle"},
    409: {
        "model": Problem,
        "description": "not possible in the flight's state (the message says why), a vehicle "
        "that belongs to another open flight, or a vehicle that is offline",
    },
}


def _controlled(responses: dict[int | str, dict[str, Any]]) -> dict[str, Any]:
    """A mutating route on one flight, refused (409) where another live service controls
    it (several services on one database: docs/service.md, "Scaling out")."""
    options = mutating(responses)
    options["dependencies"] = [*options["dependencies"], Controlled]
    return options


def _links(*operations: str) -> dict[str, dict[str, Any]]:
    """OpenAPI links from an answer carrying a flight to the operations on that flight."""
    return {
        op: {"operationId": op, "parameters": {"flight_id": "$response.body#/id"}}
        for op in operations
    }


FLIGHT_OPERATIONS = (
    "getFlight",
    "uploadFlight",
    "startFlight",
    "pauseFlight",
    "continueFlight",
    "resumeFlight",
    "abortFlight",
    "cancelFlight",
    "reportObject",
    "flightEvents",
    "flightLiveState",
    "deleteFlight",
)


class FlightIn(MissionShape):
    model_config = ConfigDict(extra="forbid", strict=True)

    plan_id: str = Field(max_length=40)
    bindings: dict[str, str] = Field(
        description="plan UAV id -> vehicle id, one vehicle per UAV",
        examples=[{"uav1": "3fa1b2c4d5e6"}],
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


class VehicleAnswerOut(BaseModel):
    uav_id: str
    vehicle_id: str
    ok: bool
    detail: str
    seconds: float | None = Field(
        default=None, description="from the request to the vehicle's answer"
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
    paths: dict[str, list[list[float]]] = Field(
        description="each changed UAV's new path, [t, x, y] in cells and in the plan's own "
        "seconds (the flight's clock divided by its pace factor)"
    )
    uploads: list[VehicleAnswerOut]


class FlightOut(BaseModel):
    id: str
    plan_id: str
    state: FlightState
    open: bool = Field(description="owns its vehicles: from upload until all are down")
    note: str = Field(description="why the flight is in its state, when it says more")
    bindings: dict[str, str]
    options: dict[str, Any]
    created_at: UtcDatetime


class FlightAction(BaseModel):
    """The flight after an action, and what each vehicle did."""

    flight: FlightOut
    vehicles: list[VehicleAnswerOut]


class EventOut(BaseModel):
    """One stored event: `data` is the event as the live stream sent it (with `type`,
    `kind` and, for a fleet event, `at`, the loop time it happened)."""

    id: int
    kind: EventKind | str  # one this version does not know (a newer service's) as it is
    uav_id: str | None
    data: dict[str, Any]
    created_at: UtcDatetime


class _Bound(BaseModel):
    uav_id: str
    vehicle_id: str


PROGRESS = Field(
    default=None,
    description="where it is on its plan; absent while the service follows no fleet for "
    "the flight (before its upload, after a restart)",
)


class FlightVehicleLive(VehicleLive, _Bound):
    """A vehicle of the flight: the UAV it flies, its live state and its progress."""

    progress: VehicleProgress | None = PROGRESS


class FlightVehicleUnheard(VehicleUnheard, _Bound):
    """A vehicle of the flight that the service has no link to."""

    progress: VehicleProgress | None = PROGRESS


class FlightLiveState(BaseModel):
    """The live stream's periodic `state` message (`GET /flights/{id}/live-state`: once)."""

    type: Literal["state"]
    flight_id: str
    state: FlightState
    pace_factor: float | None = Field(
        description="the flight's seconds per second of the plan; null when no fleet is "
        "followed for it"
    )
    min_separation_m: float | None = Field(
        description="the least distance between two of its vehicles so far, from telemetry"
    )
    vehicles: list[FlightVehicleLive | FlightVehicleUnheard]


def flight_out(row: FlightRow) -> FlightOut:
    state = FlightState(row.state)
    return FlightOut(
        id=row.id,
        plan_id=row.plan_id,
        state=state,
        open=state.is_open,
        note=row.note or "",
        bindings=row.bindings,
        options=row.options,
        created_at=row.created_at,
    )


async def _action(
    flights: FlightsDep, flight_id: str, answers: list[VehicleAnswer]
) -> FlightAction:
    return FlightAction(
        flight=flight_out(await flights.book.row(flight_id)),
        vehicles=[VehicleAnswerOut.model_validate(a, from_attributes=True) for a in answers],
    )


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    operation_id="createFlight",
    **mutating({**ANSWERS, **UNSAFE_SPEED, 201: {"links": _links(*FLIGHT_OPERATIONS)}}),
)
async def create_flight(flight: FlightIn, flights: FlightsDep) -> FlightOut:
    """Bind every UAV of a feasible plan to a registered vehicle."""
    options = flight.model_dump(exclude={"plan_id", "bindings"})
    return flight_out(await flights.create(flight.plan_id, flight.bindings, options))


@router.get("", operation_id="listFlights")
async def list_flights(
    records: FlightRecordsDep,
    limit: int = Query(default=50, ge=1, le=MAX_PAGE),
    offset: int = Query(default=0, ge=0, le=10**9),
    open: bool = Query(default=False, description="only the open ones (all of them)"),
) -> list[FlightOut]:
    """Oldest first; `?open=true`: every flight that may have vehicles in the air."""
    rows = await records.open_flights() if open else await records.page(limit, offset)
    return [flight_out(row) for row in rows]


@router.get("/{flight_id}", operation_id="getFlight", responses=ANSWERS)
async def get_flight(flight_id: str, flights: FlightsDep) -> FlightOut:
    return flight_out(await flights.book.row(flight_id))


@router.post(
    "/{flight_id}/upload", operation_id="uploadFlight", **_controlled({**ANSWERS, **UNSAFE_SPEED})
)
async def upload(flight_id: str, flights: FlightsDep) -> FlightAction:
    """Upload every UAV's mission at once, each verified by reading it back. From now on the
    vehicles belong to this flight, until it has ended with all of them on the ground.
    Refused (409) while a vehicle is armed, in the air, offline or owned by another flight."""
    return await _action(flights, flight_id, await flights.upload(flight_id))


@router.post(
    "/{flight_id}/start",
    status_code=status.HTTP_202_ACCEPTED,
    operation_id="startFlight",
    **_controlled(ANSWERS),
)
async def start(flight_id: str, flights: FlightsDep) -> FlightOut:
    """Arm, take off and hold every vehicle over its start; when all hold, start every
    mission together. Answered at once with the flight `starting` (arming can take a minute
    on a real autopilot); the flight becomes `flying`, then `landed`. If one vehicle fails
    before the start, none starts."""
    return flight_out(await flights.start(flight_id))


@router.post("/{flight_id}/pause", operation_id="pauseFlight", **_controlled(ANSWERS))
async def pause(flight_id: str, flights: FlightsDep, operator: OperatorDep) -> FlightAction:
    """The operator's fleet hold: every vehicle stops where it is until `/continue` (the
    passing order never lifts it). During the start it cancels the start."""
    return await _action(flights, flight_id, await operator.hold(flight_id))


@router.post("/{flight_id}/continue", operation_id="continueFlight", **_controlled(ANSWERS))
async def continue_flight(
    flight_id: str, flights: FlightsDep, operator: OperatorDep
) -> FlightAction:
    """Lift the operator's hold on every vehicle of a paused (or flying) flight."""
    return await _action(flights, flight_id, await operator.continue_(flight_id))


@router.post("/{flight_id}/resume", operation_id="resumeFlight", **_controlled(ANSWERS))
async def resume(flight_id: str, flights: FlightsDep, operator: OperatorDep) -> FlightAction:
    """Follow an interrupted flight again (its service restarted, or another took it
    over): each vehicle still in the plan is stopped where it is, then let go in the
    passing order, and the flight is `flying` again. Refused (409) while a vehicle is not
    heard or holds another mission than this flight's (a live replan)."""
    return await _action(flights, flight_id, await operator.resume(flight_id))


@router.post("/{flight_id}/abort", operation_id="abortFlight", **_controlled(ANSWERS))
async def abort(
    flight_id: str, request: AbortIn, flights: FlightsDep, operator: OperatorDep
) -> FlightAction:
    """Every vehicle returns to launch, or lands where it is, at once: whatever the flight
    is doing (uploading, arming, flying) is cancelled first. Accepted in every open state;
    the flight is `aborting` until every vehicle is down, then `aborted`."""
    answers = await operator.abort(flight_id, request.mode)
    return await _action(flights, flight_id, answers)


@router.post("/{flight_id}/cancel", operation_id="cancelFlight", **_controlled(ANSWERS))
async def cancel(flight_id: str, flights: FlightsDep) -> FlightOut:
    """Release the vehicles of a flight that has not started (created, uploaded)."""
    return flight_out(await flights.cancel(flight_id))


@router.post("/{flight_id}/objects", operation_id="reportObject", **_controlled(ANSWERS))
async def report_object(flight_id: str, request: ObjectIn, flights: FlightsDep) -> ReplanOut:
    """Report a non-UAV object during the flight: only the UAVs whose remaining path it
    touches are replanned (from where they are) and get a new mission; the answer says
    who changed and whether the whole fleet is still separated."""
    answer = await flights.report_object(
        flight_id,
        NewObject(
            (request.cell[0], request.cell[1]),
            (request.window[0], request.window[1]) if request.window else None,
        ),
    )
    return ReplanOut(**answer)


@router.get("/{flight_id}/events", operation_id="flightEvents", responses=ANSWERS)
async def events(
    flight_id: str,
    flights: FlightsDep,
    after: int = Query(default=0, ge=0, le=2**62, description="only events after this id"),
    limit: int = Query(default=1000, ge=1, le=10_000),
) -> list[EventOut]:
    """The flight's stored events, oldest first: at most `limit` with ids after `after`.
    A flight can store more than a page holds; ask again after the last id until a page
    comes back short."""
    await flights.book.row(flight_id)
    rows = await flights.book.flights.events(flight_id, after, limit)
    return [EventOut.model_validate(e, from_attributes=True) for e in rows]


@router.get(
    "/{flight_id}/live-state",
    operation_id="flightLiveState",
    response_model=FlightLiveState,
    response_model_exclude_unset=True,  # a vehicle's progress is absent, not null, without one
    responses=ANSWERS,
    dependencies=[Controlled],
)
async def live_state(flight_id: str, flights: FlightsDep) -> dict[str, Any]:
    """What the live stream sends as its periodic `state` message, once."""
    return await flights.snapshot(flight_id)


MissionFormat = Literal["plan", "waypoints"]


@router.get(
    "/{flight_id}/missions/{uav_id}.{extension}",
    operation_id="flightMissionFile",
    response_model=None,
    responses={
        **ANSWERS,
        200: {
            "description": "the mission as uploaded to the vehicle: a QGroundControl `.plan` "
            "(JSON) or a `QGC WPL 110` `.waypoints` file",
            "content": {"text/plain": {"schema": {"type": "string"}}},
        },
    },
)
async def flight_mission_file(
    flight_id: str, uav_id: str, extension: MissionFormat, records: FlightRecordsDep
) -> PlainTextResponse:
    """The mission this flight last uploaded to the UAV's vehicle, exactly as sent."""
    uploads = [u for u in await records.uploads(flight_id) if u.uav_id == uav_id and u.mission]
    if not uploads:
        await records.get(flight_id)
        raise NotFound(f"upload of flight {flight_id} for UAV", uav_id)
    document = uploads[-1].mission
    mission = parse_plan_document(document)
    if extension == "plan":
        notes = (document or {}).get("notes")
        return _attachment(plan_text(mission, notes), f"{uav_id}.plan", "application/json")
    return _attachment(waypoints_text(mission), f"{uav_id}.waypoints", "text/plain")


def parse_plan_document(document: dict[str, Any] | None) -> Mission:
    return parse_plan(json.dumps(document), source="stored upload")


def _attachment(text: str, name: str, media_type: str) -> PlainTextResponse:
    return PlainTextResponse(
        text,
        media_type=media_type,
        headers={"Content-Disposition": f'attachment; filename="{name}"'},
    )


@router.delete(
    "/{flight_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    operation_id="deleteFlight",
    **mutating(ANSWERS),
)
async def delete_flight(flight_id: str, flights: FlightsDep) -> None:
    """Delete a flight that has ended, with its events and uploads (409 while open)."""
    await flights.delete(flight_id)


@router.websocket("/{flight_id}/live")
async def live(websocket: WebSocket, flight_id: str) -> None:
    """`state` messages at the service's live rate (positions, modes, progress, schedule
    lag) and every fleet event as it happens, until the flight has ended. The socket only
    sends: a client message closes it (1008); beyond the service's caps it is closed at
    once (1013)."""
    services = get_services(websocket)
    async with services.live.admitted(websocket, f"flight {flight_id}") as admitted:
        if not admitted:
            return
        flights = services.flights
        try:
            await services.control.require(flight_id)
        except StateConflict as exc:
            await websocket.close(code=4409, reason=str(exc)[:120])
            return
        try:
            queue = await flights.listen(flight_id)
        except LookupError as exc:
            await websocket.close(code=4404, reason=str(exc))
            return
        try:
            await send_until_done(websocket, _stream(websocket, flights, flight_id, queue))
        finally:
            flights.unlisten(flight_id, queue)


async def _stream(
    websocket: WebSocket, flights: FlightService, flight_id: str, queue: LiveQueue
) -> None:
    period = 1.0 / get_services(websocket).settings.live_rate_hz
    while True:
        snapshot = await flights.snapshot(flight_id)
        await websocket.send_json(snapshot)
        if FlightState(snapshot["state"]).is_final and queue.empty():
            break
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(period):
                while True:
                    await websocket.send_json(await queue.get())
    await websocket.close()
