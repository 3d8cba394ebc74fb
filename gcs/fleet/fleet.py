"""A fleet flight: upload every mission, line the vehicles up, start them together, follow.

The plan's common t = 0 is the moment every vehicle, hovering at its altitude over its
start, leaves its take-off item (`launch`). During the flight (`follower`) each
vehicle's lag against its schedule is watched and vehicles ahead wait for a laggard
(`schedule_keeper`); the operator can hold, continue, withdraw one vehicle or abort the
whole fleet at any moment (`interventions`), and an operator's hold is never lifted by
the schedule keeper (`holds`). Every per-vehicle answer is a `VehicleOutcome`; everything
that happens is also an event. `close()` releases what the flight registered on its
links, so a finished flight leaves nothing behind.
"""

from __future__ import annotations

from collections.abc import AsyncIterator

from gcs.fleet import interventions, launch
from gcs.fleet.crew import Crew, Fallback, FleetSettings
from gcs.fleet.events import FleetEvent, Uploaded
from gcs.fleet.follower import FlightReport, Follower
from gcs.fleet.member import Member
from gcs.fleet.outcome import VehicleOutcome
from gcs.fleet.route_tracker import RouteTracker, VehicleProgress
from gcs.fleet.separation import SeparationTracker, SeparationWatch
from gcs.mavlink import ardupilot
from gcs.mavlink.actions import FlightActions
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Autopilot, Mission
from gcs.mavlink.mission_protocol import MissionClient, UploadResult
from gcs.mavlink.parameters import set_in_units
from gcs.mission.build import Visit, fly_ideally, takeoff_index

__all__ = ["Fallback", "Fleet", "FleetSettings", "FlightReport", "VehicleOutcome"]


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
        settings = settings or FleetSettings()
        schedules = schedules or {uav: fly_ideally(m) for uav, m in missions.items()}
        members = {
            uav: _member(uav, links[uav], missions[uav], schedules[uav], settings) for uav in links
        }
        self.crew = Crew(members, settings)
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

    def events(self) -> AsyncIterator[FleetEvent]:
        """Every event from now on; the iteration ends when the flight is closed."""
        return self.crew.bus.listen()

    def progress(self) -> tuple[VehicleProgress, ...]:
        return self.crew.progress()

    @property
    def min_separation_m(self) -> float | None:
        return self._follower.min_separation_m

    def plan_time(self) -> float:
        """The plan's clock: seconds since the common start, on the vehicles' own time."""
        return self.crew.clock()

    def autopilot(self, uav_id: str) -> Autopilot:
        return self.crew.members[uav_id].link.autopilot

    # --- the flight, step by step -------------------------------------------------------

    async def upload(self) -> dict[str, VehicleOutcome[UploadResult]]:
        """Every mission at once; each verified by reading it back, and on ArduPilot with
        the parameters that carry what its stored items cannot (the acceptance radius)."""
        outcomes = await self.crew.each(_upload, "upload")
        for uav, outcome in outcomes.items():
            self.crew.bus.publish(Uploaded(uav, outcome.ok, outcome.detail))
        return outcomes

    async def prepare(self) -> dict[str, VehicleOutcome[None]]:
        return await launch.prepare(self.crew)

    async def start(self) -> dict[str, VehicleOutcome[None]]:
        return await launch.start(self.crew)

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

    async def pause(self, uav_ids: set[str] | None = None) -> dict[str, VehicleOutcome[str]]:
        """The operator's hold (all vehicles if `uav_ids` is None)."""
        return await interventions.hold(self.crew, uav_ids)

    async def resume(self, uav_ids: set[str] | None = None) -> dict[str, VehicleOutcome[None]]:
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
        return set(self.crew.holds.operator)

    # --- live replanning -------------------------------------------------------------------

    async def replace_missions(
        self, missions: dict[str, Mission], *, starts_at: float
    ) -> dict[str, VehicleOutcome[None]]:
        """Give flying vehicles new missions that begin at plan time `starts_at` where each
        vehicle is now (a live replan). Each is uploaded, verified and made current from
        its take-off item, which an airborne vehicle completes at once; the others fly on."""

        async def replace_one(member: Member) -> None:
            mission = missions[member.uav_id]
            await member.client.upload(mission)
            visits = [v.shifted(starts_at) for v in fly_ideally(mission)]
            member.follow_mission(mission, visits)
            await member.client.set_current(member.takeoff_seq)

        return await self.crew.each(replace_one, "replan", missions)

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


def _member(
    uav: str, link: VehicleLink, mission: Mission, visits: list[Visit], settings: FleetSettings
) -> Member:
    takeoff = mission.items[takeoff_index(mission.items)]
    return Member(
        uav,
        link,
        mission,
        FlightActions(link, settings.commands, settings.readiness),
        MissionClient(link, settings.transfer),
        RouteTracker(uav, visits, (takeoff.lat, takeoff.lon)),
    )
