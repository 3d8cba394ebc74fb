"""A fleet flight: upload every mission, line the vehicles up, start them together, follow.

The plan's common t = 0 is the moment every vehicle, hovering at its altitude over its
start, leaves its take-off item (`launch`). During the flight (`follower`) the plan's
passing order is kept: a vehicle that would come too close to another before that one
has passed is stopped in time and let go when it has (`gatekeeper`); the operator can
hold, continue, withdraw one vehicle or abort the whole fleet at any moment
(`interventions`), and an operator's hold is lifted by nobody else. A flight nobody
followed for a while is taken up again where its vehicles are (`resumption`). Every
per-vehicle answer is a `VehicleOutcome`; everything that happens is also an event.
`close()` releases what the flight registered on its links, so a finished flight leaves
nothing behind.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Iterable

from gcs.fleet import interventions, launch, resumption
from gcs.fleet.crew import Crew, Fallback, FleetSettings
from gcs.fleet.events import EventBus, FleetEvent, Listener, Uploaded, VehicleFailed
from gcs.fleet.follower import FlightReport, Follower
from gcs.fleet.gatekeeper import GateCommander, Gatekeeper
from gcs.fleet.geofence import GeoFence, enable_fence, upload_fence
from gcs.fleet.link_loss import brake_on_link_loss
from gcs.fleet.member import Member
from gcs.fleet.outcome import VehicleOutcome
from gcs.fleet.path_progress import PathProgress
from gcs.fleet.route_tracker import RouteTracker, VehicleProgress
from gcs.fleet.separation import SeparationTracker, SeparationWatch
from gcs.mavlink import ardupilot
from gcs.mavlink.actions import FlightActions
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Autopilot, Mission
from gcs.mavlink.mission_protocol import MissionClient, UploadResult
from gcs.mavlink.parameters import set_in_units
from gcs.mission.build import takeoff_index
from gcs.mission.fence import FencePlan
from gcs.mission.flight_plan import FlightPlan, continued
from gcs.mission.flight_timing import FlightStuck
from gcs.mission.motion import Gate
from planner.model.trajectory import Trajectory

CATCH_UP_S = 15.0
"""Seconds of its cruise a vehicle may have flown on from where its replanned path starts
(a replan and its upload over a lossy link: 3 s in fuzzed flight 3034)."""

__all__ = ["Fallback", "Fleet", "FleetSettings", "FlightReport", "VehicleOutcome"]


class Fleet:
    """Several vehicles flying one plan; keyed by the plan's UAV ids."""

    def __init__(
        self,
        links: dict[str, VehicleLink],
        flight: FlightPlan,
        settings: FleetSettings | None = None,
        fence: FencePlan | None = None,
    ) -> None:
        """`fence`: a geographic scenario's fence and rally points, set up on every
        vehicle with its mission (`geofence.py`), with `settings.fence_action`."""
        missions = flight.missions
        if set(links) != set(missions):
            raise ValueError(f"links {sorted(links)} and missions {sorted(missions)} differ")
        settings = settings or FleetSettings()
        self.geofence = None if fence is None else GeoFence(fence, settings.fence_action)
        members = {uav: _member(uav, links[uav], flight, settings) for uav in links}
        gatekeeper = Gatekeeper(flight.order, flight.limits, settings.stopping)
        bus = EventBus()
        commander = GateCommander(
            {uav: m.actions for uav, m in members.items()},
            settings.stopping,
            lambda uav: flight.cruise_at(uav, members[uav].along.s),
            lambda uav, why: bus.publish(VehicleFailed(uav, "flight", why)),
        )
        self.crew = Crew(members, settings, flight, gatekeeper, commander, bus)
        first = next(iter(members.values())).tracker.origin
        self.crew.separation = SeparationTracker(*first)
        self.crew.watch = SeparationWatch(self.crew.separation)
        for member in members.values():
            self.crew.watch.watch(member.uav_id, member.link)
        self._follower = Follower(self.crew)

    @property
    def settings(self) -> FleetSettings:
        return self.crew.settings

    # --- what the flight shows ---------------------------------------------------------

    def events(self) -> Listener:
        """Every event from now on, as many as a bounded queue holds (`dropped` counts
        the others); the iteration ends when the flight is closed."""
        return self.crew.bus.listen()

    def record(self, sink: Callable[[FleetEvent], None]) -> None:
        """Hand every event from now on to `sink`, in order, none dropped: it is called
        in the flight's tick, so it must be quick and never wait."""
        self.crew.bus.sink(sink)

    def progress(self) -> tuple[VehicleProgress, ...]:
        return self.crew.progress()

    @property
    def min_separation_m(self) -> float | None:
        return self._follower.min_separation_m

    def places_on_plan(self) -> dict[str, float]:
        """Where each vehicle is on its own plan: the plan's time at its place along its
        path, from where a live replan continues it. (A vehicle's `plan_time_s` is on its
        timed flight's clock, which the waits, speed changes and landings put behind the
        plan's: taken for the plan's, it put a held vehicle of fuzzed flight 3034 seconds
        ahead of where it was.)"""
        paths = self.crew.flight.paths
        return {
            uav: paths[uav].leaves(m.along.s) - paths[uav].ahead_s
            for uav, m in self.crew.members.items()
        }

    def stopping_places(self) -> dict[str, tuple[float, float]]:
        """Where each vehicle under way would come to rest on its path if stopped now
        (metres, the grid's frame): a vehicle a live replan changes is stopped before
        its new mission is uploaded (`replan`), so that is where its new path must
        begin. Begun where the vehicle was, it stopped 1.9 m into its new path, 1.1 m
        past where the new order had it wait for another (fuzzed flight 3401: 5.82 m)."""
        crew, rule = self.crew, self.crew.gatekeeper.rule
        places = {}
        for uav, m in crew.members.items():
            if not self._stops_for_replan(uav):
                continue
            limits = crew.flight.limits[uav]
            room = rule.needed_m(m.along.speed, m.along.accel, limits) - rule.buffer_m
            places[uav] = m.along.path.position(m.along.s + room)
        return places

    def plan_time(self) -> float:
        """The plan's clock: seconds since the common start, on the vehicles' own time."""
        return self.crew.clock()

    def autopilot(self, uav_id: str) -> Autopilot:
        return self.crew.members[uav_id].link.autopilot

    # --- the flight, step by step -------------------------------------------------------

    async def upload(self) -> dict[str, VehicleOutcome[UploadResult]]:
        """Every mission at once; each verified by reading it back, and on ArduPilot with
        the parameters that carry what its stored items cannot (the acceptance radius)
        and its brake on losing us (`link_loss`). With a geofence, each vehicle's fence
        and rally points go first and the fence is enabled last (a vehicle whose fence
        fails gets nothing else)."""
        geofence, brake_after_s = self.geofence, self.settings.link_loss_brake_s

        async def upload_one(member: Member) -> UploadResult:
            if geofence is not None:
                await upload_fence(member.client, geofence, member.altitude_m)
            result = await _upload(member)
            silent_s = await brake_on_link_loss(member.link, brake_after_s)
            if silent_s is not None:
                self.crew.gatekeeper.silent_s[member.uav_id] = silent_s
            if geofence is not None:
                await enable_fence(member.link, geofence)
            return result

        outcomes = await self.crew.each(upload_one, "upload")
        for uav, outcome in outcomes.items():
            self.crew.bus.publish(Uploaded(uav, outcome.ok, outcome.detail))
        return outcomes

    async def prepare(self) -> dict[str, VehicleOutcome[None]]:
        return await launch.prepare(self.crew)

    async def start(self) -> dict[str, VehicleOutcome[None]]:
        return await self._follower.starting(launch.start(self.crew))

    async def resume(self) -> dict[str, VehicleOutcome[str]]:
        """Take up a flight its vehicles are already flying (nobody followed it for a
        while): each found where it is and stopped, to be let go in the passing order by
        `follow` (`resumption`)."""
        return await resumption.resume(self.crew)

    async def follow(self, timeout_s: float | None = None) -> FlightReport:
        if not self.crew.started:
            raise ValueError("follow() needs start() first")
        return await self._follower.follow(timeout_s)

    async def fly(self) -> FlightReport:
        """upload, prepare, start and follow; stops at the first step a vehicle fails."""
        try:
            for step in (self.upload, self.prepare, self.start):
                outcomes = await step()
                failures = {uav: o.detail for uav, o in outcomes.items() if not o.ok}
                if failures:
                    self.crew.failed.update(failures)
                    return self._follower.report()
            return await self.follow()
        finally:
            self.close()

    # --- the operator --------------------------------------------------------------------

    async def hold(self, uav_ids: set[str] | None = None) -> dict[str, VehicleOutcome[str]]:
        """The operator's hold (all vehicles if `uav_ids` is None)."""
        return await interventions.hold(self.crew, uav_ids)

    async def continue_(self, uav_ids: set[str] | None = None) -> dict[str, VehicleOutcome[None]]:
        """The operator's continue."""
        return await interventions.continue_(self.crew, uav_ids)

    async def withdraw(self, uav_id: str, mode: str) -> VehicleOutcome[None]:
        """One vehicle lands ("land") or returns home ("rtl") and leaves the plan."""
        return await interventions.withdraw(self.crew, uav_id, mode)

    async def abort(
        self, mode: str = "rtl", reason: str = "aborted by the operator"
    ) -> dict[str, VehicleOutcome[None]]:
        return await interventions.abort(self.crew, mode, reason)

    def held_by_operator(self) -> set[str]:
        return set(self.crew.held)

    # --- live replanning -------------------------------------------------------------------

    async def replan(
        self,
        missions: dict[str, Mission],
        changed: dict[str, Trajectory],
        *,
        starts_at: float,
        checked: FlightPlan,
    ) -> dict[str, VehicleOutcome[None]]:
        """Give flying vehicles new missions flying `changed` trajectories (cells, the
        flight's clock) from where each is now (a live replan). Each is uploaded and
        verified; then the fleet follows the rest of the flight: every vehicle from where
        it is, the new passing order among them, and the new missions made current from
        their take-off item (which an airborne vehicle completes at once). `checked` is
        that rest as `continuation` made it before the uploads (its order can be kept)."""

        async def upload_one(member: Member) -> None:
            await member.client.upload(missions[member.uav_id])
            self._gate_again(member.uav_id)

        async def start_one(member: Member) -> None:
            await member.client.set_current(member.takeoff_seq)
            self._gate_again(member.uav_id)

        crew = self.crew
        self._stop_for_replan(missions)
        await self._keep_held_for_replan(missions)
        crew.gatekeeper.expect(
            checked.order,
            {
                uav: rest.skipped_m - crew.flight.paths[uav].skipped_m
                for uav, rest in checked.paths.items()
                if uav not in missions
            },
        )
        try:
            outcomes = await crew.each(upload_one, "replan", missions)
            taken = {uav for uav, outcome in outcomes.items() if outcome.ok}
            along = self.along()  # where each vehicle is now that the uploads are done
            committed = self.committed()

            def rest() -> FlightPlan:
                try:
                    return self.continuation(along, changed, missions, starts_at, taken, committed)
                except FlightStuck:
                    if taken != set(missions):
                        raise
                    return checked  # the same missions' order, from a moment earlier

            self._follow(await asyncio.to_thread(rest), taken, starts_at)
            started = await crew.each(start_one, "replan", taken)
            return {**outcomes, **{uav: o for uav, o in started.items() if not o.ok}}
        finally:
            crew.replanning.clear()
            crew.gatekeeper.expect_nothing()

    def along(self) -> dict[str, float]:
        """Where each vehicle is along its path, in metres."""
        return {uav: m.along.s for uav, m in self.crew.members.items()}

    def committed(self) -> dict[str, float]:
        """How far on along its path each vehicle would go if told to stop now, metres:
        from its speed, on a track flown at its approach's speed if it approaches a
        limit, else its mission's."""
        flight, keeper = self.crew.flight, self.crew.gatekeeper
        committed = {}
        for uav, m in self.crew.members.items():
            track = keeper.approach.get(uav) if keeper.gates[uav] == Gate.CREEP else None
            committed[uav] = flight.limits[uav].stopping_distance(
                m.along.speed, m.along.accel, track_m_s=track or flight.cruise_at(uav, m.along.s)
            )
        return committed

    def continuation(
        self,
        along: dict[str, float],
        changed: dict[str, Trajectory],
        missions: dict[str, Mission],
        starts_at: float,
        taken: set[str] | None = None,
        committed: dict[str, float] | None = None,
    ) -> FlightPlan:
        """The rest of the flight from `along` with the new missions of `taken` (all of
        `missions` if None), timed: FlightStuck if its passing order cannot be kept. The
        vehicles it keeps on their paths lead what they would reach before they could
        stop (`committed`, from `committed()` when `along` was taken)."""
        taken = set(missions) if taken is None else taken
        flight = continued(
            self.crew.flight,
            along,
            {uav: changed[uav] for uav in taken},
            {uav: missions[uav] for uav in taken},
            starts_at,
            committed or {},
        )
        _ = flight.timed
        return flight

    def _stop_for_replan(self, uav_ids: Iterable[str]) -> None:
        """The vehicles about to get new missions stop where they are until the order
        lets them fly them: the new ones begin where each comes to rest
        (`stopping_places`), and uploads over lossy links take seconds (fuzzed flight
        3401: 8.5 s, in which one flew 25 m on along its old path, into the way of
        another). They brake out of AUTO: paused, the new mission and its new current
        item would each send them on (3401 again: from rest up to 2.2 m/s, 2.9 m past
        the place the new order had one wait at)."""
        crew = self.crew
        for uav in filter(self._stops_for_replan, uav_ids):
            crew.replanning.add(uav)
            crew.gatekeeper.stop(uav)
            crew.commander.brake(uav)

    async def _keep_held_for_replan(self, uav_ids: Iterable[str]) -> None:
        """The vehicles the operator holds that are about to get new missions brake out of
        AUTO (the operator's continue sends them on in AUTO again): paused, the new
        mission and its start made current would send them on, and nothing would stop
        them (fuzzed flight 11679: uav3, held, flew its new mission during the hold, out
        of the order, and came within 0.59 m of uav4 after the continue)."""
        crew = self.crew
        held = [uav for uav in uav_ids if uav in crew.held and not self._landing(uav)]
        await crew.each(lambda m: m.actions.brake_in_mission(), "hold", held)

    def _landing(self, uav_id: str) -> bool:
        member = self.crew.members[uav_id]
        return member.tracker.landing(member.link.state)

    def _stops_for_replan(self, uav_id: str) -> bool:
        """Not one the operator holds (`_keep_held_for_replan`), nor one coming down
        (ArduCopter will not stop it)."""
        return uav_id not in self.crew.held and not self._landing(uav_id)

    def _gate_again(self, uav_id: str) -> None:
        """A new mission, or its start made current, gives up a pause (ArduCopter SITL
        flew on 13.2 m after MISSION_SET_CURRENT while paused): a vehicle the order stops
        or slows is brought to its gate again at once (fuzzed flight 3034). One braked
        out of its mission for the replan (`_stop_for_replan`) is not moved by either."""
        crew, gatekeeper = self.crew, self.crew.gatekeeper
        gate = gatekeeper.gates[uav_id]
        if uav_id not in crew.held and uav_id not in crew.replanning and gate != Gate.GO:
            crew.commander.restarted(uav_id, gate, gatekeeper.approach.get(uav_id))

    def _follow(self, flight: FlightPlan, changed: set[str], starts_at: float) -> None:
        """From now on: `flight`'s paths and order; new missions for `changed`."""
        crew = self.crew
        crew.flight = flight
        crew.gatekeeper.replan(flight.order, flight.limits)
        for uav, member in crew.members.items():
            if uav not in changed:  # the rest of its path
                member.along.carry_on(flight.paths[uav])
                continue
            flown_since = CATCH_UP_S * flight.limits[uav].speed_m_s
            member.along.restart(flight.paths[uav], member.link.state, flown_since)
            visits = [v.shifted(starts_at) for v in flight.visits(uav)]
            member.follow_mission(flight.missions[uav], visits)

    # --- the end ------------------------------------------------------------------------

    def close(self) -> None:
        """Release the links' callbacks and end every event listener; idempotent."""
        if self.crew.watch is not None:
            self.crew.watch.close()
        self.crew.bus.close()


async def _upload(member: Member) -> UploadResult:
    result = await member.client.upload(member.mission)
    radius = ardupilot.acceptance_radius_m(member.mission)
    if member.link.autopilot == Autopilot.ARDUPILOT and radius is not None:
        await set_in_units(member.link, ardupilot.RADIUS_PARAMETERS, radius)
    return result


def _member(uav: str, link: VehicleLink, flight: FlightPlan, settings: FleetSettings) -> Member:
    mission = flight.missions[uav]
    takeoff = mission.items[takeoff_index(mission.items)]
    client = MissionClient(link, settings.transfer)
    return Member(
        uav,
        link,
        mission,
        FlightActions(link, settings.commands, settings.readiness, client),
        client,
        RouteTracker(uav, flight.visits(uav), (takeoff.lat, takeoff.lon)),
        PathProgress(flight.paths[uav], flight.frame, flight.limits[uav].speed_m_s),
    )
