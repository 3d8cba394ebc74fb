"""One vehicle of a fleet flight: its link, its mission and what follows it on the plan."""

from __future__ import annotations

from dataclasses import dataclass

from gcs.fleet.path_progress import PathProgress
from gcs.fleet.route_tracker import RouteTracker
from gcs.mavlink.actions import FlightActions
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Mission
from gcs.mavlink.mission_protocol import MissionClient
from gcs.mission.build import Visit, first_leg_index, takeoff_index


@dataclass
class Member:
    uav_id: str
    link: VehicleLink
    mission: Mission
    actions: FlightActions
    client: MissionClient
    tracker: RouteTracker  # the mission's items: reached, and when the timed flight does
    along: PathProgress  # metres along the path: what the passing order speaks of

    def __post_init__(self) -> None:
        self.actions.first_leg_seq = first_leg_index(self.mission.items)

    @property
    def takeoff_seq(self) -> int:
        return takeoff_index(self.mission.items)

    @property
    def altitude_m(self) -> float:
        return float(self.mission.items[self.takeoff_seq].z)

    def follow_mission(self, mission: Mission, visits: list[Visit]) -> None:
        """From now on the vehicle flies `mission` (a live replan), on the same clock."""
        takeoff = mission.items[takeoff_index(mission.items)]
        tracker = RouteTracker(self.uav_id, visits, (takeoff.lat, takeoff.lon))
        tracker.start_boot_ms = self.tracker.start_boot_ms
        self.link.state.reached.clear()  # seqs of the old mission mean nothing now
        self.mission, self.tracker = mission, tracker
        self.actions.first_leg_seq = first_leg_index(mission.items)
