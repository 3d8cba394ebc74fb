"""Flight behaviour stepped by hand (no sockets): arming rules, idle disarm, take-off,
AUTO, hold times, pause, speed changes, RTL and land."""

from __future__ import annotations

import math

import pymap3d
import pytest

from sitl_mock import MissionItem, Simulator, VehicleConfig
from sitl_mock.codec import mavlink
from sitl_mock.modes import FlightMode

HOME = (47.397742, 8.545594, 488.0)
ACCEPTED, FAILED = mavlink.MAV_RESULT_ACCEPTED, mavlink.MAV_RESULT_FAILED


def at(east: float, north: float, alt: float = 20.0, command: int = 16, p1: float = 0.0):
    lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, *HOME)
    return MissionItem(0, 6, command, param1=p1, x=round(lat * 1e7), y=round(lon * 1e7), z=alt)


def takeoff(alt: float = 20.0) -> MissionItem:
    return MissionItem(0, 6, mavlink.MAV_CMD_NAV_TAKEOFF, z=alt)


def land() -> MissionItem:
    return MissionItem(0, 6, mavlink.MAV_CMD_NAV_LAND)


def make(autopilot: str = "ardupilot", mission: list[MissionItem] | None = None):
    """One vehicle whose position estimate is ready 5 s after boot (ArduCopter: 41.5 s)."""
    config = VehicleConfig(sysid=1, home=HOME, autopilot=autopilot, estimate_delay_s=5.0)
    sim = Simulator([config])
    if mission is not None:
        home = [MissionItem(0, 0, 16)] if autopilot == "ardupilot" else []
        sim.load_mission(1, home + mission)
    return sim, sim.vehicle(1).flight


def local(sim: Simulator) -> tuple[float, float]:
    state = sim.state(1)
    east, north, _ = pymap3d.geodetic2enu(state.lat, state.lon, HOME[2], *HOME)
    return east, north


def said(flight) -> list[str]:
    """The STATUSTEXTs the flight controller says from now on."""
    texts: list[str] = []
    flight._say = lambda severity, text: texts.append(text)
    return texts


def airborne_in_guided(sim: Simulator, flight, alt: float = 20.0) -> None:
    sim.advance(5.0)
    assert flight.set_mode(FlightMode.GUIDED, sim.sim_time) == ACCEPTED
    assert flight.arm(sim.sim_time) == ACCEPTED
    assert flight.takeoff(alt, sim.sim_time) == ACCEPTED
    sim.advance(alt / 2.5 + 5.0)
    assert sim.state(1).alt == pytest.approx(alt, abs=0.3)


def test_arming_waits_for_the_estimate_and_an_idle_armed_vehicle_disarms_after_ten_seconds():
    sim, flight = make()
    sim.advance(4.0)
    assert flight.arm(sim.sim_time) == FAILED
    sim.advance(1.0)
    assert flight.arm(sim.sim_time) == ACCEPTED
    sim.advance(9.9)
    assert flight.armed
    sim.advance(0.2)
    assert not flight.armed


@pytest.mark.parametrize(
    ("autopilot", "param"), [("ardupilot", "DISARM_DELAY"), ("px4", "COM_DISARM_PRFLT")]
)
def test_a_disarm_delay_of_zero_keeps_an_idle_vehicle_armed(autopilot: str, param: str):
    sim, flight = make(autopilot)
    flight.params.set(param, 0)
    sim.advance(5.0)
    assert flight.arm(sim.sim_time) == ACCEPTED
    sim.advance(60.0)
    assert flight.armed


def test_auto_from_the_ground_waits_for_mission_start():
    sim, flight = make(mission=[takeoff(), at(0, 30), land()])
    sim.advance(5.0)
    flight.set_mode(FlightMode.GUIDED, sim.sim_time)
    flight.arm(sim.sim_time)
    assert flight.set_mode(FlightMode.AUTO, sim.sim_time) == ACCEPTED
    sim.advance(3.0)
    assert sim.state(1).alt == 0.0 and sim.state(1).mission_state == 2
    assert flight.start_mission(sim.sim_time) == ACCEPTED
    sim.advance(3.0)
    assert sim.state(1).alt > 1.0 and sim.state(1).mission_state == 3
    sim.advance(60.0)
    state = sim.state(1)
    assert not state.armed and state.alt == 0.0
    assert (state.mode, state.mission_seq, state.mission_state) == ("AUTO", 1, 3)  # rewound
    assert math.hypot(*(a - b for a, b in zip(local(sim), (0, 30), strict=True))) < 2.0


def test_airborne_switch_to_auto_continues_and_a_reached_takeoff_completes_at_once():
    sim, flight = make(mission=[takeoff(10.0), at(40, 0), land()])
    airborne_in_guided(sim, flight)
    assert flight.set_mode(FlightMode.AUTO, sim.sim_time) == ACCEPTED
    sim.advance(0.1)
    assert sim.state(1).mission_seq == 2  # take-off skipped: already above 10 m
    sim.advance(10.0)
    assert local(sim)[0] > 30.0


