"""Flights: a plan bound to vehicles, uploaded, started, followed, recorded and streamed.

A flight's record (bindings, state, uploads, events) is in storage; what lives only
while the service runs (the `Fleet`, the runner following the flight, the listeners)
is its `ActiveFlight`. Upload answers when every mission is verified or refused (its
waits are bounded by the mission protocol's); start answers at once with the flight
`starting`, and the runner arms, lines up, starts and follows the fleet, ending the
flight `landed` (or `ended`, `interrupted`) on its own. The operator's commands are in
`operator.py`; they pre-empt everything here.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import functools
import logging
from collections.abc import Awaitable, Callable, Iterable
from typing import Any

from gcs.fleet.crew import FleetSettings
from gcs.fleet.events import EventKind, FleetEvent, FlightOutcome, Progress
from gcs.fleet.fleet import Fleet
from gcs.fleet.outcome import VehicleOutcome
from gcs.fleet.vehicle_limits import read_limits
from gcs.mavlink.actions import FlightActions
from gcs.mavlink.errors import GcsError
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Autopilot
from gcs.mavlink.mission_protocol import MissionClient, first_mismatch
from gcs.mission.build import takeoff_index
from gcs.mission.fence import FencePlan, fence_of
from gcs.mission.files import plan_document
from gcs.mission.flight_plan import FlightPlan, flight_plan
from gcs.mission.flight_timing import FlightStuck
from gcs.mission.geographic import load_geographic
from gcs.service.flights.active import ActiveFlight, VehicleAnswer, event_json
from gcs.service.flights.book import FlightBook
from gcs.service.flights.live_queue import LiveQueue
from gcs.service.flights.slot import Preempted
from gcs.service.live_replanning import replan_flight
from gcs.service.metrics import ServiceMetrics
from gcs.service.states import FlightState, StateConflict
from gcs.service.storage import PlanRepository, ScenarioRepository, VehicleRepository
from gcs.service.storage.tables import FlightRow, UploadRow
from gcs.service.vehicle_registry import VehicleRegistry
from planner.live.replan import NewObject
from planner.model.plan import Plan
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory

log = logging.getLogger("mvo_gcs.flights")
F = FlightState
TRACK_PERIOD_S = 1.0  # wall seconds between stored positions (the flown tracks)
FOLLOWED = frozenset({F.STARTING, F.FLYING, F.PAUSED})
"""States in which the vehicles fly the plan, in its order, as the service follows them."""
HOLD_ON_STOP_S = 3.0  # how long a stopping service tries to hold each airborne vehicle


class BadObject(ValueError):
    """A reported object the planner cannot place (outside the grid, bad window); 422."""


class BadBindings(ValueError):
    """The bindings do not pair the plan's UAVs with vehicles one to one; answered 422."""


def _require_origin(scenario: Scenario, scenario_id: str, what: str) -> None:
    if scenario.origin is None:
        raise StateConflict(
            f"{what}: scenario {scenario_id} has no origin (latitude, longitude, altitude "
            "of cell 0, 0), so its plan cannot be flown; give it one"
        )


