"""A fleet flight: upload every mission, line the vehicles up, start them together, follow.

The plan's common t = 0 is the moment every vehicle, hovering at its altitude over
its start, leaves its take-off item. So the fleet first brings each vehicle up in
GUIDED (`prepare`), and only when all of them hold does it switch them all to AUTO
within the same loop iteration (`start`). If any vehicle fails before that, none
starts and the others hold or land (`Fallback`). During the flight (`follow`) each
vehicle's lag against its schedule is watched and vehicles ahead wait for a laggard
(`schedule_keeper`). Every per-vehicle answer is a `VehicleOutcome` that says what
happened; everything that happens is also published as an event.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Awaitable, Callable
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import Any, Generic, TypeVar

from gcs.fleet.events import (
    Aborted,
    EventBus,
    FleetEvent,
    FlightEnded,
    ItemReached,
    MissionsStarted,
    Paused,
    Progress,
    Resumed,
    StartCancelled,
    Uploaded,
    VehicleFailed,
    VehicleFinished,
    VehicleReady,
)
from gcs.fleet.route_tracker import RouteTracker, VehicleProgress
from gcs.fleet.schedule_keeper import KeepingPolicy, decide
from gcs.fleet.separation import SeparationTracker
from gcs.mavlink.actions import FlightActions, ReadinessPolicy
from gcs.mavlink.commands import CommandPolicy
from gcs.mavlink.errors import FlightError, GcsError
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Autopilot, Command, Mission
from gcs.mavlink.mission_protocol import MissionClient, TransferPolicy, UploadResult
from gcs.mission.build import Visit, fly_ideally
from gcs.mission.geodesy import distance_m

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


@dataclass(frozen=True)
class VehicleOutcome(Generic[T]):
    """One vehicle's answer to a fleet operation."""

    uav_id: str
    ok: bool
    detail: str
    value: T | None = None
    error: BaseException | None = None


@dataclass(frozen=True)
class FlightReport:
    completed: bool  # every vehicle flew its mission to the end and landed
    min_separation_m: float | None
    closest_pair: tuple[str, str] | None
    finished: tuple[str, ...]
    failed: dict[str, str]


@dataclass
class _Member:
    uav_id: str
    link: VehicleLink
    mission: Mission
    actions: FlightActions
    client: MissionClient
    tracker: RouteTracker

    @property
    def takeoff_seq(self) -> int:
        return next(
            k for k, item in enumerate(self.mission.items) if item.command == Command.NAV_TAKEOFF
        )

    @property
    def altitude_m(self) -> float:
        return float(self.mission.items[self.takeoff_seq].z)


