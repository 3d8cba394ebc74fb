"""The flights the service knows right now: their states, turns, live parts and owners.

Every state change goes through `transition`: one conditional write in storage (the
transition table decides), then the cached state, a `FlightState` event (stored and
streamed) and the live listeners. Ownership (a vehicle belongs to at most one open
flight) is decided under one lock, together with the transition that claims it.
"""

from __future__ import annotations

import asyncio
from collections.abc import Iterable
from typing import Any

from gcs.service.flights.active import LISTENER_QUEUE, ActiveFlight
from gcs.service.flights.event_writer import EventWriter
from gcs.service.flights.slot import FlightSlot
from gcs.service.states import FlightState, StateConflict
from gcs.service.storage import FlightRepository
from gcs.service.storage.tables import FlightRow


class FlightBook:
    def __init__(self, flights: FlightRepository, events: EventWriter) -> None:
        self.flights = flights
        self.events = events
        self.active: dict[str, ActiveFlight] = {}
        self._slots: dict[str, FlightSlot] = {}
        self._states: dict[str, FlightState] = {}
        self._bindings: dict[str, dict[str, str]] = {}
        self._listeners: dict[str, set[asyncio.Queue[dict[str, Any]]]] = {}
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
        message = {"type": "event", "kind": "FlightState", "state": new.value, "note": note}
        self.events.record(flight_id, "FlightState", message)
        self.tell(flight_id, message)
        return row

    def listen(self, flight_id: str) -> asyncio.Queue[dict[str, Any]]:
        """Every live message about the flight from now on, whatever state it is in."""
        queue: asyncio.Queue[dict[str, Any]] = asyncio.Queue(maxsize=LISTENER_QUEUE)
        self._listeners.setdefault(flight_id, set()).add(queue)
        return queue

    def unlisten(self, flight_id: str, queue: asyncio.Queue[dict[str, Any]]) -> None:
        listeners = self._listeners.get(flight_id)
        if listeners is not None:
            listeners.discard(queue)
            if not listeners:
                del self._listeners[flight_id]

    def tell(self, flight_id: str, message: dict[str, Any]) -> None:
        """Give a message to the flight's listeners; a slow one loses its oldest messages."""
        for queue in list(self._listeners.get(flight_id, ())):
            if queue.full():
                queue.get_nowait()
            queue.put_nowait(message)

    async def owners(self, vehicle_ids: Iterable[str], excluding: str) -> dict[str, FlightRow]:
        """vehicle id -> the other open flight that owns it."""
        wanted = set(vehicle_ids)
        owned: dict[str, FlightRow] = {}
        for row in await self.flights.open_flights():
            if row.id == excluding:
                continue
            for vehicle_id in wanted & set(row.bindings.values()):
                owned[vehicle_id] = row
        return owned

    async def refuse_owned(self, bindings: dict[str, str], flight_id: str) -> None:
        owned = await self.owners(bindings.values(), excluding=flight_id)
        if owned:
            uav_of = {vid: uav for uav, vid in bindings.items()}
            clashes = "; ".join(
                f"vehicle {vid} ({uav_of[vid]}) belongs to flight {row.id}, which is {row.state}"
                for vid, row in sorted(owned.items())
            )
            raise StateConflict(
                f"flight {flight_id}: {clashes}; a vehicle flies one flight at a time, until "
                "that flight's vehicles are all disarmed on the ground"
            )

    async def open_flight_of(self, vehicle_id: str) -> FlightRow | None:
        for row in await self.flights.open_flights():
            if vehicle_id in row.bindings.values():
                return row
        return None

    def forget(self, flight_id: str) -> ActiveFlight | None:
        """Drop what the service kept for a flight that has ended."""
        self._slots.pop(flight_id, None)
        self._bindings.pop(flight_id, None)
        return self.active.pop(flight_id, None)
