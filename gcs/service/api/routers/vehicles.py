"""Vehicles: registered by connection string, listed with their live state."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Query, status
from pydantic import BaseModel, ConfigDict, Field, field_validator

from gcs.mavlink.errors import LinkError
from gcs.mavlink.transport import Endpoint
from gcs.service.api.deps import ServicesDep, mutating
from gcs.service.api.schemas import Problem, UtcDatetime
from gcs.service.storage.tables import VehicleRow

router = APIRouter(prefix="/vehicles", tags=["vehicles"])
NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": Problem}}


class VehicleIn(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)

    connection: str = Field(
        max_length=200,
        description="as pymavlink names it: udpout:HOST:PORT, udpin:HOST:PORT or tcp:HOST:PORT",
        examples=["udpout:127.0.0.1:14560"],
    )
    sysid: int | None = Field(
        default=None, ge=1, le=255, description="the autopilot's system id; default: first heard"
    )
    name: str | None = Field(default=None, max_length=100)

    @field_validator("connection")
    @classmethod
    def _parsable(cls, value: str) -> str:
        try:
            Endpoint.parse(value)
        except (LinkError, ValueError) as exc:
            raise ValueError(str(exc)) from None
        return value


class VehicleOut(BaseModel):
    id: str
    name: str
    connection: str
    sysid: int | None
    created_at: UtcDatetime
    live: dict[str, Any] = Field(description="the vehicle's state as last heard")


class AlreadyRegistered(Exception):
    pass


def _out(row: VehicleRow, services: ServicesDep) -> VehicleOut:
    return VehicleOut(
        id=row.id,
        name=row.name,
        connection=row.connection,
        sysid=row.sysid,
        created_at=row.created_at,
        live=services.registry.state(row.id),
    )


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    **mutating({409: {"model": Problem, "description": "already registered"}}),
)
async def register_vehicle(vehicle: VehicleIn, services: ServicesDep) -> VehicleOut:
    """Register a vehicle; the service connects (and reconnects) to it from now on."""
    if services.vehicles.by_connection(vehicle.connection) is not None:
        raise AlreadyRegistered(f"{vehicle.connection} is already registered")
    row = services.vehicles.add(
        VehicleRow(
            name=vehicle.name or vehicle.connection,
            connection=vehicle.connection,
            sysid=vehicle.sysid,
        )
    )
    services.registry.add(row.id, row.connection, row.sysid)
    return _out(row, services)


@router.get("")
def list_vehicles(
    services: ServicesDep,
    limit: int = Query(default=100, ge=1, le=1000),
    offset: int = Query(default=0, ge=0, le=10**9),
) -> list[VehicleOut]:
    return [_out(row, services) for row in services.vehicles.list(limit, offset)]


@router.get("/{vehicle_id}", responses=NOT_FOUND)
def get_vehicle(vehicle_id: str, services: ServicesDep) -> VehicleOut:
    return _out(services.vehicles.get(vehicle_id), services)


@router.delete("/{vehicle_id}", status_code=status.HTTP_204_NO_CONTENT, **mutating(NOT_FOUND))
async def delete_vehicle(vehicle_id: str, services: ServicesDep) -> None:
    services.vehicles.delete(vehicle_id)
    await services.registry.remove(vehicle_id)
