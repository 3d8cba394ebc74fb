"""Flights: a plan bound to vehicles, uploaded, started, followed, recorded and streamed.

A flight's record (its bindings, state, uploads and events) is in storage; what only
lives while the service runs (the `Fleet` talking to the vehicles, the task following
it, the live listeners) is an `ActiveFlight`. After a restart a flight that was in the
air is `interrupted` and has to be uploaded again before it can start.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
from dataclasses import dataclass, field
from typing import Any

from gcs.fleet.events import FleetEvent, Progress
from gcs.fleet.fleet import Fleet, FleetSettings, VehicleOutcome
from gcs.mavlink.mission_item import Mission
from gcs.mission.pacing import paced_flight
from gcs.service.live_replanning import replan_flight
from gcs.service.metrics import ServiceMetrics
from gcs.service.storage import (
    FlightRepository,
    PlanRepository,
    ScenarioRepository,
    VehicleRepository,
)
from gcs.service.storage.tables import FlightRow, UploadRow
from gcs.service.vehicle_registry import VehicleRegistry
from planner.live_replan import NewObject
from planner.plan import Plan
from planner.scenario import Scenario

log = logging.getLogger("mvo_gcs.flights")


class FlightConflict(Exception):
    """The flight is not in a state that allows the request; answered 409."""


class BadObject(ValueError):
    """A reported object the planner cannot place (outside the grid, bad window); 422."""


class BadBindings(ValueError):
    """The bindings do not pair the plan's UAVs with vehicles one to one; answered 422."""


@dataclass(frozen=True)
class VehicleAnswer:
    uav_id: str
    vehicle_id: str
    ok: bool
    detail: str


@dataclass
class ActiveFlight:
    row_id: str
    fleet: Fleet
    scenario: Scenario
    plan: Plan
    missions: dict[str, Mission]
    vehicles: dict[str, str]  # uav id -> vehicle id
    options: dict[str, Any]
    pace_factor: float  # the flight's clock runs this much slower than the plan's
    objects: list[NewObject] = field(default_factory=list)  # reported during the flight
    listeners: set[asyncio.Queue[dict[str, Any]]] = field(default_factory=set)
    tasks: set[asyncio.Task[Any]] = field(default_factory=set)
    last_progress: Progress | None = None


