"""What every part of a fleet flight shares: its members, their holds, its events.

The fleet's roles (launch, follow, interventions, live replanning) are functions of this
one record rather than methods of one large class; `Fleet` is the facade over them.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable, Iterable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import TypeVar

from gcs.fleet.events import EventBus, VehicleFailed
from gcs.fleet.holds import Holds
from gcs.fleet.member import Member
from gcs.fleet.outcome import VehicleOutcome, run_each
from gcs.fleet.route_tracker import VehicleProgress
from gcs.fleet.schedule_keeper import KeepingPolicy
from gcs.fleet.separation import SeparationTracker, SeparationWatch
from gcs.mavlink.actions import ReadinessPolicy
from gcs.mavlink.commands import CommandPolicy
from gcs.mavlink.mission_protocol import TransferPolicy

T = TypeVar("T")


class Fallback(StrEnum):
    """What the vehicles that are fine do when the flight cannot go on."""

    HOLD = "hold"
    LAND = "land"
    RTL = "rtl"


@dataclass(frozen=True)
class FleetSettings:
    fallback: Fallback = Fallback.HOLD
    keep_schedule: bool = True
    keeping: KeepingPolicy = field(default_factory=KeepingPolicy)
    transfer: TransferPolicy = field(default_factory=TransferPolicy)
    commands: CommandPolicy = field(default_factory=CommandPolicy)
    readiness: ReadinessPolicy = field(default_factory=ReadinessPolicy)
    start_tolerance_m: float = 3.0  # how far from its start a vehicle may be when it arms
    tick_s: float = 0.02  # wall seconds between looks at the fleet
    progress_every_s: float = 0.25  # wall seconds between Progress events


@dataclass
class Crew:
    members: dict[str, Member]
    settings: FleetSettings
    bus: EventBus = field(default_factory=EventBus)
    holds: Holds = field(default_factory=Holds)
    failed: dict[str, str] = field(default_factory=dict)  # uav -> why it cannot go on
    withdrawn: dict[str, str] = field(default_factory=dict)  # uav -> "land" / "rtl"
    aborted: str | None = None  # why, once aborted
    ready: bool = False  # every vehicle holds at its start altitude
    started: bool = False
    separation: SeparationTracker | None = None
    watch: SeparationWatch | None = None

    def chosen(self, uav_ids: Iterable[str] | None = None) -> list[Member]:
        ids = self.members if uav_ids is None else sorted(uav_ids)
        return [self.members[uav] for uav in ids]

    async def each(
        self,
        action: Callable[[Member], Awaitable[T]],
        phase: str,
        uav_ids: Iterable[str] | None = None,
    ) -> dict[str, VehicleOutcome[T]]:
        """`action` on the chosen members at once; each failure is also an event."""

        def failed(uav: str, message: str) -> None:
            self.bus.publish(VehicleFailed(uav, phase, message))

        return await run_each(self.chosen(uav_ids), action, failed)

    def progress(self) -> tuple[VehicleProgress, ...]:
        stopped, held = self.holds.stopped, self.holds.operator
        return tuple(
            m.tracker.progress(
                m.link.state,
                paused=m.uav_id in stopped,
                held=m.uav_id in held,
                withdrawn=m.uav_id in self.withdrawn,
            )
            for m in self.members.values()
        )

    def clock(self) -> float:
        """The plan's clock: seconds since the common start, on the vehicles' own time."""
        if not self.started:
            return 0.0
        return max(m.tracker.clock(m.link.state) for m in self.members.values())
