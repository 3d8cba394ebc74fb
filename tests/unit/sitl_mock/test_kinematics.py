"""Fleet kinematics: S-curve legs (speed, acceleration and jerk limits), stopping, blended
corners, braking, climbing."""

from __future__ import annotations

import numpy as np
import pytest

from sitl_mock.kinematics import NavLimits, PointMassFleet
from sitl_mock.scurve import stopping_distance

DT = 0.02


def flying_fleet(n: int = 1, alt: float = 10.0, **limits: float) -> PointMassFleet:
    fleet = PointMassFleet(np.zeros((n, 2)))
    fleet.pos[:, 2] = alt
    fleet.target[:, 2] = alt
    fleet.active[:] = True
    for i in range(n):
        fleet.body(i).apply_limits(NavLimits(**limits))
    return fleet


def run(fleet: PointMassFleet, seconds: float) -> np.ndarray:
    """The first vehicle's horizontal velocity, one row per step."""
    history = []
    for _ in range(round(seconds / DT)):
        fleet.step(DT)
        history.append(fleet.vel[0, :2].copy())
    return np.array(history)


def run_until_reached(fleet: PointMassFleet, limit_s: float = 200.0) -> float:
    for step in range(1, round(limit_s / DT)):
        fleet.step(DT)
        if fleet.body(0).reached:
            return step * DT
    raise AssertionError("target not reached")


def test_stops_at_a_target_without_overshoot_within_speed_acceleration_and_jerk():
    fleet = flying_fleet()
    body = fleet.body(0)
    body.go_to(100.0, 0.0, 10.0, radius=2.0)
    velocity = run(fleet, 30.0)[:, 0]
    assert body.reached
    assert fleet.pos[0, 0] == pytest.approx(100.0, abs=1e-9)
    assert velocity.min() >= 0.0  # never beyond the target and back
    assert velocity.max() == pytest.approx(10.0, abs=1e-6)
    accel = np.diff(velocity) / DT
    assert np.abs(accel).max() <= 2.5 + 1e-6
    assert np.abs(np.diff(accel)).max() / DT <= 1.0 + 1e-3


def test_a_stop_from_1_m_s_takes_two_seconds_and_a_metre_as_on_arducopter():
    """At 1 m/s and WP_JERK 1 m/s³ a start and a stop each cost a second against flying
    the leg at cruise: 20 m take 22 s (a point mass at 2.5 m/s² would take 20.4 s)."""
    fleet = flying_fleet(cruise_speed=1.0)
    fleet.body(0).go_to(20.0, 0.0, 10.0, radius=0.5)
    assert run_until_reached(fleet) == pytest.approx(22.0, abs=2 * DT)
    assert stopping_distance(1.0, 2.5, 1.0) == pytest.approx(1.0)


