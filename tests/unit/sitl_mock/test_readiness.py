"""The ArduCopter start-up and mission reports, stepped by hand (no sockets): what a vehicle
sends is captured from a stand-in endpoint and decoded."""

from __future__ import annotations

import pymap3d
import pytest

from sitl_mock import MissionItem, Simulator, VehicleConfig
from sitl_mock.codec import Decoder, Encoder, Sender, mavlink
from sitl_mock.modes import FlightMode
from sitl_mock.readiness import Timeline, arducopter_arming_failures

HOME = (47.397742, 8.545594, 488.0)
GCS = Sender(255, 190, ("udp", ("127.0.0.1", 5000)))


class Capture:
    """Stands in for a socket: decodes everything the vehicle sends."""

    port = 0

    def __init__(self) -> None:
        self._decoder = Decoder()
        self.messages: list = []

    def send(self, data: bytes) -> None:
        self.messages += self._decoder.decode(data)

    async def close(self) -> None:
        return None

    def take(self, kind: str | None = None) -> list:
        taken = [m for m in self.messages if kind is None or m.get_type() == kind]
        self.messages = [m for m in self.messages if m not in taken]
        return taken


def make(**config) -> tuple[Simulator, Capture]:
    sim = Simulator([VehicleConfig(sysid=1, home=HOME, **config)])
    capture = Capture()
    sim.vehicle(1).endpoint = capture
    return sim, capture


def texts(capture: Capture) -> list[str]:
    return [m.text for m in capture.take("STATUSTEXT")]


def gcs_sends(sim: Simulator, msg) -> None:
    """A packet from the ground station, through the vehicle's decoder."""
    sim.vehicle(1).on_packet(Encoder(255, 190).encode(msg), GCS.link)


def arm(sim: Simulator) -> None:
    gcs_sends(sim, mavlink.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))


def test_the_observed_timeline_is_the_default_and_shortening_keeps_it_in_order():
    default = VehicleConfig(sysid=1).timeline()
    assert (default.ready_s, default.boot_status_s, default.origin_s, default.estimate_s) == (
        2.4,
        2.9,
        20.0,
        41.5,
    )
    short = Timeline.arducopter(position_s=None, estimate_s=3.0)
    assert short.ekf_s <= short.imu_s <= short.estimate_s == 3.0
    assert short.gps_fix_s <= short.origin_s <= short.estimate_s


@pytest.mark.parametrize(
    ("uptime", "guided", "expected"),
    [
        (1.0, True, ["System not initialised"]),
        (
            3.0,
            False,
            ["Accels inconsistent", "EKF attitude is bad", "AHRS: not using configured AHRS type"],
        ),
        (5.0, True, ["Accels inconsistent", "AHRS: waiting for home"]),
        (15.0, True, ["Gyros inconsistent", "AHRS: waiting for home"]),
        (21.0, True, ["Gyros inconsistent", "Need Position Estimate"]),
        (30.0, True, ["Need Position Estimate"]),
        (30.0, False, []),
        (42.0, True, []),
    ],
)
def test_arming_failures_follow_what_sitl_said_at_each_stage(uptime, guided, expected):
    timeline = VehicleConfig(sysid=1).timeline()
    assert arducopter_arming_failures(timeline, uptime, guided) == expected


def test_boot_ends_with_ardupilot_ready_the_boot_mode_and_room_for_a_mission():
    sim, capture = make()
    vehicle = sim.vehicle(1)
    assert vehicle.flight.set_mode(FlightMode.GUIDED, 0.0) == mavlink.MAV_RESULT_ACCEPTED
    gcs_sends(sim, mavlink.MAVLink_mission_count_message(1, 1, 3, 0))
    assert [m.type for m in capture.take("MISSION_ACK")] == [mavlink.MAV_MISSION_NO_SPACE]
    assert texts(capture) == ["Only 0 items are supported"]
    sim.advance(2.5)
    assert "ArduPilot Ready" in texts(capture)
    assert vehicle.flight.mode == FlightMode.STABILIZE
    assert sim.state(1).system_status == mavlink.MAV_STATE_BOOT
    sim.advance(0.5)
    assert sim.state(1).system_status == mavlink.MAV_STATE_STANDBY
    gcs_sends(sim, mavlink.MAVLink_mission_count_message(1, 1, 3, 0))
    assert capture.take("MISSION_REQUEST")[0].seq == 0


