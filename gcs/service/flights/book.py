"""The flights the service knows right now: their states, turns, live parts and owners.

Every state change goes through `transition`: one conditional write in storage (the
transition table decides), then the cached state, a `FlightState` event (stored and
streamed) and the live listeners. Ownership (a vehicle belongs to at most one open
flight) is decided under one lock, together with the transition that claims it, and
by vehicle, not by registration: `same_vehicles` names the registrations that reach the
vehicle another way (one system reached on its own port and on the listening port).
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Iterable
from typing import Any

from gcs.fleet.events import EventKind
from gcs.service.flights.active import LISTENER_QUEUE, ActiveFlight
from gcs.service.flights.event_writer import EventWriter
from gcs.service.flights.live_queue import LiveQueue
from gcs.service.flights.slot import FlightSlot
from gcs.service.states import FlightState, StateConflict
from gcs.service.storage import FlightRepository
from gcs.service.storage.tables import FlightRow


class FlightBook:
    def __init__(
        self,
        flights: FlightRepository,
        events: EventWriter,
        same_vehicles: Callable[[str], set[str]] = lambda vehicle_id: {vehicle_id},
    ) -> None:
        self.flights = flights
        self.events = events
        self.same_vehicles = same_vehicles
        """vehicle id -> every registered vehicle id known to reach that vehicle (itself too)."""
        self.active: dict[str, ActiveFlight] = {}
        self._slots: dict[str, FlightSlot] = {}
        self._states: dict[str, FlightState] = {}
        self._bindings: dict[str, dict[str, str]] = {}
        self._listeners: dict[str, set[LiveQueue]] = {}
        self.claims = asyncio.Lock()  # ownership checks and the claims they allow

    def slot(self, flight_id: str) -> FlightSlot:
        if flight_id not in self._slots:
            self._slots[flight_id] = FlightSlot(flight_id)
        return self._slots[flight_id]

    async def row(self, flight_id: str) -> FlightRow:
        row: FlightRow = await self.flights.get(flight_id)
        self._states[flight_id] = FlightState(row.state)
        self._bindings[flight_id] = dict(row.bindings)
        return row

    async def state(self, flight_id: str) -> FlightState:
        if flight_id not in self._states:
            await self.row(flight_id)
        return self._states[flight_id]

    async def bindings(self, flight_id: str) -> dict[str, str]:
        """uav id -> vehicle id (they never change once the flight is made)."""
        if flight_id not in self._bindings:
            await self.row(flight_id)
        return self._bindings[flight_id]

    async def transition(self, flight_id: str, new: FlightState, note: str = "") -> FlightRow:
        row = await self.flights.transition(flight_id, new, note)
        self._states[flight_id] = new
        kind = EventKind.FLIGHT_STATE
        message = {"type": "event", "kind": kind, "state": new.value, "note": note}
        self.events.record(flight_id, kind, message)
        self.tell(flight_id, message)
        return row

    def listen(self, flight_id: str) -> LiveQueue:
        """Every live message about the flight from now on, whatever state it is in, as
        many as the queue holds (and a `dropped` notice for the others)."""
        queue = LiveQueue(LISTENER_QUEUE, self.events.metrics.live_dropped.inc)
        self._listeners.setdefault(flight_id, set()).add(queue)
        return queue

    def unlisten(self, flight_id: str, queue: LiveQueue) -> None:
        listeners = self._listeners.get(flight_id)
        if listeners is not None:
            listeners.discard(queue)
            if not listeners:
                del self._listeners[flight_id]

    def tell(self, flight_id: str, message: dict[str, Any]) -> None:
        """Give a message to the flight's listeners; a slow one loses its oldest messages,
        counted, and is told so."""
        for queue in list(self._listeners.get(flight_id, ())):
            queue.put(message)

    async def owners(self, vehicle_ids: Iterable[str], excluding: str) -> dict[str, FlightRow]:
        """vehicle id -> the other open flight that owns it, under any registration."""
        owned: dict[str, FlightRow] = {}
        rows = [row for row in await self.flights.open_flights() if row.id != excluding]
        for vehicle_id in set(vehicle_ids):
            row = _owner(rows, self.same_vehicles(vehicle_id))
            if row is not None:
                owned[vehicle_id] = row
        return owned

    async def refuse_owned(self, bindings: dict[str, str], flight_id: str) -> None:
        """409 if a vehicle belongs to another open flight, or is bound twice here."""
        uav_of = {vid: uav for uav, vid in bindings.items()}
        twice = [
            (uav, other)
            for uav, vid in bindings.items()
            for other in sorted(self.same_vehicles(vid) - {vid})
            if other in uav_of and uav < uav_of[other]
        ]
        if twice:
            clashes = "; ".join(
                f"{uav} ({bindings[uav]}) and {uav_of[other]} ({other})" for uav, other in twice
            )
            raise StateConflict(
                f"flight {flight_id}: {clashes} are one vehicle reached two ways; bind it once"
            )
        owned = await self.owners(bindings.values(), excluding=flight_id)
        if owned:
            clashes = "; ".join(
                f"vehicle {vid} ({uav_of[vid]}) {_as_bound(row, vid, self.same_vehicles(vid))} "
                f"flight {row.id}, which is {row.state}"
                for vid, row in sorted(owned.items())
            )
            raise StateConflict(
                f"flight {flight_id}: {clashes}; a vehicle flies one flight at a time, until "
                "that flight's vehicles are all disarmed on the ground"
            )

    async def open_flight_of(self, vehicle_id: str) -> FlightRow | None:
        return _owner(await self.flights.open_flights(), self.same_vehicles(vehicle_id))

    def uav_of(self, row: FlightRow, vehicle_id: str) -> str:
        """The UAV of `row` flown by the vehicle `vehicle_id` reaches."""
        same = self.same_vehicles(vehicle_id)
        return next(uav for uav, vid in row.bindings.items() if vid in same)

    def forget(self, flight_id: str) -> ActiveFlight | None:
        """Drop what the service kept for a flight that has ended."""
        self._slots.pop(flight_id, None)
        self._bindings.pop(flight_id, None)
        return self.active.pop(flight_id, None)


def _owner(rows: Iterable[FlightRow], same: set[str]) -> FlightRow | None:
    return next((row for row in rows if same & set(row.bindings.values())), None)


def _as_bound(row: FlightRow, vehicle_id: str, same: set[str]) -> str:
    """How `vehicle_id` belongs to `row`: itself, or as the registration `row` bound."""
    if vehicle_id in row.bindings.values():
        return "belongs to"
    bound = next(vid for vid in row.bindings.values() if vid in same)
    return f"is vehicle {bound} (the same system and board, reached another way) of"
