"""What the fleet reports while it works: plain dataclasses, fanned out to every listener.

A terminal display, a test or a WebSocket each call `EventBus.listen()` and read the
same events at their own pace; a slow listener loses its oldest events, never stalls
the flight.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from dataclasses import dataclass, field

from gcs.fleet.route_tracker import VehicleProgress


@dataclass(frozen=True)
class FleetEvent:
    """Base of every event; `at` is the loop time it happened."""

    at: float = field(default=0.0, kw_only=True)


@dataclass(frozen=True)
class Uploaded(FleetEvent):
    uav_id: str
    ok: bool
    detail: str


@dataclass(frozen=True)
class VehicleReady(FleetEvent):
    """Armed, airborne and holding at its altitude over its start."""

    uav_id: str
    altitude_m: float


@dataclass(frozen=True)
class VehicleFailed(FleetEvent):
    uav_id: str
    phase: str  # "upload", "prepare", "start", "flight"
    message: str


@dataclass(frozen=True)
class MissionsStarted(FleetEvent):
    uav_ids: tuple[str, ...]
    spread_ms: float  # between the first and the last start command sent
    timed_duration_s: float = 0.0  # to the last arrival, as the timed flight has it


@dataclass(frozen=True)
class StartCancelled(FleetEvent):
    """A vehicle failed before the start: nobody starts, the others do `fallback`."""

    failed: tuple[str, ...]
    fallback: str


@dataclass(frozen=True)
class ItemReached(FleetEvent):
    uav_id: str
    seq: int
    plan_time_s: float  # when it got there, on the plan's clock
    scheduled_s: float  # when the plan said it would


@dataclass(frozen=True)
class Waiting(FleetEvent):
    """A vehicle stops (or approaches slowly, "creep") to let another pass first, as the
    plan has it: it may not go beyond `gap_m` metres ahead until `waits_for` has passed."""

    uav_id: str
    waits_for: str
    how: str  # "stop" or "creep"
    gap_m: float
    speed_m_s: float | None = None  # of an approach


@dataclass(frozen=True)
class WaitOver(FleetEvent):
    """The vehicle it waited for is out of its way: it flies on."""

    uav_id: str


@dataclass(frozen=True)
class OperatorHeld(FleetEvent):
    """The operator stopped these vehicles; only the operator's continue moves them."""

    uav_ids: tuple[str, ...]


@dataclass(frozen=True)
class OperatorContinued(FleetEvent):
    uav_ids: tuple[str, ...]


@dataclass(frozen=True)
class Withdrawn(FleetEvent):
    """The operator sent one vehicle down (land) or home (rtl): it leaves the plan."""

    uav_id: str
    mode: str


@dataclass(frozen=True)
class VehicleLinkRegained(FleetEvent):
    uav_id: str


@dataclass(frozen=True)
class Progress(FleetEvent):
    vehicles: tuple[VehicleProgress, ...]
    min_separation_m: float | None


@dataclass(frozen=True)
class VehicleFinished(FleetEvent):
    uav_id: str
    distance_to_goal_m: float


@dataclass(frozen=True)
class Aborted(FleetEvent):
    mode: str
    reason: str


@dataclass(frozen=True)
class FlightEnded(FleetEvent):
    completed: bool
    min_separation_m: float | None
    closest_pair: tuple[str, str] | None
    outcome: str = "landed"  # "landed", "aborted", "timeout", "failed"


class EventBus:
    def __init__(self, maxsize: int = 1000) -> None:
        self._queues: list[asyncio.Queue[FleetEvent | None]] = []
        self._maxsize = maxsize
        self._closed = False

    def publish(self, event: FleetEvent) -> None:
        if not event.at:
            object.__setattr__(event, "at", asyncio.get_running_loop().time())
        for queue in self._queues:
            if queue.full():
                queue.get_nowait()
            queue.put_nowait(event)

    async def listen(self) -> AsyncIterator[FleetEvent]:
        """Every event from now until `close()`."""
        queue: asyncio.Queue[FleetEvent | None] = asyncio.Queue(self._maxsize)
        self._queues.append(queue)
        try:
            while not self._closed or not queue.empty():
                event = await queue.get()
                if event is None:
                    return
                yield event
        finally:
            self._queues.remove(queue)

    def close(self) -> None:
        """End every listener's iteration (after the events already queued)."""
        self._closed = True
        for queue in self._queues:
            if queue.full():
                queue.get_nowait()
            queue.put_nowait(None)