class FlightService:
    def __init__(
        self,
        *,
        book: FlightBook,
        plans: PlanRepository,
        scenarios: ScenarioRepository,
        vehicles: VehicleRepository,
        registry: VehicleRegistry,
        metrics: ServiceMetrics,
        fleet_settings: FleetSettings | None = None,
    ) -> None:
        self.book, self.plans, self.scenarios = book, plans, scenarios
        self.vehicles, self.registry, self.metrics = vehicles, registry, metrics
        self.fleet_settings = fleet_settings or FleetSettings()
        self.claim_control: Callable[[str], Awaitable[None]] = _claim_nothing
        """Makes the flight this service's before its upload (FlightControl's claim)."""
        self.attach_vehicles: Callable[[Iterable[str]], Awaitable[None]] = _claim_nothing
        """Adds vehicles registered on another service sharing the database."""

    # --- creating ----------------------------------------------------------------------

    async def create(
        self, plan_id: str, bindings: dict[str, str], options: dict[str, Any]
    ) -> FlightRow:
        """Bind every UAV of a feasible plan to a distinct registered vehicle, at a speed the
        ground station can keep safe for that plan (UnsafeSpeed otherwise: nothing made)."""
        plan_row = await self.plans.get(plan_id)
        plan = Plan(**plan_row.body)
        if not plan.feasible:
            raise StateConflict(f"plan {plan_id} is infeasible: it is not safe to fly")
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
            await self.vehicles.get(vehicle_id)
        scenario = Scenario(**(await self.scenarios.get(plan_row.scenario_id)).body)
        _require_origin(scenario, plan_row.scenario_id, f"plan {plan_id}")
        autopilots = dict.fromkeys(uavs, Autopilot.ARDUPILOT)
        await asyncio.to_thread(
            functools.partial(flight_plan, landings_cleared=False),
            plan, scenario, autopilots, **options,
        )  # fmt: skip
        row: FlightRow = await self.book.flights.add(
            FlightRow(plan_id=plan_id, bindings=bindings, options=options)
        )
        return row

    # --- upload --------------------------------------------------------------------------

    async def upload(self, flight_id: str) -> list[VehicleAnswer]:
        """Every mission at once, each verified by reading it back; the vehicles then
        belong to this flight until it has ended."""
        slot = self.book.slot(flight_id)
        async with slot.serial():
            row = await self.book.row(flight_id)
            FlightState(row.state).check(F.UPLOADING, flight_id)
            plan, scenario = await self._flyable(row)
            fence = await self._fence_of(row)
            await self.attach_vehicles(row.bindings.values())
            links = {uav: self.registry.link(vid) for uav, vid in row.bindings.items()}
            flight = await _flight_for(plan, scenario, links, row.options)
            await self.registry.identify_all(row.bindings.values())  # ownership is by vehicle
            async with self.book.claims:
                await self.book.refuse_owned(row.bindings, flight_id)
                _refuse_airborne(row, links)
                await self.claim_control(flight_id)
                await self.book.transition(flight_id, F.UPLOADING)
            active = self._activate(row, links, flight, fence)
            try:
                outcomes = await slot.run(self._upload(active))
            except Preempted:
                return self._answers(active, {}, note="cancelled: the flight was aborted")
            return self._answers(active, outcomes)

    async def _flyable(self, row: FlightRow) -> tuple[Plan, Scenario]:
        """The flight's plan and scenario, refusing a scenario that cannot be flown."""
        plan_row = await self.plans.get(row.plan_id)
        scenario = Scenario(**(await self.scenarios.get(plan_row.scenario_id)).body)
        _require_origin(scenario, plan_row.scenario_id, f"flight {row.id}")
        return Plan(**plan_row.body), scenario

    async def _fence_of(self, row: FlightRow) -> FencePlan | None:
        """A geographic scenario's fence and rally points (uploaded with the missions);
        None for a grid scenario, whose flights upload no fence."""
        plan_row = await self.plans.get(row.plan_id)
        geographic = (await self.scenarios.get(plan_row.scenario_id)).geographic
        return None if geographic is None else fence_of(load_geographic(geographic))

    def _activate(
        self,
        row: FlightRow,
        links: dict[str, VehicleLink],
        flight: FlightPlan,
        fence: FencePlan | None = None,
    ) -> ActiveFlight:
        old = self.book.active.pop(row.id, None)
        if old is not None:
            old.fleet.close()
        fleet = Fleet(links, flight, settings=self.fleet_settings, fence=fence)
        active = ActiveFlight(
            row.id, fleet, flight.scenario, flight.plan, flight.missions, dict(row.bindings),
            dict(row.options), flight.factor,
        )  # fmt: skip
        self.book.active[row.id] = active
        fleet.record(self._recorder(active))
        return active

    async def _upload(self, active: ActiveFlight) -> dict[str, VehicleOutcome[Any]]:
        outcomes = await active.fleet.upload()
        for uav, outcome in outcomes.items():
            self.metrics.uploads.labels("ok" if outcome.ok else "failed").inc()
            if outcome.value is not None:
                self.metrics.upload_retries.inc(outcome.value.resends)
            mission = active.missions[uav]
            await self.book.flights.record_upload(
                UploadRow(
                    flight_id=active.flight_id, uav_id=uav, vehicle_id=active.vehicles[uav],
                    ok=outcome.ok, items=len(mission), detail=outcome.detail,
                    mission=plan_document(mission, active.fleet.crew.flight.notes(uav)),
                )
            )  # fmt: skip
        ok = all(o.ok for o in outcomes.values())
        failed = ", ".join(uav for uav, o in outcomes.items() if not o.ok)
        await self.book.transition(
            active.flight_id,
            F.UPLOADED if ok else F.UPLOAD_FAILED,
            "" if ok else f"{failed} refused",
        )
        return outcomes

    # --- start and the runner ----------------------------------------------------------

    async def start(self, flight_id: str) -> FlightRow:
        """Begin arming and lining up; answered at once, the flight is then `starting`."""
        slot = self.book.slot(flight_id)
        async with slot.serial():
            row = await self.book.row(flight_id)
            FlightState(row.state).check(F.STARTING, flight_id)
            active = self.book.active.get(flight_id)
            if active is None:
                raise StateConflict(
                    f"flight {flight_id}: the service restarted since the upload; upload again"
                )
            async with self.book.claims:
                await self.book.refuse_owned(row.bindings, flight_id)
                row = await self.book.transition(flight_id, F.STARTING)
            try:
                slot.start_runner(self._run(active))
            except Preempted as exc:  # held or aborted between the state change and now
                raise StateConflict(f"{exc}: nothing was armed") from None
            return row

    async def _run(self, active: ActiveFlight) -> None:
        """The flight's runner: prepare, start together, follow to the end."""
        await self._in_the_operators_hands(active, self._start_and_follow)

    async def _in_the_operators_hands(
        self, active: ActiveFlight, step: Callable[[ActiveFlight], Awaitable[None]]
    ) -> None:
        """`step`; a bug in it leaves the flight `interrupted`, in the operator's hands
        (a pre-emption is the operator's, who has set the state)."""
        try:
            await step(active)
        except asyncio.CancelledError:
            raise
        except Exception as exc:
            log.exception("flight %s: the runner failed", active.flight_id)
            await self.to_interrupted(active.flight_id, f"the ground station failed: {exc!r}")

    async def _start_and_follow(self, active: ActiveFlight) -> None:
        fleet, fid = active.fleet, active.flight_id
        outcomes = await fleet.prepare()
        if all(o.ok for o in outcomes.values()):
            outcomes = await fleet.start()
        failed = {uav: o.detail for uav, o in outcomes.items() if not o.ok}
        if failed:
            await self._start_failed(active, failed)
            return
        await self.book.transition(fid, F.FLYING)
        await self._follow(active)

    async def _follow(self, active: ActiveFlight) -> None:
        """Follow the flight to its end; the flight's state says how it went."""
        fid = active.flight_id
        report = await active.fleet.follow()
        if report.outcome == FlightOutcome.LANDED:
            await self.book.transition(fid, F.LANDED)
        elif report.outcome == FlightOutcome.ENDED:
            await self.book.transition(fid, F.ENDED, f"withdrawn: {sorted(report.withdrawn)}")
        elif report.outcome == FlightOutcome.TIMEOUT:
            await self.to_interrupted(fid, "the flight exceeded its time bound")
        await self.retire_when_down(fid)

    # --- following an interrupted flight again -------------------------------------------

    async def resume(self, flight_id: str, why: str = "by the operator") -> list[VehicleAnswer]:
        """Follow an interrupted flight again (after a restart or a takeover) from where
        its vehicles are: each still in the plan is stopped, then let go in the passing
        order; the flight is `flying` again. Refused (409), with nothing commanded, while
        a vehicle is not heard or flies another mission than this flight's."""
        slot = self.book.slot(flight_id)
        async with slot.serial():
            row = await self.book.row(flight_id)
            if FlightState(row.state) != F.INTERRUPTED:
                raise StateConflict(
                    f"flight {flight_id} is {row.state}: only an interrupted flight resumes"
                )
            slot.take_up_again()
            plan, scenario = await self._flyable(row)
            fence = await self._fence_of(row)
            await self.attach_vehicles(row.bindings.values())
            links = {uav: self.registry.link(vid) for uav, vid in row.bindings.items()}
            flight = await _flight_for(plan, scenario, links, row.options)
            _refuse_unresumable(row, links, flight)
            await _refuse_other_missions(row, links, flight)
            active = self._activate(row, links, flight, fence)
            outcomes = await active.fleet.resume()
            if not all(o.ok for o in outcomes.values()):
                self.book.forget(flight_id)
                active.fleet.close()
                return self._answers(active, outcomes)  # still interrupted; those stopped stay
            stopped = ", ".join(f"{uav}: {o.detail}" for uav, o in sorted(outcomes.items()))
            note = f"resumed {why}; stopped first: {stopped}"
            await self.book.transition(flight_id, F.FLYING, note)
            try:
                slot.start_runner(self._in_the_operators_hands(active, self._follow))
            except Preempted as exc:  # aborted or held while it resumed: that one stands
                raise StateConflict(f"{exc}: it was not resumed") from None
            return self._answers(active, outcomes)

    async def _start_failed(self, active: ActiveFlight, failed: dict[str, str]) -> None:
        why = "; ".join(f"{uav}: {detail}" for uav, detail in sorted(failed.items()))
        links = [m.link for m in active.fleet.crew.members.values()]
        if all(link.state.down for link in links):
            await self.book.transition(active.flight_id, F.UPLOADED, f"start failed: {why}")
        else:
            await self.to_interrupted(active.flight_id, f"start failed: {why}")

    async def to_interrupted(self, flight_id: str, note: str) -> None:
        with contextlib.suppress(StateConflict):
            await self.book.transition(flight_id, F.INTERRUPTED, note)

    async def retire_when_down(self, flight_id: str) -> None:
        """For an ended flight: release what it registered and the fleet it kept."""
        if (await self.book.state(flight_id)).is_open:
            return
        await self.book.events.flush()
        active = self.book.forget(flight_id)
        if active is not None:
            active.fleet.close()

    # --- events ------------------------------------------------------------------------

    def _recorder(self, active: ActiveFlight) -> Callable[[FleetEvent], None]:
        """What the fleet hands every event to, in its tick: stored (all but the periodic
        progress, of which the positions are kept once a second: the flown tracks) and
        passed on live. Neither waits, and storage gets every event (`event_writer.py`)."""
        kept = float("-inf")

        def record(event: FleetEvent) -> None:
            nonlocal kept
            message = event_json(event)
            if not isinstance(event, Progress):
                self.book.events.record(
                    active.flight_id, event.kind, message, message.get("uav_id")
                )
            elif event.at - kept >= TRACK_PERIOD_S:
                kept = event.at
                self.book.events.record(active.flight_id, EventKind.POSITIONS, positions(event))
            self.book.tell(active.flight_id, message)

        return record

    # --- live replanning ---------------------------------------------------------------

    async def report_object(self, flight_id: str, new_object: NewObject) -> dict[str, Any]:
        """The wormhole step, live: replan and re-upload only the UAVs the object touches."""
        slot = self.book.slot(flight_id)
        async with slot.serial():
            state = await self.book.state(flight_id)
            active = self.book.active.get(flight_id)
            if state not in (F.FLYING, F.PAUSED) or active is None:
                raise StateConflict(f"flight {flight_id} is {state.value}, not flying")
            try:
                return await slot.run(self._replan(active, new_object))
            except Preempted:
                raise StateConflict(f"flight {flight_id} was aborted during the replan") from None

    async def _replan(self, active: ActiveFlight, new_object: NewObject) -> dict[str, Any]:
        options = active.options
        try:
            outcome = await replan_flight(
                active.fleet, active.scenario, active.plan, new_object, list(active.objects),
                altitude_m=options["altitude_m"], finish=options["finish"],
                turn_radius_m=options["turn_radius_m"],
            )  # fmt: skip
        except ValueError as exc:  # the planner's verdict on the object itself
            raise BadObject(str(exc)) from exc
        except FlightStuck as exc:  # found before any upload: every mission stands
            raise StateConflict(
                f"the replan for the object at {tuple(new_object.cell)} was not flown: its "
                f"passing order cannot be kept ({exc}); every vehicle keeps its mission"
            ) from exc
        active.objects.append(new_object)
        active.plan = outcome.plan
        result = outcome.result
        for uav, upload in outcome.uploads.items():
            mission = outcome.missions[uav]
            await self.book.flights.record_upload(
                UploadRow(
                    flight_id=active.flight_id, uav_id=uav, vehicle_id=active.vehicles[uav],
                    ok=upload.ok, items=len(mission), detail=f"live replan: {upload.detail}",
                    mission=plan_document(mission, active.fleet.crew.flight.notes(uav))
                    if upload.ok
                    else None,
                )
            )  # fmt: skip
        pace = active.pace_factor
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
            "paths": {  # in the plan's own time, as GET /plans/{id} gives it
                uav: Trajectory(trajectory.points / (pace, 1.0, 1.0)).to_json()
                for uav, trajectory in result.changed.items()
                if outcome.uploads.get(uav) is not None and outcome.uploads[uav].ok
            },
            "uploads": [
                {"uav_id": u, "vehicle_id": active.vehicles[u], "ok": o.ok, "detail": o.detail}
                for u, o in sorted(outcome.uploads.items())
            ],
        }
        message = {"type": "event", "kind": EventKind.OBJECT_REPORTED, **answer}
        self.book.events.record(active.flight_id, EventKind.OBJECT_REPORTED, message)
        self.book.tell(active.flight_id, message)
        return answer

    # --- releasing and deleting ----------------------------------------------------------

    async def cancel(self, flight_id: str) -> FlightRow:
        """Release an unflown flight's vehicles (created, uploaded or upload_failed)."""
        async with self.book.slot(flight_id).serial():
            row = await self.book.transition(flight_id, F.CANCELLED, "cancelled by the operator")
        await self.retire_when_down(flight_id)
        return row

    async def delete(self, flight_id: str) -> None:
        state = await self.book.state(flight_id)
        if state.is_open:
            raise StateConflict(
                f"flight {flight_id} is {state.value}: it may have vehicles in the air; "
                "abort it or cancel it, and delete it once it has ended"
            )
        self.book.forget(flight_id)
        await self.book.flights.delete(flight_id)

    # --- live state ------------------------------------------------------------------------

    async def snapshot(self, flight_id: str) -> dict[str, Any]:
        """Every bound vehicle's position, mode, progress and schedule lag, now."""
        state = await self.book.state(flight_id)
        bindings = await self.book.bindings(flight_id)
        active = self.book.active.get(flight_id)
        progress = {p.uav_id: p for p in active.fleet.progress()} if active else {}
        vehicles = []
        for uav, vehicle_id in bindings.items():
            entry: dict[str, Any] = {
                "uav_id": uav,
                "vehicle_id": vehicle_id,
                **self.registry.state(vehicle_id),
            }
            if uav in progress:
                entry["progress"] = dataclasses.asdict(progress[uav])
            vehicles.append(entry)
        return {
            "type": "state",
            "flight_id": flight_id,
            "state": state.value,
            "pace_factor": active.pace_factor if active else None,
            "min_separation_m": active.fleet.min_separation_m if active else None,
            "vehicles": vehicles,
        }

    async def listen(self, flight_id: str) -> LiveQueue:
        await self.book.state(flight_id)  # 404 for an unknown flight
        return self.book.listen(flight_id)

    def unlisten(self, flight_id: str, queue: LiveQueue) -> None:
        self.book.unlisten(flight_id, queue)

    def _answers(
        self,
        active: ActiveFlight,
        outcomes: dict[str, VehicleOutcome[Any]],
        note: str = "",
    ) -> list[VehicleAnswer]:
        answers = []
        for uav, vid in sorted(active.vehicles.items()):
            outcome = outcomes.get(uav)
            ok = outcome is not None and outcome.ok
            answers.append(VehicleAnswer(uav, vid, ok, note or (outcome.detail if outcome else "")))
        return answers

    async def close(self) -> None:
        """The service stops. No vehicle may fly on unfollowed (nothing would keep the
        passing order), so every one in the air is told to hold where it is, and its
        flight becomes `interrupted`, still owning its vehicles: after a restart the
        operator brings them down (abort: land or return)."""
        for flight_id in list(self.book.active):
            await self.book.slot(flight_id).preempt()
            active = self.book.forget(flight_id)
            if active is None:
                continue
            active.fleet.close()
            if await self.book.state(flight_id) in FOLLOWED:  # not landing or going home
                held = await _hold_airborne(active)
                await self.to_interrupted(
                    flight_id, f"the ground station stopped; held where they were: {held}"
                )


