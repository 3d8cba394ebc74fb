"""Several services, one database: which one controls a flight, and taking over from one
that died.

A service holds the flights it uploaded (and those it took over) under a lease in the
database (`storage/leases.py`) and renews every lease it holds once a `renew_s`. Each
renewal also looks for open flights whose holder's lease has run out (killed, frozen, cut
off from the database): it claims each (one conditional UPDATE: of two survivors one
wins), re-attaches its vehicles (registered, perhaps, on the dead service only: they are
added from storage; each vehicle must be reachable from both, as SITL's further serial
ports or a MAVLink router allow), records a `TakenOver` event, and keeps the operator in
control. Nothing is uploaded: the vehicles fly on the missions they have. The passing
order was kept by the dead service's follower, which is gone; so a flight taken over in
the air is `interrupted`, as after a restart, each vehicle still flying its mission is
paused as soon as its link is up (nobody keeps the order), and the flight is watched
until every vehicle is down: resume, abort, hold, land and return work on it from the
survivor, which resumes it by itself (`resume_taken_over`) once every vehicle is heard
and paused, unless the operator commands it first.
An `aborting` flight stays so, its abort sent again to every vehicle not yet down.

A service that finds a flight it thought its own held by another (it was frozen longer
than a lease) lets it go at once, commanding nothing. A request for a flight that another
live service holds is refused (409) naming that service and where it answers.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import uuid
from collections.abc import Iterable

from gcs.fleet.crew import Fallback
from gcs.fleet.events import EventKind
from gcs.mavlink.connection import Signing
from gcs.service.flights.operator import OperatorCommands
from gcs.service.flights.service import FlightService
from gcs.service.settings import Settings
from gcs.service.states import AIRBORNE, FlightState, StateConflict
from gcs.service.storage import NotFound, VehicleRepository
from gcs.service.storage.leases import Holder, LeaseRepository
from gcs.service.storage.tables import FlightRow
from gcs.service.vehicle_registry import VehicleRegistry

log = logging.getLogger("mvo_gcs.control")
F = FlightState
TAKEN_IN_THE_AIR = frozenset({F.UPLOADING, F.STARTING, F.FLYING, F.PAUSED})
"""States a dead service's follower kept; nobody follows them now: `interrupted`."""


class ControlledElsewhere(StateConflict):
    """The flight is controlled by another live service; answered 409, naming it."""


def _abort_of(row: FlightRow) -> Fallback | None:
    """The operator's abort an `aborting` flight carries out ("land by the operator")."""
    word = (row.note or "").split(" ", 1)[0]
    return Fallback(word) if word in (Fallback.LAND.value, Fallback.RTL.value) else None


def holder_for(settings: Settings) -> Holder:
    """This service as a lease holder: `service_id` and `public_url`, or made up."""
    service_id = settings.service_id or (
        f"{socket.gethostname()}:{settings.port}/{uuid.uuid4().hex[:8]}"
    )
    url = settings.public_url or f"http://{settings.host}:{settings.port}"
    return Holder(service_id, url.rstrip("/"))