def test_rounds_a_corner_it_knows_the_next_leg_of_without_losing_time():
    """ArduCopter's fast waypoint: the next leg starts as this one slows down, and the
    waypoint counts as reached half-way through the blended turn."""
    fleet = flying_fleet(cruise_speed=1.0)
    body = fleet.body(0)
    body.go_to(20.0, 0.0, 10.0, radius=2.0, then=(20.0, 20.0))
    corner_at = run_until_reached(fleet)
    assert corner_at == pytest.approx(21.0, abs=2 * DT)  # 20 s to slow down, 2 s blend
    assert body.ground_speed > 0.6
    body.go_to(20.0, 20.0, 10.0, radius=2.0)
    track, speeds = [], []
    for _ in range(round(40 / DT)):
        fleet.step(DT)
        track.append(fleet.pos[0, :2].copy())
        speeds.append(body.ground_speed)
        if body.reached:
            break
    assert body.reached
    assert corner_at + len(track) * DT == pytest.approx(42.0, abs=3 * DT)  # as a straight 40 m
    closest = np.hypot(*(np.array(track) - (20.0, 0.0)).T).min()
    assert 0.1 < closest < 0.5
    assert min(speeds[: len(speeds) // 2]) > 0.6


def test_a_tight_waypoint_radius_delays_the_blend_into_a_tighter_slower_turn():
    fleet = flying_fleet(cruise_speed=1.0)
    body = fleet.body(0)
    body.go_to(20.0, 0.0, 10.0, radius=0.1, then=(20.0, 20.0))
    track = []
    while not body.reached:
        fleet.step(DT)
        track.append(fleet.pos[0, :2].copy())
    assert len(track) * DT > 21.1
    assert np.hypot(*(np.array(track) - (20.0, 0.0)).T).min() < 0.1
    assert body.ground_speed < 0.5


def test_a_new_speed_applies_to_the_leg_being_flown():
    fleet = flying_fleet(cruise_speed=5.0)
    body = fleet.body(0)
    body.go_to(200.0, 0.0, 10.0, radius=2.0)
    run(fleet, 10.0)
    assert body.ground_speed == pytest.approx(5.0)
    body.set_cruise(2.0)
    run(fleet, 10.0)
    assert body.ground_speed == pytest.approx(2.0)
    run_until_reached(fleet)
    assert fleet.pos[0, 0] == pytest.approx(200.0, abs=1e-9)


def test_climbs_at_the_climb_rate_and_never_below_ground():
    fleet = flying_fleet(alt=0.0)
    body = fleet.body(0)
    body.go_to(0.0, 0.0, 20.0, radius=0.5)
    run(fleet, 4.0)
    assert fleet.vel[0, 2] == pytest.approx(2.5)
    body.go_to(0.0, 0.0, -5.0, radius=0.5)
    run(fleet, 40.0)
    assert fleet.pos[0, 2] == 0.0


def test_inactive_vehicles_do_not_move_and_vehicles_are_independent():
    fleet = flying_fleet(n=2)
    fleet.active[1] = False
    fleet.body(0).go_to(30.0, 0.0, 10.0, radius=1.0)
    fleet.body(1).go_to(30.0, 0.0, 10.0, radius=1.0)
    run(fleet, 15.0)
    assert fleet.pos[0, 0] == pytest.approx(30.0, abs=1e-9)
    assert fleet.pos[1, 0] == 0.0


def test_motors_stopping_mid_leg_leave_the_vehicle_where_it_is():
    fleet = flying_fleet(cruise_speed=2.0)
    fleet.body(0).go_to(100.0, 0.0, 10.0, radius=2.0)
    run(fleet, 10.0)
    where = fleet.pos[0, :2].copy()
    assert where[0] > 5.0
    fleet.active[0] = False
    run(fleet, 1.0)
    assert fleet.pos[0, :2] == pytest.approx(where)


def test_hold_brakes_along_the_velocity_to_the_jerk_limited_stopping_point():
    fleet = flying_fleet()
    body = fleet.body(0)
    body.go_to(1000.0, 0.0, 10.0, radius=2.0)
    run(fleet, 20.0)
    assert body.ground_speed == pytest.approx(10.0)
    start = fleet.pos[0, 0]
    body.hold()
    run(fleet, 20.0)
    assert fleet.pos[0, 0] - start == pytest.approx(stopping_distance(10.0, 2.5, 1.0), abs=0.2)
    assert body.ground_speed == 0.0
    assert body.reached


def test_turning_away_brakes_first_and_then_flies_to_the_new_target():
    fleet = flying_fleet(cruise_speed=2.0)
    body = fleet.body(0)
    body.go_to(100.0, 0.0, 10.0, radius=2.0)
    run(fleet, 10.0)
    body.go_to(0.0, 0.0, 10.0, radius=2.0)  # back where it came from
    velocity = run(fleet, 80.0)
    assert body.reached
    assert fleet.pos[0, :2] == pytest.approx((0.0, 0.0), abs=1e-9)
    assert np.hypot(*(np.diff(velocity, axis=0) / DT).T).max() <= 2.5 + 1e-6


def test_a_brake_before_turning_back_is_not_blended_into_the_leg_after_the_target():
    """A new mission mid-flight sends the vehicle back to a waypoint behind it with a
    corner after it: it brakes, flies back to that waypoint, and only that leg blends."""
    fleet = flying_fleet(cruise_speed=1.0)
    body = fleet.body(0)
    body.go_to(0.0, 100.0, 10.0, radius=0.5)
    run(fleet, 20.0)
    body.go_to(0.0, 10.0, 10.0, radius=0.5, then=(5.0, 15.0))
    track = []
    while not body.reached:
        fleet.step(DT)
        track.append(fleet.pos[0, :2].copy())
    assert np.hypot(*(np.array(track) - (0.0, 10.0)).T).min() < 0.5
    assert max(east for east, _ in track[: len(track) // 2]) < 1e-9  # straight back first
