"""What only lives while the service runs, for a flight uploaded in this run: its `Fleet`
and the plan as flown."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from gcs.fleet.events import FleetEvent
from gcs.fleet.fleet import Fleet
from gcs.mavlink.mission_item import Mission
from planner.live.replan import NewObject
from planner.model.plan import Plan
from planner.model.scenario import Scenario

LISTENER_QUEUE = 1000  # live messages kept for one slow client (the default)


@dataclass(frozen=True)
class VehicleAnswer:
    """What one vehicle did about a request, and how long after the request it answered."""

    uav_id: str
    vehicle_id: str
    ok: bool
    detail: str
    seconds: float | None = None


@dataclass
class ActiveFlight:
    flight_id: str
    fleet: Fleet
    scenario: Scenario  # as flown: speeds divided by the pace factor
    plan: Plan  # as flown: times multiplied by the pace factor
    missions: dict[str, Mission]
    vehicles: dict[str, str]  # uav id -> vehicle id
    options: dict[str, Any]
    pace_factor: float  # the flight's clock runs this much slower than the plan's
    objects: list[NewObject] = field(default_factory=list)  # reported during the flight

    def uav_of(self, vehicle_id: str) -> str | None:
        return next((uav for uav, vid in self.vehicles.items() if vid == vehicle_id), None)


def event_json(event: FleetEvent) -> dict[str, Any]:
    return {"type": "event", "kind": event.kind, **dataclasses.asdict(event)}
