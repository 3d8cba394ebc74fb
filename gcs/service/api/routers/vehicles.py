"""Vehicles: registered by connection string, listed with their live state, commanded one
at a time (hold, land, return to launch, continue), with or without a flight."""

from __future__ import annotations

from typing import Any, Literal

from fastapi import APIRouter, Query, status
from pydantic import BaseModel, ConfigDict, Field, field_validator
from sqlalchemy.exc import IntegrityError

from gcs.mavlink.connection import Signing
from gcs.mavlink.endpoint import Endpoint, EndpointError
from gcs.service.api.deps import (
    FlightsDep,
    OperatorDep,
    RegistryDep,
    SettingsDep,
    VehiclesDep,
    mutating,
)
from gcs.service.api.routers.flights import VehicleAnswerOut
from gcs.service.api.schemas import (
    LIVE,
    MAX_PAGE,
    Problem,
    UtcDatetime,
    VehicleLive,
    VehicleUnheard,
)
from gcs.service.states import StateConflict
from gcs.service.storage.tables import VehicleRow
from gcs.service.vehicle_registry import VehicleRegistry, describe

router = APIRouter(prefix="/vehicles", tags=["vehicles"])
NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": Problem}}
CONFLICT: dict[int | str, dict[str, Any]] = {
    409: {"model": Problem, "description": "offline, or not possible now (the message says)"}
}


class VehicleIn(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)

    connection: str = Field(
        max_length=200,
        description="as pymavlink names it: udpout:HOST:PORT, udpin:HOST:PORT or tcp:HOST:PORT "
        "(IPv6 in brackets); stored in canonical form",
        examples=["tcp:127.0.0.1:5760"],
    )
    sysid: int | None = Field(
        default=None, ge=1, le=255, description="the autopilot's system id; default: first heard"
    )
    name: str | None = Field(default=None, max_length=100)
    signing_key: str | None = Field(
        default=None,
        min_length=8,
        max_length=200,
        description="MAVLink 2 signing: 64 hex digits, or a passphrase (as MAVProxy's "
        "`signing setup`). Every packet to the vehicle is then signed and every unsigned "
        "or wrongly signed one from it dropped. Stored, never shown again.",
    )

    @field_validator("connection")
    @classmethod
    def _canonical(cls, value: str) -> str:
        try:
            return str(Endpoint.parse(value))
        except EndpointError as exc:
            raise ValueError(str(exc)) from None


class VehicleOut(BaseModel):
    id: str
    name: str
    connection: str
    sysid: int | None
    signed: bool = Field(description="MAVLink 2 signing is on for this vehicle")
    created_at: UtcDatetime
    live: VehicleLive | VehicleUnheard = Field(description="the vehicle's state as last heard")


class AlreadyRegistered(Exception):
    pass


class BadConnection(ValueError):
    """A connection string the service will not open (answered 422)."""


class DiscoveredOut(BaseModel):
    sysid: int
    connection: str = Field(description="register it with this and its sysid")
    vehicle_id: str | None = Field(description="the registered vehicle it is, if any")
    live: VehicleLive


def _out(row: VehicleRow, registry: VehicleRegistry) -> VehicleOut:
    return VehicleOut(
        id=row.id,
        name=row.name,
        connection=row.connection,
        sysid=row.sysid,
        signed=row.signing_key is not None,
        created_at=row.created_at,
        live=LIVE.validate_python(registry.state(row.id)),
    )


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    operation_id="registerVehicle",
    **mutating({409: {"model": Problem, "description": "already registered"}}),
)
async def register_vehicle(
    vehicle: VehicleIn, vehicles: VehiclesDep, registry: RegistryDep, settings: SettingsDep
) -> VehicleOut:
    """Register a vehicle; the service connects (and reconnects) to it from now on. One
    endpoint and system id is one vehicle, however its connection string is spelled."""
    endpoint = Endpoint.parse(vehicle.connection)
    if (
        endpoint.kind == "udpin"
        and not endpoint.is_loopback
        and not settings.listen_beyond_loopback
    ):
        raise BadConnection(
            f"{vehicle.connection} listens beyond this machine; the service listens on "
            "loopback only unless MVO_GCS_LISTEN_BEYOND_LOOPBACK is set"
        )
    resolved = str(await endpoint.resolved())
    shared = registry.discovery is not None and registry.discovery.serves(resolved)
    if vehicle.signing_key and shared:
        raise BadConnection(
            f"signing_key: {vehicle.connection} is the shared listening port, where the "
            "service neither signs nor checks signatures; register a signed vehicle on a "
            "connection of its own (its udpin: port, tcp: or udpout:)"
        )
    async with registry.registering:
        for spelling in dict.fromkeys((vehicle.connection, resolved)):
            existing = await vehicles.by_connection(spelling, vehicle.sysid)
            if existing is not None:
                raise AlreadyRegistered(
                    f"{vehicle.connection} (sysid {vehicle.sysid or 'any'}) is already "
                    f"registered as vehicle {existing.id} ({existing.connection})"
                )
        signing = Signing.from_text(vehicle.signing_key) if vehicle.signing_key else None
        same = await registry.registered_as(resolved, vehicle.sysid, signing)
        if same is not None:
            existing = await vehicles.get(same[0])
            raise AlreadyRegistered(
                f"{vehicle.connection} reaches vehicle {existing.id} ({same[1]}), already "
                f"registered as {existing.connection}: one vehicle is registered once"
            )
        row = VehicleRow(
            name=vehicle.name or vehicle.connection,
            connection=resolved,
            sysid=vehicle.sysid,
            signing_key=vehicle.signing_key,
        )
        try:
            await vehicles.add(row)
        except IntegrityError:
            raise AlreadyRegistered(f"{vehicle.connection} is already registered") from None
    registry.add(row.id, row.connection, row.sysid, _signing(row))
    return _out(row, registry)