async def _claim_nothing(_what: object) -> None:
    """One service alone on its database needs no claim."""


async def _flight_for(
    plan: Plan, scenario: Scenario, links: dict[str, VehicleLink], options: dict[str, Any]
) -> FlightPlan:
    """The plan at the flight's speed with each vehicle's own limits (UnsafeSpeed if the
    ground station cannot keep it safe with them); computed off the event loop. A plan
    whose passing order these vehicles cannot keep to the end is refused (StateConflict:
    fuzzed flight 13783 answered it with a 500)."""
    read = await asyncio.gather(*(read_limits(link) for link in links.values()))
    limits = dict(zip(links, read, strict=True))
    autopilots = {uav: link.autopilot for uav, link in links.items()}
    flight = await asyncio.to_thread(
        flight_plan, plan, scenario, autopilots, limits=limits, **options
    )
    try:
        await asyncio.to_thread(lambda: flight.timed)  # the schedule, before the loop needs it
    except FlightStuck as exc:
        raise StateConflict(
            f"plan {plan.scenario!r} cannot be flown in its passing order with these "
            f"vehicles' limits ({exc}); nothing was uploaded: plan it again (another "
            "seed) or fly it slower"
        ) from None
    return flight


async def _hold_airborne(active: ActiveFlight) -> list[str]:
    """Hold every vehicle of the flight that is in the air (a bounded try each: the
    service is stopping); the UAVs that confirmed."""

    async def hold(uav: str, link: VehicleLink) -> str | None:
        if not link.state.airborne:
            return None
        with contextlib.suppress(Exception):
            async with asyncio.timeout(HOLD_ON_STOP_S):
                await FlightActions(link).hold()
                return uav
        log.warning("flight %s: %s did not confirm its hold", active.flight_id, uav)
        return None

    members = active.fleet.crew.members
    held = await asyncio.gather(*(hold(uav, m.link) for uav, m in sorted(members.items())))
    return [uav for uav in held if uav is not None]