def test_home_is_announced_unasked_when_set_and_again_on_arming():
    sim, capture = make()
    sim.advance(19.9)
    assert capture.take("HOME_POSITION") == [] and capture.take("GPS_GLOBAL_ORIGIN") == []
    assert not sim.state(1).home_set and sim.state(1).position_known  # GPS fix at 10 s
    sim.advance(0.2)
    assert len(capture.take("HOME_POSITION")) == len(capture.take("GPS_GLOBAL_ORIGIN")) == 1
    sim.advance(10.0)
    arm(sim)  # STABILIZE: armable once the IMUs agree (23 s)
    sim.advance(0.1)
    assert sim.state(1).armed and len(capture.take("HOME_POSITION")) == 1


def test_every_failing_check_is_said_after_the_ack_and_prearm_repeats_every_30_s():
    sim, capture = make()
    sim.advance(5.0)
    vehicle = sim.vehicle(1)
    vehicle.flight.set_mode(FlightMode.GUIDED, sim.sim_time)
    capture.take()
    arm(sim)
    sent = [m.get_type() for m in capture.messages]
    assert sent == ["COMMAND_ACK", "STATUSTEXT", "STATUSTEXT"]
    assert texts(capture) == ["Arm: Accels inconsistent", "Arm: AHRS: waiting for home"]
    sim.advance(25.5)
    assert "PreArm: Need Position Estimate" in texts(capture)  # the gcs was heard: reports


def test_sys_status_bits_are_those_sitl_sends_at_each_stage():
    sim, _ = make()
    sim.advance(5.0)
    assert sim.state(1).sensors == (0x5371FC0F, 0x5341FC0F, 0x4751FC0F)
    sim.advance(21.0)
    assert sim.state(1).sensors == (0x5371FC2F, 0x5361FC2F, 0x5771FC2F)  # STABILIZE armable
    sim.vehicle(1).flight.set_mode(FlightMode.GUIDED, sim.sim_time)
    assert sim.state(1).sensors.health == 0x4771FC2F  # GUIDED needs the estimate: no PREARM


def at(east: float, north: float, alt: float = 10.0) -> MissionItem:
    lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, *HOME)
    return MissionItem(0, 6, 16, x=round(lat * 1e7), y=round(lon * 1e7), z=alt)


def test_reached_is_merged_per_step_sent_for_do_items_and_never_for_the_landing():
    sim, capture = make(estimate_delay_s=5.0)
    speed = MissionItem(0, 2, mavlink.MAV_CMD_DO_CHANGE_SPEED, 1.0, 5.0)
    mission = [
        MissionItem(0, 0, 16),
        MissionItem(0, 6, 22, z=10.0),
        speed,
        at(0, 20),
        MissionItem(0, 6, 21),
    ]
    sim.load_mission(1, mission)
    sim.advance(5.0)
    flight = sim.vehicle(1).flight
    flight.set_mode(FlightMode.GUIDED, sim.sim_time)
    assert flight.arm(sim.sim_time) == mavlink.MAV_RESULT_ACCEPTED
    flight.start_mission(sim.sim_time)
    capture.take()
    sim.advance(60.0)
    assert [m.seq for m in capture.take("MISSION_ITEM_REACHED")] == [2, 3]  # 1 merged into 2
    said = texts(capture)
    assert [t for t in said if t.startswith("Mission:")][:4] == [
        "Mission: 2 ChangeSpeed",
        "Mission: 3 WP",
        "Mission: 4 Land",
        "Mission: 1 Takeoff",
    ]
    assert "Reached command #3" in said
    state = sim.state(1)
    assert not state.armed and (state.mode, state.mission_seq, state.mission_state) == (
        "AUTO",
        1,
        mavlink.MISSION_STATE_ACTIVE,
    )