def _signing(row: VehicleRow) -> Signing | None:
    return Signing.from_text(row.signing_key) if row.signing_key else None


@router.get("", operation_id="listVehicles")
async def list_vehicles(
    vehicles: VehiclesDep,
    registry: RegistryDep,
    limit: int = Query(default=50, ge=1, le=MAX_PAGE),
    offset: int = Query(default=0, ge=0, le=10**9),
) -> list[VehicleOut]:
    return [_out(row, registry) for row in await vehicles.page(limit, offset)]


@router.get("/discovered", operation_id="listDiscovered")
async def list_discovered(vehicles: VehiclesDep, registry: RegistryDep) -> list[DiscoveredOut]:
    """Every autopilot heard on the service's listening port (`discovery_url`), as
    QGroundControl would list them, whether registered or not."""
    discovery = registry.discovery
    if discovery is None:
        return []
    registered = {(row.connection, row.sysid): row.id for row in await vehicles.page(1000, 0)}
    return [
        DiscoveredOut(
            sysid=sysid,
            connection=discovery.url,
            vehicle_id=registered.get((discovery.url, sysid)),
            live=VehicleLive.model_validate(describe(link)),
        )
        for sysid, link in sorted(discovery.links.items())
    ]


@router.get("/{vehicle_id}", operation_id="getVehicle", responses=NOT_FOUND)
async def get_vehicle(vehicle_id: str, vehicles: VehiclesDep, registry: RegistryDep) -> VehicleOut:
    return _out(await vehicles.get(vehicle_id), registry)


@router.delete(
    "/{vehicle_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    operation_id="deleteVehicle",
    **mutating({**NOT_FOUND, **CONFLICT}),
)
async def delete_vehicle(
    vehicle_id: str, vehicles: VehiclesDep, registry: RegistryDep, flights: FlightsDep
) -> None:
    """Forget a vehicle (409 while an open flight owns it: it may be in the air)."""
    await vehicles.get(vehicle_id)
    async with flights.book.claims:  # no upload may claim it meanwhile
        owner = await flights.book.open_flight_of(vehicle_id)
        if owner is not None and vehicle_id in owner.bindings.values():
            raise StateConflict(
                f"vehicle {vehicle_id} belongs to flight {owner.id}, which is {owner.state}: "
                "it cannot be removed until that flight has ended"
            )
        await vehicles.delete(vehicle_id)
    await registry.remove(vehicle_id)


class AddressIn(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)

    address: str = Field(
        max_length=64,
        description="HOST:PORT (IPv6 in brackets), as the vehicle's `claimed_from` shows it",
        examples=["127.0.0.1:14551"],
    )


@router.post(
    "/{vehicle_id}/address",
    operation_id="moveVehicleAddress",
    **mutating({**NOT_FOUND, **CONFLICT}),
)
async def move_vehicle_address(
    vehicle_id: str, body: AddressIn, vehicles: VehiclesDep, registry: RegistryDep
) -> VehicleOut:
    """The vehicle now speaks from the address that has lately claimed its system id (its
    `claimed_from`), as after MAVProxy or a router restarted on a new port. A registered
    vehicle's address never moves otherwise, however long it is silent: another local
    program cannot take it over. 409 if that address did not claim it."""
    row = await vehicles.get(vehicle_id)
    registry.relock(vehicle_id, body.address)
    return _out(row, registry)


VehicleCommand = Literal["hold", "land", "rtl", "continue"]


@router.post(
    "/{vehicle_id}/{command}",
    operation_id="commandVehicle",
    **mutating({**NOT_FOUND, **CONFLICT}),
)
async def command_vehicle(
    vehicle_id: str, command: VehicleCommand, vehicles: VehiclesDep, operator: OperatorDep
) -> VehicleAnswerOut:
    """`hold` (stop where it is), `land`, `rtl` (return to launch) or `continue` (lift an
    operator's hold) for one vehicle, now. In a flight, the fleet knows: an operator's hold
    is never lifted by the schedule keeper, and a vehicle sent down or home leaves the plan
    while the others fly on."""
    await vehicles.get(vehicle_id)
    answer = await operator.vehicle(vehicle_id, command)
    return VehicleAnswerOut.model_validate(answer, from_attributes=True)