class FlightControl:
    def __init__(
        self,
        leases: LeaseRepository,
        flights: FlightService,
        operator: OperatorCommands,
        vehicles: VehicleRepository,
        registry: VehicleRegistry,
        renew_s: float,
        *,
        resume_taken_over: bool = False,
    ) -> None:
        self.leases, self.flights, self.operator = leases, flights, operator
        self.vehicles, self.registry = vehicles, registry
        self.resume_taken_over = resume_taken_over
        self.renew_s = min(renew_s, leases.lease_s / 2)
        self._task: asyncio.Task[None] | None = None
        self._held: set[str] = set()  # as the last renewal or claim found: no query needed
        self._fresh_until = 0.0  # loop time until which the last renewal's leases hold
        self.taken_over = 0

    @property
    def holder(self) -> Holder:
        return self.leases.holder

    def start(self) -> None:
        self._task = asyncio.ensure_future(self._keep())

    async def stop(self) -> None:
        """Renew and take over no more (this service is stopping)."""
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task

    async def release(self) -> None:
        """Hand this service's flights over at once, once `FlightService.close` has held
        what was in the air: another service takes them without waiting for the lease."""
        with contextlib.suppress(Exception):
            await self.leases.release()

    async def _keep(self) -> None:
        while True:
            try:
                await self.tick()
            except Exception:  # storage away for a moment: try again next time
                log.exception("renewing the leases failed")
            await asyncio.sleep(self.renew_s)

    async def tick(self) -> None:
        """Renew, let go of what another took, take over what a dead one left."""
        asked = asyncio.get_running_loop().time()
        renewal = await self.leases.renew()
        self._held = set(renewal.flights)
        self._fresh_until = asked + self.leases.lease_s
        for flight_id in sorted(set(self.flights.book.active) - renewal.flights):
            await self._let_go(flight_id)
        await self.sync_vehicles()
        for row in renewal.orphans:
            await self.take_over(row)

    # --- requests -------------------------------------------------------------------------

    async def require(self, flight_id: str) -> None:
        """409 unless this service may act on the flight: nobody's (not uploaded yet), its
        own, or its holder's lease has run out (this service is taking it over)."""
        if flight_id in self._held and asyncio.get_running_loop().time() < self._fresh_until:
            return  # held under a lease still running: an abort must not wait for storage
        holder, live = await self.leases.holder_of(flight_id)
        if holder is None or holder.id == self.holder.id:
            return
        if live:
            raise ControlledElsewhere(
                f"flight {flight_id} is controlled by service {holder.id} at {holder.url}: "
                "ask it there"
            )
        row = await self.flights.book.flights.get(flight_id)
        if FlightState(row.state).is_open:
            await self.take_over(row)
        now_held, _ = await self.leases.holder_of(flight_id)
        if now_held is None or now_held.id != self.holder.id:
            raise ControlledElsewhere(
                f"flight {flight_id}: service {holder.id} at {holder.url} stopped renewing "
                "its lease and another service is taking it over; ask again"
            )

    async def claim_for_upload(self, flight_id: str) -> None:
        """The upload makes the flight this service's (409 if another live one has it)."""
        await self.require(flight_id)
        if not await self.leases.claim_flight(flight_id):
            holder, _ = await self.leases.holder_of(flight_id)
            where = f"service {holder.id} at {holder.url}" if holder else "another service"
            raise ControlledElsewhere(f"flight {flight_id} is controlled by {where}")
        self._held.add(flight_id)

    # --- taking over ------------------------------------------------------------------------

    async def take_over(self, row: FlightRow) -> bool:
        """Claim a dead service's open flight, re-attach its vehicles and keep the operator
        in control of it; False if another service claimed it first."""
        previous = row.owner_id or "nobody"
        if not await self.leases.claim_flight(row.id):
            return False
        self._held.add(row.id)
        self.taken_over += 1
        await self.attach(row.bindings.values())
        row = await self.flights.book.row(row.id)
        state = FlightState(row.state)
        note = f"taken over by service {self.holder.id} at {self.holder.url} from {previous}"
        message = {
            "type": "event",
            "kind": EventKind.TAKEN_OVER,
            "by": self.holder.id,
            "url": self.holder.url,
            "state": state.value,
            "from": previous,
        }
        self.flights.book.events.record(row.id, EventKind.TAKEN_OVER, message)
        self.flights.book.tell(row.id, message)
        log.warning("flight %s (%s): %s", row.id, state.value, note)
        if state in TAKEN_IN_THE_AIR:
            await self.flights.to_interrupted(
                row.id,
                f"{note}: nobody keeps the passing order now, so the missions still flown "
                "are paused. Resume the flight, or land, return or abort the vehicles",
            )
            self.operator.pause_unfollowed(row.id, row.bindings)
            if self.resume_taken_over:
                by = f"by service {self.holder.id}, which took it over from {previous}"
                self.operator.resume_when_heard(row.id, by)
        fallback = _abort_of(row) if state == F.ABORTING else None
        if fallback is not None:  # the dead service may not have reached every vehicle
            self.operator.owe_abort(row.id, fallback, row.bindings.values())
        elif state in AIRBORNE or state in TAKEN_IN_THE_AIR:
            self.operator.watch_until_down(row.id)
        return True

    async def attach(self, vehicle_ids: Iterable[str]) -> None:
        """Every vehicle of `vehicle_ids` known to the registry (registered, perhaps, on
        another service after this one started): its link connects by itself."""
        for vehicle_id in sorted(set(vehicle_ids)):
            if self.registry.knows(vehicle_id):
                continue
            try:
                vehicle = await self.vehicles.get(vehicle_id)
            except NotFound:
                continue
            signing = Signing.from_text(vehicle.signing_key) if vehicle.signing_key else None
            self.registry.add(vehicle.id, vehicle.connection, vehicle.sysid, signing)

    async def sync_vehicles(self) -> None:
        """Connect to the vehicles registered on other services too, and forget those
        deleted there: every service is ready to take any flight over. Under the
        registry's registration lock, so that no registration here is half seen."""
        async with self.registry.registering:
            stored, known = await self.vehicles.ids(), self.registry.known()
            for vehicle_id in sorted(stored - known):
                with contextlib.suppress(NotFound):  # deleted meanwhile
                    row = await self.vehicles.get(vehicle_id)
                    signing = Signing.from_text(row.signing_key) if row.signing_key else None
                    self.registry.add(row.id, row.connection, row.sysid, signing)
            for vehicle_id in sorted(known - stored):
                await self.registry.remove(vehicle_id)

    async def _let_go(self, flight_id: str) -> None:
        """Another service holds a flight this one ran (it was frozen longer than a
        lease): stop following it, command nothing."""
        book = self.flights.book
        with contextlib.suppress(NotFound):  # deleted meanwhile: forgotten below
            if (await book.row(flight_id)).owner_id in (None, self.holder.id):
                return  # still this service's: it has just ended
        log.warning("flight %s: another service holds it now; letting it go", flight_id)
        await book.slot(flight_id).preempt()
        self.operator.stop_watching(flight_id)
        active = book.forget(flight_id)
        if active is not None:
            active.fleet.close()
