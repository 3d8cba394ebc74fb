"""SET_POSITION_TARGET_GLOBAL_INT as ArduCopter takes it: flown to (and held) in GUIDED
once airborne, at the altitude given; ignored on the ground, outside GUIDED, and by PX4
(which takes it only in OFFBOARD, not simulated)."""

from __future__ import annotations

import math

import pymap3d
import pytest

from sitl_mock.modes import FlightMode
from tests.unit.sitl_mock.test_flight import HOME, airborne_in_guided, local, make


def target(east: float, north: float) -> tuple[float, float]:
    lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, *HOME)
    return float(lat), float(lon)


def test_guided_flies_to_the_target_at_its_altitude_and_holds_there() -> None:
    sim, flight = make()
    airborne_in_guided(sim, flight, alt=10.0)
    flight.guided_target(*target(4.0, -3.0), 12.0, sim.sim_time)
    sim.advance(20.0)
    east, north = local(sim)
    assert math.hypot(east - 4.0, north + 3.0) < 0.1
    assert sim.state(1).alt == pytest.approx(12.0, abs=0.1)
    flight.guided_target(*target(4.0, -3.0), 12.0, sim.sim_time)  # again: no change
    sim.advance(10.0)
    assert math.hypot(local(sim)[0] - 4.0, local(sim)[1] + 3.0) < 0.1
    assert sim.state(1).mode == "GUIDED" and sim.state(1).armed


@pytest.mark.parametrize("mode", [FlightMode.LOITER, FlightMode.BRAKE])
def test_outside_guided_a_target_is_ignored(mode: FlightMode) -> None:
    sim, flight = make()
    airborne_in_guided(sim, flight, alt=10.0)
    flight.set_mode(mode, sim.sim_time)
    sim.advance(2.0)
    before = local(sim)
    flight.guided_target(*target(5.0, 5.0), 10.0, sim.sim_time)
    sim.advance(10.0)
    assert math.dist(local(sim), before) < 0.5


def test_on_the_ground_a_target_is_ignored() -> None:
    sim, flight = make()
    sim.advance(5.0)
    flight.set_mode(FlightMode.GUIDED, sim.sim_time)
    flight.arm(sim.sim_time)
    flight.guided_target(*target(5.0, 5.0), 10.0, sim.sim_time)
    sim.advance(3.0)
    assert sim.state(1).alt == 0.0 and math.hypot(*local(sim)) < 0.1
