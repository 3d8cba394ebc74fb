"""The mock's GCS failsafe, stepped by hand: ArduCopter's `failsafe_gcs_check` and what
it does once its ground station's HEARTBEATs stop (FS_GCS_ENABLE, FS_GCS_TIMEOUT,
FS_OPTIONS, MAV_GCS_SYSID)."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_mock import Simulator
from sitl_mock.modes import FlightMode
from tests.unit.sitl_mock.test_flight import ACCEPTED, airborne_in_guided, at, make, takeoff

BRAKE_OR_LAND = 7
HEARTBEAT_EVERY_S = 0.2


def heartbeats(sim: Simulator, seconds: float, sysid: int = 255) -> None:
    """`seconds` of simulated time with a ground station `sysid` beating all along."""
    codec = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=190)
    beat = codec.heartbeat_encode(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 4)
    for _ in range(round(seconds / HEARTBEAT_EVERY_S)):
        sim.vehicle(1).on_packet(bytes(beat.pack(codec)), "gcs")
        sim.advance(HEARTBEAT_EVERY_S)


def said_by(sim: Simulator) -> list[str]:
    """What the failsafe says from now on."""
    texts: list[str] = []
    sim.vehicle(1).failsafe._say = lambda severity, text: texts.append(text)
    return texts


def cruising(enable: int = BRAKE_OR_LAND, timeout_s: float = 2.0):
    """A vehicle 5 s into a 200 m leg of its mission, its ground station heard until now
    (and not before: the failsafe waits for a first HEARTBEAT)."""
    sim, flight = make(mission=[takeoff(), at(200, 0)])
    sim.set_param(1, "FS_GCS_ENABLE", enable)
    sim.set_param(1, "FS_GCS_TIMEOUT", timeout_s)
    airborne_in_guided(sim, flight)
    assert flight.set_mode(FlightMode.AUTO, sim.sim_time) == ACCEPTED
    heartbeats(sim, 5.0)
    return sim, flight


def speed(sim: Simulator) -> float:
    north, east, _ = sim.state(1).velocity_ned
    return math.hypot(north, east)


def test_a_vehicle_silent_past_its_timeout_brakes_and_stays_braked_once_heard_again() -> None:
    sim, flight = cruising(timeout_s=2.0)
    said = said_by(sim)
    assert speed(sim) > 2.0
    sim.advance(1.7)  # 1.9 s since the last HEARTBEAT
    assert flight.mode == FlightMode.AUTO and said == []
    sim.advance(0.4)
    assert flight.mode == FlightMode.BRAKE and said == ["GCS Failsafe"]
    sim.advance(8.0)
    assert speed(sim) < 0.05
    said.clear()
    heartbeats(sim, 1.0)
    assert said == ["GCS Failsafe Cleared"]
    assert flight.mode == FlightMode.BRAKE  # only a ground station sends it on again


def test_a_vehicle_takes_no_action_when_disabled_or_never_heard_or_heard_from_others() -> None:
    sim, flight = cruising(enable=0)
    sim.advance(10.0)
    assert flight.mode == FlightMode.AUTO
    sim, flight = make(mission=[takeoff(), at(200, 0)])
    sim.set_param(1, "FS_GCS_ENABLE", BRAKE_OR_LAND)
    sim.set_param(1, "FS_GCS_TIMEOUT", 2.0)
    airborne_in_guided(sim, flight)
    flight.set_mode(FlightMode.AUTO, sim.sim_time)
    heartbeats(sim, 10.0, sysid=250)  # another system's heartbeats: not MAV_GCS_SYSID
    assert flight.mode == FlightMode.AUTO


@pytest.mark.parametrize(("options", "mode"), [(16, FlightMode.BRAKE), (24, FlightMode.LAND)])
def test_a_landing_goes_on_only_with_fs_options_bit_3(options: int, mode: FlightMode) -> None:
    sim, flight = cruising()
    sim.set_param(1, "FS_OPTIONS", options)
    assert flight.set_mode(FlightMode.LAND, sim.sim_time) == ACCEPTED
    heartbeats(sim, 4.0)  # braking, then coming down
    sim.advance(2.5)
    assert flight.mode == mode


@pytest.mark.parametrize(
    ("enable", "mode"), [(1, FlightMode.RTL), (5, FlightMode.LAND), (99, FlightMode.RTL)]
)
def test_the_action_is_the_one_fs_gcs_enable_names(enable: int, mode: FlightMode) -> None:
    sim, flight = cruising(enable=enable)
    sim.advance(2.5)
    assert flight.mode == mode


def test_a_vehicle_armed_on_the_ground_disarms() -> None:
    sim, flight = make(mission=[takeoff(), at(200, 0)])
    sim.set_param(1, "FS_GCS_ENABLE", BRAKE_OR_LAND)
    sim.set_param(1, "FS_GCS_TIMEOUT", 2.0)
    heartbeats(sim, 5.0)
    assert flight.set_mode(FlightMode.GUIDED, sim.sim_time) == ACCEPTED
    assert flight.arm(sim.sim_time) == ACCEPTED
    said = said_by(sim)
    sim.advance(2.5)
    assert not flight.armed and said == ["GCS Failsafe - Disarming"]
