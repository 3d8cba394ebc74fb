"""The geofence and rally points of a flight, set up on each vehicle as a backstop.

A flight on a geographic scenario gives every vehicle, before its mission, the
scenario's fence (the FENCE mission type: the area as an inclusion polygon, the no-fly
zones as exclusions) and rally points (RALLY), each read back and compared with what
ArduPilot keeps of it; after the mission, on ArduPilot, `FENCE_TYPE` 4 (the uploaded
polygons and circles only: not ArduCopter's default altitude fence and 300 m circle
round home), `FENCE_ACTION` (the operator's choice; ArduCopter's values: 0 report only,
1 RTL or LAND, 2 LAND, 3 SmartRTL or RTL or LAND, 4 BRAKE or LAND, 5 SmartRTL or LAND)
and last `FENCE_ENABLE` 1, so that the fence is in force only once all of it is there.
A fence or rally upload that fails raises `FenceUploadError` before the mission or a
parameter is touched: ArduPilot stages an upload and keeps its previous fence and rally
points when one does not complete, so the vehicle is left as it was.
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs.mavlink.errors import GcsError
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Autopilot
from gcs.mavlink.mission_protocol import (
    MISSION_TYPE_FENCE,
    MISSION_TYPE_RALLY,
    MissionClient,
)
from gcs.mavlink.parameters import set_parameter
from gcs.mission.fence import (
    FencePlan,
    fence_items,
    rally_items,
    same_fence_item,
    same_rally_item,
)

FENCE_TYPE_POLYGONS = 4
"""AC_FENCE_TYPE_POLYGON: inclusion and exclusion polygons and circles."""
FENCE_ACTIONS = {
    0: "report only",
    1: "RTL or LAND",
    2: "LAND",
    3: "SmartRTL or RTL or LAND",
    4: "BRAKE or LAND",
    5: "SmartRTL or LAND",
}
"""ArduCopter's FENCE_ACTION values."""
DEFAULT_FENCE_ACTION = 1


class FenceUploadError(GcsError):
    """The fence or rally points were not taken: the flight must not start."""


@dataclass(frozen=True)
class GeoFence:
    """What a flight sets up on each vehicle besides its mission."""

    plan: FencePlan
    action: int = DEFAULT_FENCE_ACTION

    def __post_init__(self) -> None:
        if self.action not in FENCE_ACTIONS:
            raise ValueError(
                f"FENCE_ACTION {self.action}: ArduCopter knows {sorted(FENCE_ACTIONS)}"
            )


async def upload_fence(client: MissionClient, fence: GeoFence, rally_alt_m: float) -> None:
    """Write and verify the fence, then the rally points (at `rally_alt_m` above home
    where the scenario gives none); FenceUploadError saying which and why."""
    for what, items, mission_type, same in (
        ("fence", fence_items(fence.plan), MISSION_TYPE_FENCE, same_fence_item),
        ("rally points", rally_items(fence.plan, rally_alt_m), MISSION_TYPE_RALLY, same_rally_item),
    ):
        try:
            await client.upload_list(items, mission_type, same)
        except GcsError as exc:
            raise FenceUploadError(
                f"vehicle {client.link.sysid}: {what} upload failed, flight refused: {exc}"
            ) from exc


async def enable_fence(link: VehicleLink, fence: GeoFence) -> None:
    """ArduPilot: the polygon fence with the flight's action, enabled last."""
    if link.autopilot != Autopilot.ARDUPILOT:
        return  # PX4 keeps its own geofence parameters (GF_ACTION): not set here
    try:
        await set_parameter(link, "FENCE_TYPE", FENCE_TYPE_POLYGONS)
        await set_parameter(link, "FENCE_ACTION", fence.action)
        await set_parameter(link, "FENCE_ENABLE", 1)
    except GcsError as exc:
        raise FenceUploadError(
            f"vehicle {link.sysid}: the fence was not enabled, flight refused: {exc}"
        ) from exc
