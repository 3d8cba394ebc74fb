"""Point-mass kinematics: speed and acceleration limits, stopping, carrying speed."""

from __future__ import annotations

import numpy as np
import pytest

from sitl_mock.kinematics import NavLimits, PointMassFleet

DT = 0.02


def flying_fleet(n: int = 1, alt: float = 10.0) -> PointMassFleet:
    fleet = PointMassFleet(np.zeros((n, 2)))
    fleet.pos[:, 2] = alt
    fleet.target[:, 2] = alt
    fleet.active[:] = True
    for i in range(n):
        fleet.body(i).apply_limits(NavLimits())
    return fleet


def run(fleet: PointMassFleet, seconds: float) -> list[np.ndarray]:
    history = []
    for _ in range(round(seconds / DT)):
        fleet.step(DT)
        history.append(fleet.vel.copy())
    return history


def test_stops_at_a_target_without_overshoot_within_the_limits():
    fleet = flying_fleet()
    body = fleet.body(0)
    body.go_to(100.0, 0.0, 10.0, radius=2.0)
    history = np.array(run(fleet, 20.0))[:, 0, :2]
    assert body.reached
    assert fleet.pos[0, 0] == pytest.approx(100.0, abs=0.05)
    speeds = np.hypot(history[:, 0], history[:, 1])
    assert speeds.max() == pytest.approx(10.0, abs=1e-6)
    accel = np.hypot(*np.diff(history, axis=0).T) / DT
    assert accel.max() <= 2.5 + 1e-6


def test_carries_speed_into_the_next_leg():
    fleet = flying_fleet()
    body = fleet.body(0)
    body.go_to(50.0, 0.0, 10.0, radius=2.0, exit_speed=5.0)
    for _ in range(2000):
        fleet.step(DT)
        if body.reached:
            break
    assert body.reached
    assert body.ground_speed == pytest.approx(5.0, abs=2.5 * DT * 2)


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
    run(fleet, 10.0)
    assert fleet.pos[0, 0] == pytest.approx(30.0, abs=0.05)
    assert fleet.pos[1, 0] == 0.0


def test_hold_brakes_to_the_stopping_point():
    fleet = flying_fleet()
    fleet.vel[0] = (10.0, 0.0, 0.0)
    body = fleet.body(0)
    body.hold()
    run(fleet, 10.0)
    assert fleet.pos[0, 0] == pytest.approx(10.0**2 / (2 * 2.5), abs=0.3)
    assert body.ground_speed < 0.01
