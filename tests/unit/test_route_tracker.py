"""Following a vehicle along its plan as real autopilots report it."""

from __future__ import annotations

from gcs.fleet.route_tracker import RouteTracker
from gcs.mavlink.vehicle_state import LandedState, Position, VehicleState
from gcs.mission.build import Visit

WP = Visit(seq=3, arrive=10.0, leave=10.0, lat=-35.3630, lon=149.1650)
LAND = Visit(seq=5, arrive=20.0, leave=20.0, lat=-35.3630, lon=149.1660, lands=True)


def tracker() -> RouteTracker:
    t = RouteTracker("uav1", [WP, LAND], origin=(-35.3630, 149.1640))
    t.start(time_boot_ms=1_000)
    return t


def state(lat: float, lon: float, *, armed: bool, landed: int, seq: int = 1) -> VehicleState:
    s = VehicleState(sysid=1, autopilot=3, time_boot_ms=40_000, link_up=True)
    s.position = Position(lat, lon, 0.0 if landed == LandedState.ON_GROUND else 20.0, 584.0)
    s.armed, s.landed_state, s.mission_seq = armed, landed, seq
    return s


def test_down_at_the_landing_point_is_the_end_though_nothing_was_reported() -> None:
    """ArduCopter sends no MISSION_ITEM_REACHED for NAV_LAND (and may have merged the
    waypoint's into a later one), then disarms and resets MISSION_CURRENT to 1."""
    t = tracker()
    landed = state(LAND.lat, LAND.lon, armed=False, landed=LandedState.ON_GROUND)
    assert t.newly_passed(landed) == [0, 1]
    assert t.finished(landed)


def test_down_elsewhere_is_not_the_end() -> None:
    t = tracker()
    elsewhere = state(WP.lat, WP.lon, armed=False, landed=LandedState.ON_GROUND)
    assert t.newly_passed(elsewhere) == []
    assert not t.finished(elsewhere)


def test_a_report_for_a_later_item_passes_the_ones_before() -> None:
    t = tracker()
    flying = state(WP.lat, WP.lon, armed=True, landed=LandedState.IN_AIR, seq=4)
    flying.reached = {4}  # the DO item after the waypoint; the waypoint's report merged
    assert t.newly_passed(flying) == [0]
    assert not t.finished(flying)
