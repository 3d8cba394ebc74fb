"""What the fleet reports while it works: plain dataclasses, fanned out to sinks and listeners.

Events are published from the flight's tick, which must never wait. What must see every
event (the service's flight record) is a *sink*: called in `publish` itself, in order,
and it must be quick. A terminal display, a test or a live stream each call
`EventBus.listen()` and read the same events at their own pace from a bounded queue; a
slow listener loses its oldest events, never stalls the flight, and each one it loses
is counted (`Listener.dropped`).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import ClassVar

from gcs.fleet.route_tracker import VehicleProgress

log = logging.getLogger("mvo_gcs.fleet")


class FlightOutcome(StrEnum):
    """How the watch over a flight ended; the value is the wire name (events, API)."""

    LANDED = "landed"  # every vehicle flew its mission to the end and is down
    ABORTED = "aborted"  # the operator or a fallback aborted the flight
    TIMEOUT = "timeout"  # it ran past its time bound (and was aborted)
    ENDED = "ended"  # the others ended without a vehicle that was withdrawn


class EventKind(StrEnum):
    """What an event is: the `kind` of every event a client reads (the live stream, the
    stored events, the console). The value is the wire name: it never changes, since
    clients compare it and databases store it."""

    # published by the fleet: one event class each, below
    UPLOADED = "Uploaded"
    VEHICLE_READY = "VehicleReady"
    VEHICLE_FAILED = "VehicleFailed"
    MISSIONS_STARTED = "MissionsStarted"
    START_CANCELLED = "StartCancelled"
    ITEM_REACHED = "ItemReached"
    WAITING = "Waiting"
    WAIT_OVER = "WaitOver"
    LEAD_TAKEN = "LeadTaken"
    OPERATOR_HELD = "OperatorHeld"
    OPERATOR_CONTINUED = "OperatorContinued"
    WITHDRAWN = "Withdrawn"
    VEHICLE_LINK_REGAINED = "VehicleLinkRegained"
    BRAKED_ON_LINK_LOSS = "BrakedOnLinkLoss"
    ADDRESS_CLAIMED = "AddressClaimed"
    PROGRESS = "Progress"  # live only, never stored (see POSITIONS)
    VEHICLE_FINISHED = "VehicleFinished"
    ABORTED = "Aborted"
    FLIGHT_ENDED = "FlightEnded"
    # recorded by the service about a flight (gcs.service.flights)
    FLIGHT_STATE = "FlightState"  # the flight's state changed (`state`, `note`)
    OBJECT_REPORTED = "ObjectReported"  # a live replan's answer
    OPERATOR_COMMAND = "OperatorCommand"  # one vehicle commanded during a flight
    POSITIONS = "Positions"  # stored only, once a second from PROGRESS: the flown tracks
    TAKEN_OVER = "TakenOver"  # another service took the flight over
    UNFOLLOWED_PAUSED = "UnfollowedPaused"  # its mission paused: nobody kept its order
    AUTO_RESUMED = "AutoResumed"  # a flight taken over resumed by the service (`detail`)
    # no longer made: the schedule keeper's pause and resume of the vehicles waiting for a
    # late one, before the passing order's WAITING and WAIT_OVER; databases keep them
    PAUSED = "Paused"
    RESUMED = "Resumed"


@dataclass(frozen=True)
class FleetEvent:
    """Base of every event; `at` is the loop time it happened, `kind` its wire name."""

    kind: ClassVar[EventKind]
    at: float = field(default=0.0, kw_only=True)


@dataclass(frozen=True)
class Uploaded(FleetEvent):
    kind = EventKind.UPLOADED
    uav_id: str
    ok: bool
    detail: str


@dataclass(frozen=True)
class VehicleReady(FleetEvent):
    """Armed, airborne and holding at its altitude over its start."""

    kind = EventKind.VEHICLE_READY
    uav_id: str
    altitude_m: float


@dataclass(frozen=True)
class VehicleFailed(FleetEvent):
    kind = EventKind.VEHICLE_FAILED
    uav_id: str
    phase: str  # "upload", "prepare", "start", "flight"
    message: str


@dataclass(frozen=True)
class MissionsStarted(FleetEvent):
    kind = EventKind.MISSIONS_STARTED
    uav_ids: tuple[str, ...]
    spread_ms: float  # between the first and the last start command sent
    timed_duration_s: float = 0.0  # to the last arrival, as the timed flight has it


@dataclass(frozen=True)
class StartCancelled(FleetEvent):
    """A vehicle failed before the start: nobody starts, the others do `fallback`."""

    kind = EventKind.START_CANCELLED
    failed: tuple[str, ...]
    fallback: str


@dataclass(frozen=True)
class ItemReached(FleetEvent):
    kind = EventKind.ITEM_REACHED
    uav_id: str
    seq: int
    plan_time_s: float  # when it got there, on the plan's clock
    scheduled_s: float  # when the plan said it would


@dataclass(frozen=True)
class Waiting(FleetEvent):
    """A vehicle stops (or approaches slowly, "creep") to let another pass first, as the
    plan has it: it may not go beyond `gap_m` metres ahead until `waits_for` has passed."""

    kind = EventKind.WAITING
    uav_id: str
    waits_for: str
    how: str  # "stop" or "creep"
    gap_m: float
    speed_m_s: float | None = None  # of an approach


@dataclass(frozen=True)
class WaitOver(FleetEvent):
    """The vehicle it waited for is out of its way: it flies on."""

    kind = EventKind.WAIT_OVER
    uav_id: str


@dataclass(frozen=True)
class LeadTaken(FleetEvent):
    """A vehicle stood `past_m` past the place it was to wait at, inside an encounter
    (its stop came late): it goes first there, and the order is turned round for the
    pairs `turned` (each: who now goes first, who now waits), `gcs.fleet.lead_taking`.
    `unheard`: its link went down while it flew on, `past_m` metres past that place
    (below 0: short of it), so it goes first wherever the others can still wait."""

    kind = EventKind.LEAD_TAKEN
    uav_id: str
    past_m: float
    turned: tuple[tuple[str, str], ...]
    unheard: bool = False


@dataclass(frozen=True)
class OperatorHeld(FleetEvent):
    """The operator stopped these vehicles; only the operator's continue moves them."""

    kind = EventKind.OPERATOR_HELD
    uav_ids: tuple[str, ...]


