"""The mock's fence (sitl_mock/fence.py) in the plane: what is a breach, how far, what
ArduCopter says, and which lists AC_PolyFence_loader refuses."""

from __future__ import annotations

import numpy as np
import pytest

from sitl_mock.codec import mavlink
from sitl_mock.fence import (
    ALT_MAX,
    CIRCLE,
    POLYGON,
    FenceMonitor,
    Zones,
    fence_list_valid,
    fence_names,
    stored_rally_item,
)
from sitl_mock.mission_item import MissionItem
from tests.unit.sitl_mock.test_flight import airborne_in_guided, at, local, make

SQUARE = np.array([(0.0, 0.0), (100.0, 0.0), (100.0, 100.0), (0.0, 100.0)])
ZONES = Zones(
    inclusions=(SQUARE,),
    exclusions=(SQUARE / 10 + 40,),  # 40..50
    exclusion_circles=((80.0, 80.0, 5.0),),
)


@pytest.mark.parametrize(
    ("east", "north", "distance"),
    [(10, 10, None), (120, 50, 20.0), (45, 44, 4.0), (80, 82, 3.0), (-5, 50, 5.0)],
)
def test_a_breach_is_outside_an_inclusion_or_inside_an_exclusion(
    east: float, north: float, distance: float | None
) -> None:
    found = ZONES.breach_distance(east, north)
    assert found == (None if distance is None else pytest.approx(distance))


def test_a_breach_is_new_once_counted_and_cleared_when_back_inside() -> None:
    monitor = FenceMonitor()
    check = lambda e, n, up=10.0: monitor.check(  # noqa: E731
        ALT_MAX | CIRCLE | POLYGON, ZONES, (e, n, up), (10.0, 10.0), (100.0, 300.0), 1000
    )
    assert check(10, 10) is None
    breach = check(101, 50)
    assert breach is not None and breach.new == POLYGON and breach.distance_m == pytest.approx(1)
    assert check(110, 50) is None  # still breached: not new
    assert (monitor.breaches, monitor.breach_count) == (POLYGON, 1)
    assert monitor.breach_type == mavlink.FENCE_BREACH_BOUNDARY
    assert check(10, 10) is None and monitor.breaches == 0
    both = check(101, 50, up=120.0)
    assert both is not None and both.new == ALT_MAX | POLYGON and monitor.breach_count == 2


def test_fence_names_are_ardupilots() -> None:
    assert fence_names(POLYGON) == "Polygon fence"
    assert fence_names(ALT_MAX | POLYGON) == "Max Alt and Polygon fences"
    assert fence_names(ALT_MAX | CIRCLE | POLYGON) == "Max Alt, Circle and Polygon fences"


def vertex(count: float, command: int = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION):
    return MissionItem(seq=0, frame=0, command=command, param1=count, x=1, y=1)


def test_polygons_that_do_not_add_up_are_refused() -> None:
    assert fence_list_valid([vertex(3)] * 3)
    assert not fence_list_valid([vertex(3)] * 2)  # a vertex missing
    assert not fence_list_valid([vertex(3), vertex(4), vertex(3)])
    assert not fence_list_valid([vertex(2)] * 2)
    circle = vertex(0.0, mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION)
    assert not fence_list_valid([circle])


def test_a_rally_point_keeps_whole_metres_and_its_altitude_frame() -> None:
    sent = MissionItem(seq=0, frame=6, command=5100, x=1, y=2, z=30.7)
    kept = stored_rally_item(sent)
    assert (kept.frame, kept.z, kept.x, kept.y) == (3, 30.0, 1, 2)
    assert stored_rally_item(MissionItem(seq=0, frame=5, command=5100, z=1.5)).frame == 0


def test_guided_refuses_a_target_outside_the_enabled_fence() -> None:
    """ModeGuided::set_pos_NED_m: a destination check_destination_within_fence refuses is
    not flown to (the fence as a 40 m square round home)."""
    sim, flight = make()
    corners = [at(e, n) for e, n in ((-40, -40), (40, -40), (40, 40), (-40, 40))]
    fence = [
        MissionItem(
            seq=k,
            frame=0,
            command=mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            param1=4.0,
            x=c.x,
            y=c.y,
            mission_type=mavlink.MAV_MISSION_TYPE_FENCE,
        )
        for k, c in enumerate(corners)
    ]
    sim.load_mission(1, fence, mavlink.MAV_MISSION_TYPE_FENCE)
    for name, value in (("FENCE_TYPE", 4), ("FENCE_ENABLE", 1)):
        sim.set_param(1, name, value)
    airborne_in_guided(sim, flight, alt=10.0)
    outside, inside = at(60, 0), at(20, 0)
    flight.guided_target(outside.lat, outside.lon, 10.0, sim.sim_time)
    sim.advance(10.0)
    assert np.hypot(*local(sim)) < 0.5 and not flight.fence.breaches
    flight.guided_target(inside.lat, inside.lon, 10.0, sim.sim_time)
    sim.advance(15.0)
    assert local(sim)[0] == pytest.approx(20.0, abs=0.5)
