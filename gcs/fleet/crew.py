"""What every part of a fleet flight shares: its members, its order, its holds, its events.

The fleet's roles (launch, follow, interventions, live replanning) are functions of this
one record rather than methods of one large class; `Fleet` is the facade over them.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable, Iterable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import TypeVar

from gcs.fleet.events import EventBus, VehicleFailed
from gcs.fleet.gatekeeper import GateCommander, Gatekeeper
from gcs.fleet.member import Member
from gcs.fleet.outcome import VehicleOutcome, run_each
from gcs.fleet.route_tracker import VehicleProgress
from gcs.fleet.separation import SeparationTracker, SeparationWatch
from gcs.mavlink.actions import ReadinessPolicy
from gcs.mavlink.commands import CommandPolicy
from gcs.mavlink.mission_protocol import TransferPolicy
from gcs.mission.flight_plan import FlightPlan
from gcs.mission.motion import Gate, StoppingRule

T = TypeVar("T")


class Fallback(StrEnum):
    """What the vehicles that are fine do when the flight cannot go on."""

    HOLD = "hold"
    LAND = "land"
    RTL = "rtl"


@dataclass(frozen=True)
class FleetSettings:
    fallback: Fallback = Fallback.HOLD
    keep_order: bool = True  # keep the plan's passing order (off: each flies alone)
    stopping: StoppingRule = field(default_factory=StoppingRule)
    transfer: TransferPolicy = field(default_factory=TransferPolicy)
    commands: CommandPolicy = field(default_factory=CommandPolicy)
    readiness: ReadinessPolicy = field(default_factory=ReadinessPolicy)
    start_tolerance_m: float = 3.0  # how far from its start a vehicle may be when it arms
    # as it is; further, but inside its start cell, it flies to its start once airborne
    # (ArduCopter; see gcs/fleet/launch.py), within start_hold_m and start_move_timeout_s
    start_hold_m: float = 0.5
    start_move_timeout_s: float = 60.0
    fence_action: int = 1  # ArduCopter's FENCE_ACTION for a flight with a geofence: RTL
    link_loss_brake_s: float = 2.0  # a vehicle that has not heard us for this long
    # brakes (ArduCopter's GCS failsafe, `link_loss.py`); 0 leaves its own failsafe be
    tick_s: float = 0.05  # seconds between looks at the fleet
    progress_every_s: float = 0.25  # seconds between Progress events


@dataclass
class Crew:
    members: dict[str, Member]
    settings: FleetSettings
    flight: FlightPlan
    gatekeeper: Gatekeeper
    commander: GateCommander
    bus: EventBus = field(default_factory=EventBus)
    held: set[str] = field(default_factory=set)  # by the operator: only the operator moves it
    replanning: set[str] = field(default_factory=set)  # stopped for their new missions
    failed: dict[str, str] = field(default_factory=dict)  # uav -> why it cannot go on
    withdrawn: dict[str, str] = field(default_factory=dict)  # uav -> "land" / "rtl"
    aborted: str | None = None  # why, once aborted
    ready: bool = False  # every vehicle holds at its start altitude
    started: bool = False
    starting: set[str] = field(default_factory=set)  # told to start, not answered yet
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
        gates, waits = self.gatekeeper.gates, self.gatekeeper.waits_for
        return tuple(
            m.tracker.progress(
                m.link.state,
                paused=m.uav_id in self.held or gates[m.uav_id] != Gate.GO,
                held=m.uav_id in self.held,
                withdrawn=m.uav_id in self.withdrawn,
                waits_for=waits[m.uav_id],
                along_m=m.along.s,
            )
            for m in self.members.values()
        )

    def clock(self) -> float:
        """The plan's clock: seconds since the common start, on the vehicles' own time."""
        if not self.started:
            return 0.0
        return max(m.tracker.clock(m.link.state) for m in self.members.values())