@dataclass(frozen=True)
class OperatorContinued(FleetEvent):
    kind = EventKind.OPERATOR_CONTINUED
    uav_ids: tuple[str, ...]


@dataclass(frozen=True)
class Withdrawn(FleetEvent):
    """The operator sent one vehicle down (land) or home (rtl): it leaves the plan."""

    kind = EventKind.WITHDRAWN
    uav_id: str
    mode: str


@dataclass(frozen=True)
class VehicleLinkRegained(FleetEvent):
    kind = EventKind.VEHICLE_LINK_REGAINED
    uav_id: str


@dataclass(frozen=True)
class BrakedOnLinkLoss(FleetEvent):
    """The vehicle was found braked by its own GCS failsafe (it had not heard us for
    `link_loss_brake_s`): the passing order sends it on again (AUTO), or, sent home by
    the operator, it is sent home again."""

    kind = EventKind.BRAKED_ON_LINK_LOSS
    uav_id: str


@dataclass(frozen=True)
class AddressClaimed(FleetEvent):
    """Another address sends as this vehicle's system id (and is ignored): an impostor,
    or the vehicle itself come back through a restarted router, for the operator to move
    (`POST /vehicles/{id}/address`)."""

    kind = EventKind.ADDRESS_CLAIMED
    uav_id: str
    address: str


@dataclass(frozen=True)
class Progress(FleetEvent):
    kind = EventKind.PROGRESS
    vehicles: tuple[VehicleProgress, ...]
    min_separation_m: float | None


@dataclass(frozen=True)
class VehicleFinished(FleetEvent):
    kind = EventKind.VEHICLE_FINISHED
    uav_id: str
    distance_to_goal_m: float


@dataclass(frozen=True)
class Aborted(FleetEvent):
    kind = EventKind.ABORTED
    mode: str
    reason: str


@dataclass(frozen=True)
class FlightEnded(FleetEvent):
    kind = EventKind.FLIGHT_ENDED
    completed: bool
    min_separation_m: float | None
    closest_pair: tuple[str, str] | None
    outcome: FlightOutcome = FlightOutcome.LANDED


class Listener:
    """One listener's bounded queue: when it is full the oldest event is dropped and
    counted in `dropped`, so that a slow listener never stalls the flight and its loss is
    known."""

    def __init__(self, bus: EventBus, maxsize: int) -> None:
        self._bus = bus
        self._queue: asyncio.Queue[FleetEvent | None] = asyncio.Queue(maxsize)
        self.dropped = 0

    def put(self, event: FleetEvent | None) -> None:
        if self._queue.full():
            self._queue.get_nowait()
            self.dropped += 1
        self._queue.put_nowait(event)

    def __aiter__(self) -> Listener:
        return self

    async def __anext__(self) -> FleetEvent:
        event = await self._queue.get() if self in self._bus.listeners else None
        if event is None:
            self.close()
            raise StopAsyncIteration
        return event

    def close(self) -> None:
        """Stop listening (the iteration ends)."""
        if self in self._bus.listeners:
            self._bus.listeners.remove(self)


Sink = Callable[[FleetEvent], None]


class EventBus:
    """Every event to every sink (all of them, in order: what must be kept, such as the
    flight's record) and to every listener (as many as its queue holds: displays)."""

    def __init__(self, maxsize: int = 1000) -> None:
        self.listeners: list[Listener] = []
        self._sinks: list[Sink] = []
        self._maxsize = maxsize
        self._closed = False

    @property
    def dropped(self) -> int:
        """Events the current listeners have lost."""
        return sum(listener.dropped for listener in self.listeners)

    def publish(self, event: FleetEvent) -> None:
        if not event.at:
            object.__setattr__(event, "at", asyncio.get_running_loop().time())
        for sink in self._sinks:
            try:
                sink(event)
            except Exception:  # a sink's fault must not stop the flight's tick
                log.exception("an event sink failed on %s", type(event).__name__)
        for listener in self.listeners:
            listener.put(event)

    def sink(self, sink: Sink) -> None:
        """Call `sink(event)` with every event from now on, in order, in `publish` itself:
        nothing is dropped, so `sink` must be quick and never wait (it runs in the flight's
        tick)."""
        self._sinks.append(sink)

    def listen(self) -> Listener:
        """Every event from now until `close()`, as many as the listener's queue holds."""
        listener = Listener(self, self._maxsize)
        if self._closed:
            listener.put(None)
        self.listeners.append(listener)
        return listener

    def close(self) -> None:
        """End every listener's iteration (after the events already queued)."""
        self._closed = True
        for listener in self.listeners:
            listener.put(None)
