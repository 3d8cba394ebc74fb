"""A flight's geofence and rally points on a simulated ArduCopter (gcs/fleet/geofence.py
and sitl_mock/fence.py), on the virtual clock: uploaded and read back as ArduPilot keeps
them, enabled, and enforced as ArduCopter does (a breach says so, counts in FENCE_STATUS
and sets off FENCE_ACTION)."""

from __future__ import annotations

import math
from collections.abc import AsyncIterator
from dataclasses import replace

import pymap3d
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.fleet.geofence import FenceUploadError, GeoFence, enable_fence, upload_fence
from gcs.mavlink.actions import FlightActions
from gcs.mavlink.errors import CommandFailedError, MissionGenericError
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Autopilot, Command, Frame, Mission, MissionItem
from gcs.mavlink.mission_protocol import MISSION_TYPE_FENCE, MISSION_TYPE_RALLY, MissionClient
from gcs.mavlink.parameters import set_parameter
from gcs.mission.fence import FencePlan, fence_items, rally_items
from sitl_mock import Faults, Simulator, VehicleConfig
from tests.inprocess.fleet import connect_all
from tests.inprocess.service import until
from tests.inprocess.vehicles import SimulatedVehicles

from .conftest import CMAC

pytestmark = [pytest.mark.virtual_clock]

ALT_M = 10.0


def lat_lon(east: float, north: float) -> tuple[float, float]:
    lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, CMAC[0], CMAC[1], 0.0)
    return (round(float(lat), 7), round(float(lon), 7))


def square(e0: float, n0: float, e1: float, n1: float) -> tuple[tuple[float, float], ...]:
    return (lat_lon(e0, n0), lat_lon(e1, n0), lat_lon(e1, n1), lat_lon(e0, n1))


FENCE = FencePlan(
    inclusion_polygons=(square(-100, -100, 100, 100),),
    exclusion_polygons=(square(-60, 40, -40, 60),),
    exclusion_circles=((*lat_lon(0, -60), 15.0),),
    rally_points=(lat_lon(70, 30), (*lat_lon(-70, -70), 25.0)),
)


def mission_to(east: float, north: float) -> Mission:
    """Take off at home and fly to (east, north), then land there."""
    lat, lon = (round(v * 1e7) for v in CMAC[:2])
    x, y = (round(v * 1e7) for v in lat_lon(east, north))
    items = (
        MissionItem(Command.NAV_WAYPOINT, Frame.GLOBAL, x=lat, y=lon, z=CMAC[2]),
        MissionItem(Command.NAV_TAKEOFF, z=ALT_M, x=lat, y=lon),
        MissionItem(Command.NAV_WAYPOINT, x=x, y=y, z=ALT_M),
        MissionItem(Command.NAV_LAND, x=x, y=y),
    )
    return Mission(items, Autopilot.ARDUPILOT, CMAC)


@pytest.fixture
async def one(vehicles: SimulatedVehicles) -> AsyncIterator[tuple[Simulator, VehicleLink]]:
    config = VehicleConfig(
        sysid=1, home=CMAC, transport="memory", estimate_delay_s=6.0, position_delay_s=3.0
    )
    sim = await vehicles.start([config])
    (link,) = await connect_all(vehicles, sim)
    yield sim, link
    await link.close()


async def set_up(link: VehicleLink, action: int, fence: FencePlan = FENCE) -> None:
    client = MissionClient(link)
    await upload_fence(client, GeoFence(fence, action), rally_alt_m=ALT_M)
    await enable_fence(link, GeoFence(fence, action))


async def test_the_vehicle_keeps_fence_and_rally_points_as_ardupilot_does(one) -> None:
    sim, link = one
    await set_up(link, action=1)
    fence = sim.mission(1, MISSION_TYPE_FENCE)
    sent = fence_items(FENCE)
    assert len(fence) == len(sent) == 4 + 4 + 1
    assert [(i.command, i.param1, i.x, i.y) for i in fence] == [
        (s.command, s.params[0], s.x, s.y) for s in sent
    ]
    assert {(i.frame, i.z) for i in fence} == {(mavlink2.MAV_FRAME_GLOBAL, 0.0)}
    rally = sim.mission(1, MISSION_TYPE_RALLY)
    assert [(i.frame, i.x, i.y, i.z) for i in rally] == [
        (mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT, r.x, r.y, r.z) for r in rally_items(FENCE, ALT_M)
    ]
    assert [i.z for i in rally] == [10.0, 25.0]
    params = sim.vehicle(1).params
    assert (params.get("FENCE_ENABLE"), params.get("FENCE_TYPE")) == (1, 4)
    # the mission is untouched: fence and rally are lists of their own
    assert len(sim.mission(1)) <= 1


async def breach(sim: Simulator, link: VehicleLink, east: float, north: float) -> None:
    """Fly a mission towards (east, north) until the vehicle leaves AUTO."""
    await MissionClient(link).upload(mission_to(east, north))
    actions = FlightActions(link)
    await actions.arm_and_take_off(ALT_M)
    await actions.start_mission()
    await until(lambda: sim.state(1).mode != "AUTO", 120, "the fence action")