class FlightService:
    def __init__(
        self,
        *,
        plans: PlanRepository,
        scenarios: ScenarioRepository,
        flights: FlightRepository,
        vehicles: VehicleRepository,
        registry: VehicleRegistry,
        metrics: ServiceMetrics,
        fleet_settings: FleetSettings | None = None,
    ) -> None:
        self.plans, self.scenarios, self.flights = plans, scenarios, flights
        self.vehicles, self.registry, self.metrics = vehicles, registry, metrics
        self.fleet_settings = fleet_settings or FleetSettings()
        self.active: dict[str, ActiveFlight] = {}

    # --- creating --------------------------------------------------------------------

    def create(self, plan_id: str, bindings: dict[str, str], options: dict[str, Any]) -> FlightRow:
        """Bind every UAV of a feasible plan to a distinct registered vehicle."""
        plan = Plan(**self.plans.get(plan_id).body)
        if not plan.feasible:
            raise FlightConflict(f"plan {plan_id} is infeasible: it is not safe to fly")
        uavs = {u.id for u in plan.uavs}
        missing, extra = sorted(uavs - set(bindings)), sorted(set(bindings) - uavs)
        if missing or extra:
            raise BadBindings(
                f"bindings must name every UAV of the plan exactly: missing {missing}, "
                f"not in the plan {extra}"
            )
        if len(set(bindings.values())) != len(bindings):
            raise BadBindings("bindings: each UAV needs its own vehicle")
        for vehicle_id in bindings.values():
            self.vehicles.get(vehicle_id)
        return self.flights.add(FlightRow(plan_id=plan_id, bindings=bindings, options=options))

    # --- upload, start, pause, abort ---------------------------------------------------

    async def upload(self, flight_id: str) -> list[VehicleAnswer]:
        row = self.flights.get(flight_id)
        if row.state in ("starting", "flying", "paused"):
            raise FlightConflict(f"flight {flight_id} is {row.state}: abort it first")
        links = {uav: self.registry.link(vid) for uav, vid in row.bindings.items()}
        plan_row = self.plans.get(row.plan_id)
        paced = paced_flight(
            Plan(**plan_row.body),
            Scenario(**self.scenarios.get(plan_row.scenario_id).body),
            {uav: link.autopilot for uav, link in links.items()},
            **row.options,
        )
        missions = paced.missions
        await self._retire(flight_id)
        fleet = Fleet(links, missions, settings=self.fleet_settings)
        active = ActiveFlight(
            flight_id,
            fleet,
            paced.scenario,
            paced.plan,
            missions,
            dict(row.bindings),
            dict(row.options),
            paced.factor,
        )
        self.active[flight_id] = active
        self._spawn(active, self._record(active))
        self._set_state(flight_id, "uploading")
        outcomes = await fleet.upload()
        for uav, outcome in outcomes.items():
            self.metrics.uploads.labels("ok" if outcome.ok else "failed").inc()
            if outcome.value is not None:
                self.metrics.upload_retries.inc(outcome.value.resends)
            self.flights.record_upload(
                UploadRow(
                    flight_id=flight_id,
                    uav_id=uav,
                    vehicle_id=row.bindings[uav],
                    ok=outcome.ok,
                    items=len(missions[uav]),
                    detail=outcome.detail,
                )
            )
        ok = all(o.ok for o in outcomes.values())
        self._set_state(flight_id, "uploaded" if ok else "upload_failed")
        return self._answers(active, outcomes)

    async def start(self, flight_id: str) -> list[VehicleAnswer]:
        """Arm, take off and hold every vehicle, then start them all together."""
        row = self.flights.get(flight_id)
        active = self.active.get(flight_id)
        if row.state != "uploaded" or active is None:
            raise FlightConflict(
                f"flight {flight_id} is {row.state}: upload its missions first"
                if row.state != "uploaded"
                else f"flight {flight_id}: the service restarted since the upload; upload again"
            )
        self._set_state(flight_id, "starting")
        outcomes = await active.fleet.prepare()
        if all(o.ok for o in outcomes.values()):
            outcomes = await active.fleet.start()
        if not all(o.ok for o in outcomes.values()):
            self._set_state(flight_id, "start_failed")
            return self._answers(active, outcomes)
        self._set_state(flight_id, "flying")
        self._spawn(active, self._follow(active))
        return self._answers(active, outcomes)

    async def pause(self, flight_id: str, paused: bool) -> list[VehicleAnswer]:
        active = self._flying(flight_id)
        fleet = active.fleet
        outcomes = await (fleet.pause() if paused else fleet.resume())
        self._set_state(flight_id, "paused" if paused else "flying")
        return self._answers(active, outcomes)

    async def abort(self, flight_id: str, mode: str) -> list[VehicleAnswer]:
        active = self._flying(flight_id)
        outcomes = await active.fleet.abort(mode)
        self._set_state(flight_id, "aborted")
        return self._answers(active, outcomes)

    async def report_object(self, flight_id: str, new_object: NewObject) -> dict[str, Any]:
        """The wormhole step, live: replan and re-upload only the UAVs the object touches."""
        active = self._flying(flight_id)
        try:
            outcome = await replan_flight(
                active.fleet,
                active.scenario,
                active.plan,
                new_object,
                list(active.objects),
                altitude_m=active.options["altitude_m"],
                finish=active.options["finish"],
                turn_radius_m=active.options["turn_radius_m"],
            )
        except ValueError as exc:  # the planner's verdict on the object itself
            raise BadObject(str(exc)) from exc
        active.objects.append(new_object)
        active.plan = outcome.plan
        result = outcome.result
        self.metrics.replans.labels("feasible" if result.feasible else "unresolved").inc()
        answer = {
            "cell": list(new_object.cell),
            "window": list(new_object.window) if new_object.window else None,
            "plan_time_s": result.now,
            "touched": result.touched,
            "changed": sorted(result.changed),
            "unresolved": result.unresolved,
            "feasible": result.feasible,
            "explanation": result.explanation,
            "uploads": [
                {"uav_id": u, "vehicle_id": active.vehicles[u], "ok": o.ok, "detail": o.detail}
                for u, o in sorted(outcome.uploads.items())
            ],
        }
        self.flights.record_event(flight_id, "ObjectReported", {"type": "event", **answer})
        return answer

    # --- live ----------------------------------------------------------------------------

    def snapshot(self, flight_id: str) -> dict[str, Any]:
        """Every bound vehicle's position, mode, progress and schedule lag, now."""
        row = self.flights.get(flight_id)
        active = self.active.get(flight_id)
        progress = {p.uav_id: p for p in active.fleet.progress()} if active else {}
        vehicles = []
        for uav, vehicle_id in row.bindings.items():
            entry = {"uav_id": uav, "vehicle_id": vehicle_id, **self.registry.state(vehicle_id)}
            if uav in progress:
                entry["progress"] = dataclasses.asdict(progress[uav])
            vehicles.append(entry)
        separation = active.fleet.min_separation_m if active else None
        return {
            "type": "state",
            "flight_id": flight_id,
            "state": row.state,
            "pace_factor": active.pace_factor if active else None,
            "min_separation_m": separation,
            "vehicles": vehicles,
        }

    def listen(self, flight_id: str) -> asyncio.Queue[dict[str, Any]]:
        self.flights.get(flight_id)
        queue: asyncio.Queue[dict[str, Any]] = asyncio.Queue(maxsize=1000)
        active = self.active.get(flight_id)
        if active is not None:
            active.listeners.add(queue)
        return queue

    def unlisten(self, flight_id: str, queue: asyncio.Queue[dict[str, Any]]) -> None:
        active = self.active.get(flight_id)
        if active is not None:
            active.listeners.discard(queue)

    async def close(self) -> None:
        for flight_id in list(self.active):
            await self._retire(flight_id)

    # --- inside ----------------------------------------------------------------------------

    def _flying(self, flight_id: str) -> ActiveFlight:
        row = self.flights.get(flight_id)
        active = self.active.get(flight_id)
        if row.state not in ("flying", "paused") or active is None:
            raise FlightConflict(f"flight {flight_id} is {row.state}, not flying")
        return active

    async def _follow(self, active: ActiveFlight) -> None:
        report = await active.fleet.follow()
        row = self.flights.get(active.row_id)
        if row.state in ("flying", "paused"):
            self._set_state(active.row_id, "landed" if report.completed else "ended")

    async def _record(self, active: ActiveFlight) -> None:
        """Store every event but the periodic progress, and pass all of them on live."""
        async for event in active.fleet.events():
            message = event_json(event)
            if isinstance(event, Progress):
                active.last_progress = event
            else:
                self.flights.record_event(
                    active.row_id, message["kind"], message, message.get("uav_id")
                )
            for queue in list(active.listeners):
                if queue.full():
                    queue.get_nowait()
                queue.put_nowait(message)

    def _set_state(self, flight_id: str, state: str) -> None:
        self.flights.update(flight_id, state=state)
        message = {"type": "event", "kind": "FlightState", "state": state}
        self.flights.record_event(flight_id, "FlightState", message)
        active = self.active.get(flight_id)
        for queue in list(active.listeners) if active else ():
            if not queue.full():
                queue.put_nowait(message)

    def _spawn(self, active: ActiveFlight, coro: Any) -> None:
        task = asyncio.create_task(coro)
        active.tasks.add(task)
        task.add_done_callback(lambda t: _log_failure(active, t))

    async def _retire(self, flight_id: str) -> None:
        active = self.active.pop(flight_id, None)
        if active is None:
            return
        for task in active.tasks:
            task.cancel()
        for task in list(active.tasks):
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task

    def _answers(
        self, active: ActiveFlight, outcomes: dict[str, VehicleOutcome[Any]]
    ) -> list[VehicleAnswer]:
        return [
            VehicleAnswer(uav, active.vehicles[uav], o.ok, o.detail)
            for uav, o in sorted(outcomes.items())
        ]


def _log_failure(active: ActiveFlight, task: asyncio.Task[Any]) -> None:
    active.tasks.discard(task)
    if not task.cancelled() and task.exception() is not None:
        log.error("flight %s: %r", active.row_id, task.exception())


def event_json(event: FleetEvent) -> dict[str, Any]:
    return {"type": "event", "kind": type(event).__name__, **dataclasses.asdict(event)}