def _refuse_unresumable(row: FlightRow, links: dict[str, VehicleLink], flight: FlightPlan) -> None:
    """A flight resumes with a vehicle in the air, each airborne one having started its
    mission (`registry.link` has refused one not heard)."""
    if not any(link.state.airborne for link in links.values()):
        raise StateConflict(f"flight {row.id}: every vehicle is on the ground: nothing resumes")
    for uav, link in sorted(links.items()):
        state = link.state
        started = state.mode == "AUTO" or state.mission_seq > takeoff_index(
            flight.missions[uav].items
        )
        if state.airborne and not started:
            raise StateConflict(
                f"flight {row.id}: vehicle {row.bindings[uav]} ({uav}) has not started its "
                "mission (the flight was interrupted during its start): it cannot be "
                "resumed; upload and start it again once down, or abort"
            )


async def _refuse_other_missions(
    row: FlightRow, links: dict[str, VehicleLink], flight: FlightPlan
) -> None:
    """Each vehicle in the air must still hold this flight's mission, as built again from
    its plan (not one uploaded since, by a live replan or another ground station); the
    missions are read back from all at once."""

    async def check(uav: str, link: VehicleLink) -> None:
        who = f"vehicle {row.bindings[uav]} ({uav})"
        try:
            held = await MissionClient(link).download()
        except GcsError as exc:
            message = f"flight {row.id}: {who}'s mission could not be read: {exc}"
            raise StateConflict(message) from exc
        seq = first_mismatch(flight.missions[uav], held)
        if seq is not None:
            raise StateConflict(
                f"flight {row.id}: {who} holds another mission than this flight's (item "
                f"{seq} differs; replanned live, or uploaded by another ground station): "
                "it cannot be resumed; land, return or abort it"
            )

    airborne = [(uav, link) for uav, link in sorted(links.items()) if link.state.airborne]
    await asyncio.gather(*(check(uav, link) for uav, link in airborne))


def _refuse_airborne(row: FlightRow, links: dict[str, VehicleLink]) -> None:
    """A mission goes only to a vehicle disarmed on the ground (not to one that is flying
    for a flight the service no longer follows, after a restart)."""
    for uav, link in links.items():
        state = link.state
        if state.armed or state.airborne:
            what = "armed" if state.armed else "in the air"
            raise StateConflict(
                f"vehicle {row.bindings[uav]} ({uav}) is {what}: "
                "a mission is uploaded only to a vehicle disarmed on the ground"
            )


def positions(progress: Progress) -> dict[str, Any]:
    """The flown tracks' sample: where each vehicle is, on the flight's clock."""
    vehicles = {p.uav_id: [p.lat, p.lon, p.alt_m] for p in progress.vehicles if p.lat is not None}
    clock = max((p.clock_s for p in progress.vehicles), default=0.0)
    return {"type": "event", "kind": EventKind.POSITIONS, "clock_s": clock, "vehicles": vehicles}