@pytest.mark.parametrize(
    ("action", "mode"), [(1, "RTL"), (2, "LAND"), (4, "BRAKE"), (3, "RTL"), (5, "LAND")]
)
async def test_leaving_the_inclusion_polygon_sets_off_the_fence_action(
    one, action: int, mode: str
) -> None:
    sim, link = one
    await set_up(link, action)
    with link.subscribe(["FENCE_STATUS"]) as statuses:
        await breach(sim, link, 160.0, 0.0)
        assert sim.state(1).mode == mode
        east, _, _ = sim.local_positions()[1]
        home_east, _ = sim.to_local(*CMAC[:2])
        assert east - home_east == pytest.approx(100.0, abs=3.0)  # at the fence, not beyond
        status = await statuses.next_matching(lambda m: m.breach_status == 1, 5.0)
    assert (status.breach_count, status.breach_type) == (1, mavlink2.FENCE_BREACH_BOUNDARY)
    said = link.state.recent_text(0.0)
    assert "Polygon fence breached; Manual recovery started" in said, said  # as SITL says


async def test_rtl_after_a_breach_returns_to_the_nearest_rally_point_and_clears(one) -> None:
    sim, link = one
    await set_up(link, action=1)
    await breach(sim, link, 160.0, 0.0)
    await until(lambda: not sim.state(1).armed, 300, "landing at the rally point")
    east, north = sim.to_local(*FENCE.rally_points[0][:2])
    here = sim.local_positions()[1]
    assert math.hypot(here[0] - east, here[1] - north) < 3.0
    assert "Fence breach cleared" in link.state.recent_text(0.0)


async def test_entering_an_exclusion_circle_is_a_breach(one) -> None:
    sim, link = one
    await set_up(link, action=2)
    await breach(sim, link, 0.0, -90.0)
    assert sim.state(1).mode == "LAND"
    _, north, _ = sim.local_positions()[1]
    _, home_north = sim.to_local(*CMAC[:2])
    assert north - home_north == pytest.approx(-45.0, abs=3.0)  # the circle's edge


async def test_report_only_keeps_flying_and_a_disabled_fence_is_not_enforced(one) -> None:
    sim, link = one
    await set_up(link, action=0)
    await MissionClient(link).upload(mission_to(130.0, 0.0))
    actions = FlightActions(link)
    await actions.arm_and_take_off(ALT_M)
    await actions.start_mission()
    await until(lambda: not sim.state(1).armed, 300, "the mission's landing")
    assert "Polygon fence breached" in link.state.recent_text(0.0)
    assert sim.vehicle(1).flight.fence.breach_count == 1
    await set_parameter(link, "FENCE_ENABLE", 0)
    assert sim.vehicle(1).flight.fence_types() == 0


async def test_a_failed_fence_upload_refuses_and_leaves_the_previous_fence(one) -> None:
    sim, link = one
    await set_up(link, action=1)
    before = sim.mission(1, MISSION_TYPE_FENCE)
    sim.set_faults(1, Faults(reject_missions=True, reject_at="last_item"))
    smaller = replace(FENCE, inclusion_polygons=(square(-50, -50, 50, 50),))
    with pytest.raises(FenceUploadError, match="fence upload failed, flight refused"):
        await upload_fence(MissionClient(link), GeoFence(smaller, 2), rally_alt_m=ALT_M)
    assert sim.mission(1, MISSION_TYPE_FENCE) == before


async def test_a_fence_whose_polygons_do_not_add_up_is_refused_whole(one) -> None:
    """AC_PolyFence_loader refuses a polygon with a vertex count that is not its own."""
    sim, link = one
    items = list(fence_items(FENCE))
    items[1] = replace(items[1], params=(5.0, 0.0, 0.0, 0.0))
    client = MissionClient(link)
    with pytest.raises(MissionGenericError):
        await client.upload_list(tuple(items), MISSION_TYPE_FENCE, lambda a, b: True)
    assert sim.mission(1, MISSION_TYPE_FENCE) == []


async def test_arming_is_refused_while_the_vehicle_breaches_the_fence(one) -> None:
    sim, link = one
    outside = FencePlan(inclusion_polygons=(square(50, 50, 100, 100),))
    await set_up(link, action=1, fence=outside)
    await until(lambda: sim.state(1).estimate_ready, 60, "the position estimate")
    assert sim.vehicle(1).flight.fence.breaches
    actions = FlightActions(link)
    await actions.set_mode("GUIDED")
    with pytest.raises(CommandFailedError):
        await actions.arm()
    await until(lambda: "breaching" in link.state.recent_text(0.0), 5, "the arming failure")
    assert "Arm: Vehicle breaching Polygon fence" in link.state.recent_text(0.0)
    assert not sim.state(1).armed


async def test_rtl_ignores_a_rally_point_outside_the_fence(one) -> None:
    """AP_Rally_Copter::is_valid: a rally point the fence excludes is not returned to."""
    sim, link = one
    outside = replace(FENCE, rally_points=(lat_lon(130, 0),))  # beyond the east edge
    await set_up(link, action=1, fence=outside)
    await breach(sim, link, 160.0, 0.0)
    assert sim.state(1).mode == "RTL"
    await until(lambda: not sim.state(1).armed, 300, "landing at home")
    home = sim.to_local(*CMAC[:2])
    here = sim.local_positions()[1]
    assert math.hypot(here[0] - home[0], here[1] - home[1]) < 3.0