class Fleet:
    """Several vehicles flying one plan; keyed by the plan's UAV ids."""

    def __init__(
        self,
        links: dict[str, VehicleLink],
        missions: dict[str, Mission],
        schedules: dict[str, list[Visit]] | None = None,
        settings: FleetSettings | None = None,
    ) -> None:
        if set(links) != set(missions):
            raise ValueError(f"links {sorted(links)} and missions {sorted(missions)} differ")
        self.settings = settings or FleetSettings()
        schedules = schedules or {uav: fly_ideally(m) for uav, m in missions.items()}
        self._members = {
            uav: self._member(uav, links[uav], missions[uav], schedules[uav]) for uav in links
        }
        self._bus = EventBus()
        self._paused: set[str] = set()
        self._failed: dict[str, str] = {}
        self._ready = False
        self._started = False
        self._aborted: str | None = None
        first = next(iter(self._members.values())).tracker.origin
        self._separation = SeparationTracker(*first)
        for member in self._members.values():
            self._track_separation(member)

    def _member(
        self, uav: str, link: VehicleLink, mission: Mission, visits: list[Visit]
    ) -> _Member:
        takeoff = next(i for i in mission.items if i.command == Command.NAV_TAKEOFF)
        s = self.settings
        return _Member(
            uav,
            link,
            mission,
            FlightActions(link, s.commands, s.readiness),
            MissionClient(link, s.transfer),
            RouteTracker(uav, visits, (takeoff.lat, takeoff.lon)),
        )

    # --- events and snapshots --------------------------------------------------------------

    def events(self) -> AsyncIterator[FleetEvent]:
        """Every event from now on; the iteration ends when the flight has ended."""
        return self._bus.listen()

    def progress(self) -> tuple[VehicleProgress, ...]:
        return tuple(
            m.tracker.progress(m.link.state, m.uav_id in self._paused)
            for m in self._members.values()
        )

    @property
    def min_separation_m(self) -> float | None:
        closest = self._separation.closest
        return closest.distance_m if closest else None

    # --- upload ------------------------------------------------------------------------------

    async def upload(self) -> dict[str, VehicleOutcome[UploadResult]]:
        """Every mission at once; each verified by reading it back."""
        outcomes = await self._each(lambda m: m.client.upload(m.mission), "upload")
        for uav, outcome in outcomes.items():
            self._bus.publish(Uploaded(uav, outcome.ok, outcome.detail))
        return outcomes

    # --- prepare and start ---------------------------------------------------------------------

    async def prepare(self) -> dict[str, VehicleOutcome[None]]:
        """Arm, take off and hold every vehicle at its altitude over its start.

        Nobody arms unless every vehicle is at its start. If one fails later, the others
        do the fallback and `start` will refuse.
        """
        outcomes = await self._each(self._check_at_start, "prepare")
        failed = tuple(uav for uav, o in outcomes.items() if not o.ok)
        if failed:
            self._bus.publish(StartCancelled(failed, "none armed"))
            return outcomes
        outcomes = await self._each(self._prepare_one, "prepare")
        failed = tuple(uav for uav, o in outcomes.items() if not o.ok)
        self._ready = not failed
        if failed:
            fallback = self.settings.fallback
            self._bus.publish(StartCancelled(failed, fallback.value))
            healthy = [m for m in self._members.values() if m.uav_id not in failed]
            await self._fall_back(healthy, fallback)
        return outcomes

    async def _prepare_one(self, member: _Member) -> None:
        await member.client.set_current(member.takeoff_seq)
        await member.actions.arm_and_take_off(member.altitude_m)
        await member.actions.wait_altitude(member.altitude_m)
        self._bus.publish(VehicleReady(member.uav_id, member.altitude_m))

    async def start(self) -> dict[str, VehicleOutcome[None]]:
        """AUTO + MISSION_START to every vehicle within one loop iteration (plan t = 0)."""
        if not self._ready:
            raise FlightError("the fleet is not ready: prepare() did not succeed for every vehicle")
        sent: list[float] = []
        loop = asyncio.get_running_loop()

        async def start_one(member: _Member) -> None:
            member.tracker.start(member.link.state.time_boot_ms)
            sent.append(loop.time())
            await member.actions.start_mission()

        outcomes = await self._each(start_one, "start")
        self._started = True
        spread = (max(sent) - min(sent)) * 1000 if sent else 0.0
        self._bus.publish(MissionsStarted(tuple(self._members), spread))
        failed = [uav for uav, o in outcomes.items() if not o.ok]
        if failed:
            await self.abort(self.settings.fallback.value, f"{', '.join(failed)} did not start")
        return outcomes

    # --- during the flight --------------------------------------------------------------------

    async def follow(self, timeout_s: float | None = None) -> FlightReport:
        """Watch the flight to its end (every vehicle landed), an abort, or `timeout_s`.

        `timeout_s` is in the vehicles' seconds (default: three times the longest
        schedule plus two minutes) and bounds the wall time too.
        """
        if not self._started:
            raise FlightError("follow() needs start() first")
        limit = timeout_s or self._default_timeout()
        loop = asyncio.get_running_loop()
        wall_deadline = loop.time() + limit
        next_progress = 0.0
        finished: set[str] = set()
        while self._aborted is None and len(finished) + len(self._failed) < len(self._members):
            self._note_items_and_ends(finished)
            self._note_link_losses()
            if self.settings.keep_schedule:
                await self._keep_schedule()
            if loop.time() >= next_progress:
                self._bus.publish(Progress(self.progress(), self.min_separation_m))
                next_progress = loop.time() + self.settings.progress_every_s
            if self._clock() > limit or loop.time() > wall_deadline:
                await self.abort(self.settings.fallback.value, f"flight exceeded {limit:.0f} s")
                break
            await asyncio.sleep(self.settings.tick_s)
        return self._end(finished)

    def _note_items_and_ends(self, finished: set[str]) -> None:
        for m in self._members.values():
            state = m.link.state
            for k in m.tracker.newly_passed(state):
                visit = m.tracker.visits[k]
                self._bus.publish(
                    ItemReached(m.uav_id, visit.seq, m.tracker.passed_at(k), visit.arrive)
                )
            if m.uav_id not in finished and m.tracker.finished(state):
                finished.add(m.uav_id)
                self._bus.publish(VehicleFinished(m.uav_id, self._distance_to_goal(m)))

    def _note_link_losses(self) -> None:
        for m in self._members.values():
            if not m.link.state.link_up and m.uav_id not in self._failed:
                self._failed[m.uav_id] = "link lost in flight"
                self._bus.publish(VehicleFailed(m.uav_id, "flight", "link lost"))

    async def _keep_schedule(self) -> None:
        decision = decide(list(self.progress()), self._paused, self.settings.keeping)
        if decision.pause:
            self._paused |= decision.pause
            self._bus.publish(
                Paused(
                    tuple(sorted(decision.pause)), decision.laggard or "", decision.laggard_lag_s
                )
            )
            await self._command_each(decision.pause, lambda m: m.actions.pause())
        if decision.resume:
            self._paused -= decision.resume
            self._bus.publish(Resumed(tuple(sorted(decision.resume))))
            await self._command_each(decision.resume, lambda m: m.actions.resume())

    def plan_time(self) -> float:
        """The plan's clock: seconds since the common start, on the vehicles' own time."""
        return self._clock() if self._started else 0.0

    def autopilot(self, uav_id: str) -> Autopilot:
        return self._members[uav_id].link.autopilot

    async def replace_missions(
        self, missions: dict[str, Mission], *, starts_at: float
    ) -> dict[str, VehicleOutcome[None]]:
        """Give flying vehicles new missions that begin at plan time `starts_at` where each
        vehicle is now (a live replan). Each is uploaded, verified and made current from
        its take-off item, which an airborne vehicle completes at once; the others fly on."""
        members = [self._members[uav] for uav in sorted(missions)]

        async def replace_one(member: _Member) -> None:
            mission = missions[member.uav_id]
            await member.client.upload(mission)
            visits = [
                replace(v, arrive=v.arrive + starts_at, leave=v.leave + starts_at)
                for v in fly_ideally(mission)
            ]
            takeoff = next(i for i in mission.items if i.command == Command.NAV_TAKEOFF)
            tracker = RouteTracker(member.uav_id, visits, (takeoff.lat, takeoff.lon))
            tracker.start_boot_ms = member.tracker.start_boot_ms
            member.link.state.reached.clear()  # seqs of the old mission mean nothing now
            member.mission, member.tracker = mission, tracker
            await member.client.set_current(member.takeoff_seq)

        return await self._each(replace_one, "replan", members)

    async def pause(self, uav_ids: set[str] | None = None) -> dict[str, VehicleOutcome[None]]:
        """Stop the vehicles where they are (DO_PAUSE_CONTINUE 0); all if `uav_ids` is None."""
        chosen = uav_ids or set(self._members)
        self._paused |= chosen
        return await self._command_each(chosen, lambda m: m.actions.pause())

    async def resume(self, uav_ids: set[str] | None = None) -> dict[str, VehicleOutcome[None]]:
        chosen = uav_ids or set(self._members)
        self._paused -= chosen
        return await self._command_each(chosen, lambda m: m.actions.resume())

    async def abort(
        self, mode: str = "rtl", reason: str = "aborted by the operator"
    ) -> dict[str, VehicleOutcome[None]]:
        """Every vehicle to RTL or LAND at once; the flight then ends."""
        fallback = Fallback(mode)
        self._aborted = reason
        self._bus.publish(Aborted(fallback.value, reason))
        return await self._fall_back(list(self._members.values()), fallback)

    async def fly(self) -> FlightReport:
        """upload, prepare, start and follow; stops at the first step a vehicle fails."""
        for step in (self.upload, self.prepare, self.start):
            outcomes = await step()
            failures = {uav: o.detail for uav, o in outcomes.items() if not o.ok}
            if failures:
                self._failed.update(failures)
                return self._end(set())
        return await self.follow()

    # --- helpers ---------------------------------------------------------------------------

    async def _fall_back(
        self, members: list[_Member], fallback: Fallback
    ) -> dict[str, VehicleOutcome[None]]:
        if fallback == Fallback.HOLD:
            return {m.uav_id: VehicleOutcome(m.uav_id, True, "holding") for m in members}
        action: Callable[[_Member], Awaitable[None]] = (
            (lambda m: m.actions.land())
            if fallback == Fallback.LAND
            else (lambda m: m.actions.return_to_launch())
        )
        ids = {m.uav_id for m in members}
        return await self._command_each(ids, action)

    async def _command_each(
        self, uav_ids: set[str] | frozenset[str], action: Callable[[_Member], Awaitable[Any]]
    ) -> dict[str, VehicleOutcome[Any]]:
        members = [self._members[uav] for uav in sorted(uav_ids)]
        return await self._each(action, "flight", members)

    async def _each(
        self,
        action: Callable[[_Member], Awaitable[T]],
        phase: str,
        members: list[_Member] | None = None,
    ) -> dict[str, VehicleOutcome[T]]:
        chosen = list(self._members.values()) if members is None else members
        results = await asyncio.gather(*(action(m) for m in chosen), return_exceptions=True)
        outcomes: dict[str, VehicleOutcome[T]] = {}
        for member, result in zip(chosen, results, strict=True):
            if isinstance(result, GcsError | OSError | ValueError | TimeoutError):
                self._bus.publish(VehicleFailed(member.uav_id, phase, str(result)))
                outcomes[member.uav_id] = VehicleOutcome(
                    member.uav_id, False, str(result), error=result
                )
            elif isinstance(result, BaseException):
                raise result
            else:
                outcomes[member.uav_id] = VehicleOutcome(member.uav_id, True, "ok", result)
        return outcomes

    def _track_separation(self, member: _Member) -> None:
        loop = asyncio.get_running_loop()

        def on_position(msg: Any) -> None:
            state = member.link.state
            if state.position is not None:
                self._separation.update(
                    member.uav_id,
                    state.position.lat,
                    state.position.lon,
                    state.velocity_n_e_m_s,
                    state.airborne,
                    loop.time(),
                    state.time_boot_ms,
                )

        member.link.on_message(on_position, ["GLOBAL_POSITION_INT"])

    async def _check_at_start(self, member: _Member) -> None:
        """The plan is safe only if every UAV starts where the plan starts it."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.settings.readiness.arm_timeout_s
        while (position := member.link.state.position) is None:  # no estimate yet
            if loop.time() > deadline:
                raise FlightError(f"{member.uav_id}: the vehicle reports no position")
            await asyncio.sleep(self.settings.tick_s)
        off = distance_m(position.lat, position.lon, *member.tracker.origin)
        if off > self.settings.start_tolerance_m:
            raise FlightError(
                f"{member.uav_id} is {off:.1f} m from its start "
                f"(limit {self.settings.start_tolerance_m} m): the plan is only safe "
                "from the start it was planned for"
            )

    def _distance_to_goal(self, member: _Member) -> float:
        pos, goal = member.link.state.position, member.tracker.visits[-1]
        return distance_m(pos.lat, pos.lon, goal.lat, goal.lon) if pos else float("nan")

    def _clock(self) -> float:
        return max(m.tracker.clock(m.link.state) for m in self._members.values())

    def _default_timeout(self) -> float:
        longest = max(
            (m.tracker.visits[-1].leave for m in self._members.values() if m.tracker.visits),
            default=0.0,
        )
        return 3 * longest + 120.0

    def _end(self, finished: set[str]) -> FlightReport:
        closest = self._separation.closest
        completed = self._aborted is None and len(finished) == len(self._members)
        self._bus.publish(
            FlightEnded(completed, self.min_separation_m, closest.pair if closest else None)
        )
        self._bus.close()
        return FlightReport(
            completed,
            self.min_separation_m,
            closest.pair if closest else None,
            tuple(sorted(finished)),
            dict(self._failed),
        )
