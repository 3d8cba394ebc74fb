"""Dependencies the routers ask for: each part of the service by itself, and the token check.

`Services` is built once in the app's lifespan; a router names only the parts it uses
(`ScenariosDep`, `FlightsDep`, `OperatorDep`, ...), as in FastAPI's full-stack template.
Every dependency is a coroutine: FastAPI runs a plain function in a worker thread, a
round trip through the thread pool per request for what is an attribute read.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import Depends
from starlette.requests import HTTPConnection

from gcs.fleet.crew import FleetSettings
from gcs.mavlink.transport import TransportOpener, open_transport
from gcs.service.api.auth import require_token
from gcs.service.api.live_sockets import LiveSockets
from gcs.service.api.schemas import Problem
from gcs.service.discovery import Discovery
from gcs.service.flights.book import FlightBook
from gcs.service.flights.control import FlightControl, holder_for
from gcs.service.flights.event_spill import EventSpill
from gcs.service.flights.event_writer import EventWriter
from gcs.service.flights.operator import OperatorCommands
from gcs.service.flights.service import FlightService
from gcs.service.loop_lag import LoopLagProbe
from gcs.service.metrics import ServiceMetrics
from gcs.service.mission_files import MissionFiles
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
from gcs.service.storage.leases import LeaseRepository
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
    flight_records: FlightRepository
    planning: PlanningService
    registry: VehicleRegistry
    events: EventWriter
    flights: FlightService
    operator: OperatorCommands
    loop_lag: LoopLagProbe
    discovery: Discovery | None
    live: LiveSockets
    missions: MissionFiles
    control: FlightControl

    @classmethod
    def build(
        cls, settings: Settings, db: Database, opener: TransportOpener = open_transport
    ) -> Services:
        metrics = ServiceMetrics()
        scenarios, plans, jobs = ScenarioRepository(db), PlanRepository(db), JobRepository(db)
        vehicles, flight_records = VehicleRepository(db), FlightRepository(db)
        discovery = discovery_for(settings, opener)
        registry = VehicleRegistry(metrics, discovery=discovery, opener=opener)
        spill = EventSpill(settings.data_dir / "event-spill.jsonl")
        events = EventWriter(flight_records, spill, metrics, settings.event_memory_rows)
        flights = FlightService(
            book=FlightBook(flight_records, events, registry.same_vehicles),
            plans=plans,
            scenarios=scenarios,
            vehicles=vehicles,
            registry=registry,
            metrics=metrics,
            fleet_settings=FleetSettings(
                fence_action=settings.fence_action, link_loss_brake_s=settings.link_loss_brake_s
            ),
        )
        operator = OperatorCommands(flights, registry)
        leases = LeaseRepository(db, holder_for(settings), settings.lease_s)
        control = FlightControl(
            leases, flights, operator, vehicles, registry, settings.lease_renew_s,
            resume_taken_over=settings.resume_taken_over,
        )  # fmt: skip
        flights.claim_control, flights.attach_vehicles = control.claim_for_upload, control.attach
        operator.require = control.require
        planning = PlanningService(scenarios, plans, jobs, metrics, claim=leases.claim_job)
        return cls(
            settings=settings,
            db=db,
            metrics=metrics,
            scenarios=scenarios,
            plans=plans,
            jobs=jobs,
            vehicles=vehicles,
            flight_records=flight_records,
            planning=planning,
            registry=registry,
            events=events,
            flights=flights,
            operator=operator,
            loop_lag=LoopLagProbe(metrics.loop_lag),
            discovery=discovery,
            live=LiveSockets(settings.max_live_sockets, settings.max_live_sockets_per_subject),
            missions=MissionFiles(plans, scenarios, metrics),
            control=control,
        )


def discovery_for(settings: Settings, opener: TransportOpener = open_transport) -> Discovery | None:
    """The listening port, if configured; beyond loopback only when that is allowed."""
    if not settings.discovery_url:
        return None
    discovery = Discovery(
        settings.discovery_url, opener=opener, forget_after_s=settings.discovery_forget_s
    )
    if not discovery.endpoint.is_loopback and not settings.listen_beyond_loopback:
        raise ValueError(
            f"discovery_url {settings.discovery_url} listens beyond this machine: set "
            "MVO_GCS_LISTEN_BEYOND_LOOPBACK=1 to allow it"
        )
    return discovery


def get_services(connection: HTTPConnection) -> Services:
    services: Services = connection.app.state.services
    return services


async def _services(connection: HTTPConnection) -> Services:
    return get_services(connection)


ServicesDep = Annotated[Services, Depends(_services)]


async def _settings(services: ServicesDep) -> Settings:
    return services.settings


async def _scenarios(services: ServicesDep) -> ScenarioRepository:
    return services.scenarios


async def _plans(services: ServicesDep) -> PlanRepository:
    return services.plans


async def _jobs(services: ServicesDep) -> JobRepository:
    return services.jobs


async def _vehicles(services: ServicesDep) -> VehicleRepository:
    return services.vehicles


async def _flight_records(services: ServicesDep) -> FlightRepository:
    return services.flight_records


async def _planning(services: ServicesDep) -> PlanningService:
    return services.planning


async def _registry(services: ServicesDep) -> VehicleRegistry:
    return services.registry


async def _flights(services: ServicesDep) -> FlightService:
    return services.flights


async def _operator(services: ServicesDep) -> OperatorCommands:
    return services.operator


async def _mission_files(services: ServicesDep) -> MissionFiles:
    return services.missions


async def _controlled(flight_id: str, services: ServicesDep) -> None:
    """409 naming the service that controls the flight, when it is another live one."""
    await services.control.require(flight_id)


SettingsDep = Annotated[Settings, Depends(_settings)]
ScenariosDep = Annotated[ScenarioRepository, Depends(_scenarios)]
PlansDep = Annotated[PlanRepository, Depends(_plans)]
JobsDep = Annotated[JobRepository, Depends(_jobs)]
VehiclesDep = Annotated[VehicleRepository, Depends(_vehicles)]
FlightRecordsDep = Annotated[FlightRepository, Depends(_flight_records)]
PlanningDep = Annotated[PlanningService, Depends(_planning)]
RegistryDep = Annotated[VehicleRegistry, Depends(_registry)]
FlightsDep = Annotated[FlightService, Depends(_flights)]
OperatorDep = Annotated[OperatorCommands, Depends(_operator)]
MissionFilesDep = Annotated[MissionFiles, Depends(_mission_files)]
Controlled = Depends(_controlled)
"""On a flight's route: refused (409) where another live service controls the flight."""

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