def test_waypoint_hold_time_stops_and_waits():
    sim, flight = make(mission=[takeoff(), at(20, 0, p1=5.0), at(40, 0)])
    airborne_in_guided(sim, flight)
    flight.set_mode(FlightMode.AUTO, sim.sim_time)
    positions = []
    for _ in range(300):  # two 20 m S-curve legs and the 5 s hold
        sim.advance(0.1)
        positions.append(local(sim)[0])
    stopped = [east for east in positions if abs(east - 20.0) < 0.2]
    assert len(stopped) >= 45  # ~5 s at the waypoint
    assert positions[-1] == pytest.approx(40.0, abs=0.3)


def test_pause_holds_and_continue_resumes():
    sim, flight = make(mission=[takeoff(), at(200, 0), land()])
    airborne_in_guided(sim, flight)
    flight.set_mode(FlightMode.AUTO, sim.sim_time)
    sim.advance(5.0)
    assert flight.pause(sim.sim_time) == ACCEPTED
    sim.advance(10.0)  # an S-curve stop from the speed reached: about 7 s
    paused_at = local(sim)[0]
    sim.advance(3.0)
    assert local(sim)[0] == pytest.approx(paused_at, abs=0.05)
    assert sim.state(1).mission_state == 4
    assert flight.resume(sim.sim_time) == ACCEPTED
    sim.advance(8.0)  # an S-curve start from rest: over 10 m in 8 s
    assert local(sim)[0] > paused_at + 5.0


def test_a_paused_arducopter_mission_that_runs_past_its_waypoint_goes_on_to_the_next():
    """ArduCopter's pause runs the track's clock down while the mission is updated: a
    waypoint the paused curve runs past is reached, and the next one is current, still
    paused. (The mock kept the item; an approach's MISSION_SET_CURRENT then sent the
    vehicle 16 m back to the waypoint: fuzzed flight 7548.)"""
    sim, flight = make(mission=[takeoff(), at(60, 0), at(200, 4), land()])
    airborne_in_guided(sim, flight)
    flight.set_mode(FlightMode.AUTO, sim.sim_time)
    while local(sim)[0] < 52.0:  # at speed, 8 m short of the waypoint
        sim.advance(0.1)
    assert sim.state(1).mission_seq == 2
    assert flight.pause(sim.sim_time) == ACCEPTED
    sim.advance(15.0)
    stopped = local(sim)[0]
    assert stopped > 61.0  # ran past it
    assert sim.state(1).mission_seq == 3
    sim.advance(2.0)
    assert local(sim)[0] == pytest.approx(stopped, abs=0.05)  # still paused
    assert flight.resume(sim.sim_time) == ACCEPTED
    sim.advance(5.0)
    assert local(sim)[0] > stopped + 2.0  # on to the next, not back


def test_arducopter_pauses_a_mission_only_on_the_way_to_a_place():
    """As ArduCopter's ModeAuto::pause (WP submode, destination not reached): not in a
    reached waypoint's hold, yes on the way to the landing's place, not in the descent;
    a refusal is FAILED with "Failed to pause"."""
    landing = at(20, 40, alt=0.0, command=mavlink.MAV_CMD_NAV_LAND)
    sim, flight = make(mission=[takeoff(), at(20, 0, p1=20.0), landing])
    texts = said(flight)
    airborne_in_guided(sim, flight)
    flight.set_mode(FlightMode.AUTO, sim.sim_time)
    sim.advance(15.0)  # at the waypoint, in its 20 s hold
    assert local(sim)[0] == pytest.approx(20.0, abs=0.3)
    assert flight.pause(sim.sim_time) == FAILED
    assert texts == ["Failed to pause"]
    for _ in range(300):  # until the hold is over: on the way to the landing's place
        sim.advance(0.1)
        if sim.state(1).mission_seq == 3:
            break
    assert sim.state(1).mission_seq == 3 and sim.state(1).alt > 19.0
    assert flight.pause(sim.sim_time) == ACCEPTED
    assert flight.resume(sim.sim_time) == ACCEPTED
    for _ in range(300):  # there, coming down
        sim.advance(0.1)
        if sim.state(1).alt < 15.0:
            break
    assert 10.0 < sim.state(1).alt < 15.0
    assert flight.pause(sim.sim_time) == FAILED
    assert flight.resume(sim.sim_time) == ACCEPTED  # AUTO resumes, paused or not


@pytest.mark.parametrize("mode", [FlightMode.LOITER, FlightMode.BRAKE])
def test_arducopter_pauses_and_resumes_nothing_but_auto_and_guided(mode: FlightMode):
    sim, flight = make()
    texts = said(flight)
    airborne_in_guided(sim, flight)
    assert flight.pause(sim.sim_time) == ACCEPTED  # GUIDED pauses
    assert flight.resume(sim.sim_time) == ACCEPTED
    assert flight.set_mode(mode, sim.sim_time) == ACCEPTED
    assert flight.pause(sim.sim_time) == FAILED
    assert flight.resume(sim.sim_time) == FAILED
    assert texts[-2:] == ["Failed to pause", "Failed to resume"]


