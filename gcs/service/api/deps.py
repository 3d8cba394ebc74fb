"""Dependencies the routers ask for: the service's parts and the token check."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import Depends
from starlette.requests import HTTPConnection

from gcs.service.api.auth import require_token
from gcs.service.api.schemas import Problem
from gcs.service.flight_service import FlightService
from gcs.service.metrics import ServiceMetrics
from gcs.service.planning import PlanningService
from gcs.service.settings import Settings
from gcs.service.storage import (
    Database,
    FlightRepository,
    JobRepository,
    PlanRepository,
    ScenarioRepository,
    VehicleRepository,
)
from gcs.service.vehicle_registry import VehicleRegistry


@dataclass
class Services:
    """The parts one service instance is made of; built once in the app's lifespan."""

    settings: Settings
    db: Database
    metrics: ServiceMetrics
    scenarios: ScenarioRepository
    plans: PlanRepository
    jobs: JobRepository
    vehicles: VehicleRepository
    flights: FlightRepository
    planning: PlanningService
    registry: VehicleRegistry
    flight_service: FlightService

    @classmethod
    def build(cls, settings: Settings, db: Database) -> Services:
        metrics = ServiceMetrics()
        scenarios, plans, jobs = ScenarioRepository(db), PlanRepository(db), JobRepository(db)
        vehicles, flights = VehicleRepository(db), FlightRepository(db)
        registry = VehicleRegistry(metrics)
        return cls(
            settings=settings,
            db=db,
            metrics=metrics,
            scenarios=scenarios,
            plans=plans,
            jobs=jobs,
            vehicles=vehicles,
            flights=flights,
            planning=PlanningService(scenarios, plans, jobs, metrics),
            registry=registry,
            flight_service=FlightService(
                plans=plans,
                scenarios=scenarios,
                flights=flights,
                vehicles=vehicles,
                registry=registry,
                metrics=metrics,
            ),
        )


def get_services(connection: HTTPConnection) -> Services:
    return connection.app.state.services


ServicesDep = Annotated[Services, Depends(get_services)]

_MUTATING_ANSWERS: dict[int | str, dict[str, Any]] = {
    400: {"model": Problem, "description": "the body could not be read"},
    401: {"model": Problem, "description": "no bearer token"},
    403: {"model": Problem, "description": "wrong bearer token"},
    413: {"model": Problem, "description": "the body is too large"},
    422: {"model": Problem, "description": "the request is invalid; `detail` says where"},
}


def mutating(responses: dict[int | str, dict[str, Any]] | None = None) -> dict[str, Any]:
    """Route options of an endpoint that changes state: the token check and its answers."""
    return {
        "dependencies": [Depends(require_token)],
        "responses": {**_MUTATING_ANSWERS, **(responses or {})},
    }