def test_px4_holds_on_its_way_to_land():
    far_landing = at(200, 0, alt=0.0, command=mavlink.MAV_CMD_NAV_LAND)
    sim, flight = make("px4", [at(20, 0), far_landing])
    sim.advance(5.0)
    flight.set_mode(FlightMode.AUTO, sim.sim_time)
    assert flight.arm(sim.sim_time) == ACCEPTED
    sim.advance(40.0)
    assert sim.state(1).mission_seq == 1 and sim.state(1).alt > 2.0
    assert flight.pause(sim.sim_time) == ACCEPTED


def test_change_speed_item_sets_the_cruise_speed():
    speed = mavlink.MAV_CMD_DO_CHANGE_SPEED
    sim, flight = make(mission=[takeoff(), MissionItem(0, 2, speed, 1.0, 4.0), at(300, 0)])
    airborne_in_guided(sim, flight)
    flight.set_mode(FlightMode.AUTO, sim.sim_time)
    sim.advance(20.0)
    assert sim.state(1).ground_speed == pytest.approx(4.0, abs=0.01)


@pytest.mark.parametrize(
    ("mode", "result"),
    [
        (FlightMode.AUTO, ACCEPTED),
        (FlightMode.GUIDED, ACCEPTED),
        (FlightMode.RTL, ACCEPTED),
        (FlightMode.BRAKE, FAILED),
        (FlightMode.LAND, FAILED),
    ],
)
def test_arducopter_takes_a_speed_only_in_auto_guided_and_rtl(mode: FlightMode, result: int):
    """SITL 4.8.0-dev answered DO_CHANGE_SPEED FAILED to a vehicle in BRAKE (braked by
    its GCS failsafe), where the mock took it: the service's resume never sent it on."""
    sim, flight = make(mission=[takeoff(), at(200, 0), land()])
    airborne_in_guided(sim, flight)
    assert flight.set_mode(mode, sim.sim_time) == ACCEPTED
    assert flight.change_speed(3.0) == result


def test_rtl_climbs_flies_home_and_lands():
    sim, flight = make(mission=[takeoff(10.0), at(50, 50, alt=10.0)])
    airborne_in_guided(sim, flight, alt=10.0)
    flight.set_mode(FlightMode.AUTO, sim.sim_time)
    sim.advance(20.0)
    assert flight.set_mode(FlightMode.RTL, sim.sim_time) == ACCEPTED
    sim.advance(8.0)
    assert sim.state(1).alt == pytest.approx(15.0, abs=0.5)  # RTL_ALT_M 15
    sim.advance(60.0)
    state = sim.state(1)
    assert not state.armed and state.alt == 0.0
    assert math.hypot(*local(sim)) < 2.0


def test_a_landing_passes_10_m_at_landing_speed_and_disarms_once_the_ground_is_sure():
    """As ArduCopter SITL lands from 20 m: it slows on its way to LAND_ALT_LOW so as to be
    at LAND_SPD_MS there, and stays armed and LANDING for 2.1 s on the ground while its
    land detector makes sure. A mock that disarmed at the touch let a vehicle waiting for
    the landing go 2 s early."""
    sim, flight = make()
    airborne_in_guided(sim, flight)
    assert flight.set_mode(FlightMode.LAND, sim.sim_time) == ACCEPTED
    samples = []
    while sim.state(1).armed and sim.sim_time < 200.0:
        sim.advance(0.1)
        samples.append((sim.sim_time, sim.state(1).alt, flight.landed_state))
    down_at = next(t for t, alt, _ in samples if alt <= 0.0)
    disarmed_at = samples[-1][0]
    assert disarmed_at - down_at == pytest.approx(2.1, abs=0.15)
    on_ground = [state for t, _, state in samples[:-1] if t > down_at]
    assert set(on_ground) == {mavlink.MAV_LANDED_STATE_LANDING}
    at_10 = [t for t, alt, _ in samples if 9.9 <= alt <= 10.1]
    rate = 0.2 / (at_10[-1] - at_10[0])  # over the 20 cm about 10 m
    assert rate == pytest.approx(0.5, abs=0.2)  # SITL: 0.5-0.7 m/s about 10 m


def test_px4_mission_mode_takes_off_by_itself_and_reports_modes():
    sim, flight = make("px4", mission=[at(0, 20, alt=10.0), land()])
    sim.advance(5.0)
    assert flight.arm(sim.sim_time) == ACCEPTED
    assert flight.set_mode(FlightMode.AUTO, sim.sim_time) == ACCEPTED
    state = sim.state(1)
    assert state.custom_mode == (4 << 16) | (4 << 24)
    sim.advance(40.0)
    assert not sim.state(1).armed
    assert local(sim)[1] == pytest.approx(20.0, abs=2.0)


def test_same_inputs_same_track():
    tracks = []
    for _ in range(2):
        sim, flight = make(mission=[takeoff(), at(30, 10), at(0, 40), land()])
        airborne_in_guided(sim, flight)
        flight.set_mode(FlightMode.AUTO, sim.sim_time)
        sim.advance(30.0)
        tracks.append(sim.track(1))
    assert tracks[0] == tracks[1]
    assert len(tracks[0]) == round(sim.sim_time * 10)  # 10 samples per simulated second
