"""pymavlink's own client against the mock over real loopback sockets: the mission
protocol and its edge cases, commands, parameters, telemetry, addressing and faults."""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from typing import Any, NamedTuple

import pytest

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil

from sitl_mock import Faults, Simulator, VehicleConfig

mavutil.set_dialect("ardupilotmega")
mavlink = mavutil.mavlink

HOME = (47.397742, 8.545594, 488.0)
SPEEDUP = 20.0
QUICK_ESTIMATE_S = 5.0
"""Most tests need an armable vehicle soon; the ArduCopter timeline itself is tested apart."""
BOOTING = mavlink.MAV_STATE_BOOT


class Item(NamedTuple):
    command: int
    frame: int = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    x: int = 0
    y: int = 0
    z: float = 0.0
    p1: float = 0.0
    p2: float = 0.0


def waypoints(n: int, first_is_home: bool = True) -> list[Item]:
    home = Item(16, mavlink.MAV_FRAME_GLOBAL, 473977420, 85455940, 488.0)
    items = [home] if first_is_home else []
    items.append(Item(22, z=15.0))
    for k in range(n - len(items)):
        items.append(
            Item(
                16,
                x=473977420 + 100 * (k + 1),
                y=85455940 + 50 * k,
                z=20.0 + k % 7,
                p1=k % 3,
                p2=k % 2,
            )
        )
    return items


class Gcs:
    """A minimal ground station on pymavlink's mavlink_connection."""

    def __init__(self, url: str, sysid: int = 255, compid: int = 190, target: int = 1) -> None:
        self.link = mavutil.mavlink_connection(url, source_system=sysid, source_component=compid)
        self.target = target
        self.requests: list[tuple[str, int]] = []
        self.link.mav.heartbeat_send(6, 8, 0, 0, 0)

    def close(self) -> None:
        self.link.close()

    def drain(self) -> None:
        while self.link.recv_match(blocking=False) is not None:
            pass

    def recv(
        self,
        types: str | list[str],
        timeout: float = 2.0,
        where: Callable[..., bool] = lambda m: True,
    ) -> Any:
        """The first message of `types` that `where` accepts (a pymavlink message), or None."""
        deadline = time.monotonic() + timeout
        while (remaining := deadline - time.monotonic()) > 0:
            msg = self.link.recv_match(type=types, blocking=True, timeout=remaining)
            if msg is not None and where(msg):
                return msg
        return None

    def collect(self, seconds: float, types: list[str] | None = None) -> list:
        found, deadline = [], time.monotonic() + seconds
        while (remaining := deadline - time.monotonic()) > 0:
            msg = self.link.recv_match(type=types, blocking=True, timeout=remaining)
            if msg is not None and msg.get_type() != "BAD_DATA":
                found.append(msg)
        return found

    def command(
        self, command: int, *params: float, confirmation: int = 0, timeout: float = 2.0
    ) -> Any:
        padded = [*params, *[0.0] * (7 - len(params))]
        self.link.mav.command_long_send(self.target, 1, command, confirmation, *padded)
        return self.recv("COMMAND_ACK", timeout, where=lambda m: m.command == command)

    def send_item(self, seq: int, item: Item, mission_type: int = 0) -> None:
        self.link.mav.mission_item_int_send(
            self.target,
            1,
            seq,
            item.frame,
            item.command,
            0,
            1,
            item.p1,
            item.p2,
            0,
            0,
            item.x,
            item.y,
            item.z,
            mission_type,
        )

    def upload(
        self, items: list[Item], mission_type: int = 0, timeout: float = 10.0, retry_s: float = 0.5
    ) -> int | None:
        """Answer MISSION_REQUEST and MISSION_REQUEST_INT; resend on silence; final ACK type."""
        self.drain()
        self.link.mav.mission_count_send(self.target, 1, len(items), mission_type)
        last: int | None = None
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            msg = self.recv(
                ["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"],
                retry_s,
                where=lambda m: m.mission_type == mission_type,
            )
            if msg is None:
                if last is None:
                    self.link.mav.mission_count_send(self.target, 1, len(items), mission_type)
                else:
                    self.send_item(last, items[last], mission_type)
            elif msg.get_type() == "MISSION_ACK":
                if msg.type != mavlink.MAV_MISSION_INVALID_SEQUENCE:
                    return msg.type
            else:
                self.requests.append((msg.get_type(), msg.seq))
                self.send_item(msg.seq, items[msg.seq], mission_type)
                last = msg.seq
        return None

    def download(
        self,
        mission_type: int = 0,
        timeout: float = 10.0,
        retry_s: float = 0.5,
        legacy: bool = False,
    ) -> list | None:
        self.drain()
        count = None
        deadline = time.monotonic() + timeout
        while count is None and time.monotonic() < deadline:
            self.link.mav.mission_request_list_send(self.target, 1, mission_type)
            count = self.recv("MISSION_COUNT", retry_s)
        if count is None:
            return None
        items: list[Any] = []
        kind = "MISSION_ITEM" if legacy else "MISSION_ITEM_INT"
        request = (
            self.link.mav.mission_request_send if legacy else self.link.mav.mission_request_int_send
        )
        while len(items) < count.count and time.monotonic() < deadline:
            seq = len(items)
            request(self.target, 1, seq, mission_type)
            msg = self.recv(kind, retry_s, where=lambda m, seq=seq: m.seq == seq)
            if msg is not None:
                items.append(msg)
        self.link.mav.mission_ack_send(self.target, 1, 0, mission_type)
        return items if len(items) == count.count else None


def as_items(downloaded: list) -> list[Item]:
    return [Item(m.command, m.frame, m.x, m.y, m.z, m.param1, m.param2) for m in downloaded]


def as_ardupilot_stores(items: list[Item]) -> list[Item]:
    """What ArduCopter SITL returned for our items (docs/sitl_mock.md, wire facts): frame 6
    comes back 3, a waypoint's acceptance radius (param2) is dropped, hold times are whole
    seconds, altitudes whole centimetres."""
    stored = []
    for item in items:
        frame = (
            mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
            if item.frame == (mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)
            else item.frame
        )
        p2 = 0.0 if item.command == mavlink.MAV_CMD_NAV_WAYPOINT else item.p2
        stored.append(item._replace(frame=frame, p1=float(int(item.p1)), p2=p2))
    return stored


def wait_booted(gcs: Gcs, timeout: float = 5.0) -> bool:
    """A ground station waits for the HEARTBEAT to leave BOOT before uploading."""
    return gcs.recv("HEARTBEAT", timeout, where=lambda m: m.system_status != BOOTING) is not None


@pytest.fixture
def make_sim() -> Iterator[Callable[..., tuple[Simulator, Gcs]]]:
    stack: list[tuple[AbstractContextManager[Simulator], Gcs]] = []

    def start(
        autopilot: str = "ardupilot",
        transport: str = "udp",
        speedup: float = SPEEDUP,
        faults: Faults | None = None,
        booted: bool = True,
        wall_clock: Callable[[], float] = time.monotonic,
        **config,
    ) -> tuple[Simulator, Gcs]:
        config.setdefault("estimate_delay_s", QUICK_ESTIMATE_S)
        vehicle = VehicleConfig(
            sysid=1,
            home=HOME,
            autopilot=autopilot,
            transport=transport,
            faults=faults or Faults(),
            **config,
        )
        sim = Simulator([vehicle], speedup=speedup, seed=1, wall_clock=wall_clock)
        running = sim.running()
        running.__enter__()
        gcs = Gcs(sim.connection_string(1))
        stack.append((running, gcs))
        assert gcs.recv("HEARTBEAT", 3.0) is not None
        if booted:
            assert wait_booted(gcs)
        return sim, gcs

    yield start
    for running, gcs in stack:
        gcs.close()
        running.__exit__(None, None, None)


FLAVOURS = [("ardupilot", "udp"), ("ardupilot", "tcp"), ("px4", "udp"), ("px4", "tcp")]


# -- the mission protocol -----------------------------------------------------------------


@pytest.mark.parametrize(("autopilot", "transport"), FLAVOURS)
def test_upload_download_round_trip(make_sim, autopilot, transport):
    sim, gcs = make_sim(autopilot, transport)
    ardupilot = autopilot == "ardupilot"
    items = waypoints(12, first_is_home=ardupilot)
    assert gcs.upload(items) == mavlink.MAV_MISSION_ACCEPTED
    expected_request = "MISSION_REQUEST" if ardupilot else "MISSION_REQUEST_INT"
    assert gcs.requests == [(expected_request, seq) for seq in range(len(items))]
    downloaded = as_items(gcs.download())
    if ardupilot:  # item 0 comes back as the current home, the others as ArduPilot stores them
        home = downloaded.pop(0)
        assert (home.frame, home.x, home.y, home.z) == (0, 473977420, 85455940, 488.0)
        items = items[1:]
        assert downloaded == as_ardupilot_stores(items)
    else:
        assert downloaded == items
    legacy = gcs.download(legacy=True)
    legacy_x = [m.x * 1e7 for m in legacy[-len(items) :]]
    assert legacy_x == pytest.approx([i.x for i in items], abs=100)  # float32 degrees
    assert len(sim.mission(1)) == len(items) + ardupilot


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_clear_and_count_zero_empty_the_mission(make_sim, autopilot):
    _sim, gcs = make_sim(autopilot)
    home_items = 1 if autopilot == "ardupilot" else 0
    assert gcs.upload(waypoints(5)) == mavlink.MAV_MISSION_ACCEPTED
    gcs.link.mav.mission_clear_all_send(1, 1, 0)
    assert gcs.recv("MISSION_ACK").type == mavlink.MAV_MISSION_ACCEPTED
    assert len(gcs.download()) == home_items
    assert gcs.upload(waypoints(5)) == mavlink.MAV_MISSION_ACCEPTED
    assert gcs.upload([]) == mavlink.MAV_MISSION_ACCEPTED
    assert len(gcs.download()) == home_items
    current = gcs.recv("MISSION_CURRENT", 3.0) if autopilot == "px4" else None
    assert current is None or current.mission_state == 1


def test_set_current_by_message_and_by_command(make_sim):
    sim, gcs = make_sim()
    assert gcs.upload(waypoints(6)) == mavlink.MAV_MISSION_ACCEPTED
    gcs.link.mav.mission_set_current_send(1, 1, 3)
    current = gcs.recv("MISSION_CURRENT")
    assert (current.seq, current.total, current.mission_state) == (3, 5, 2)
    gcs.link.mav.command_long_send(
        1, 1, mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, 0, 4, 0, 0, 0, 0, 0, 0
    )
    seen = gcs.collect(0.3, ["COMMAND_ACK", "MISSION_CURRENT"])
    assert [m.result for m in seen if m.get_type() == "COMMAND_ACK"] == [0]
    assert [m.seq for m in seen if m.get_type() == "MISSION_CURRENT"] == [4]
    assert sim.state(1).mission_seq == 4
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, 9).result == (
        mavlink.MAV_RESULT_FAILED
    )


def test_too_many_items_is_no_space(make_sim):
    _sim, gcs = make_sim(mission_capacity=50)
    assert gcs.upload(waypoints(51)) == mavlink.MAV_MISSION_NO_SPACE
    assert gcs.upload(waypoints(50)) == mavlink.MAV_MISSION_ACCEPTED


@pytest.mark.parametrize(
    ("bad", "result"),
    [
        (Item(16, mavlink.MAV_FRAME_LOCAL_NED, 1, 1, 5.0), mavlink.MAV_MISSION_UNSUPPORTED_FRAME),
        (
            Item(mavlink.MAV_CMD_DO_SET_SERVO, mavlink.MAV_FRAME_MISSION),
            mavlink.MAV_MISSION_UNSUPPORTED,
        ),
    ],
)
def test_unsupported_item_is_refused_and_the_previous_mission_stays(make_sim, bad, result):
    _sim, gcs = make_sim()
    good = waypoints(4)
    assert gcs.upload(good) == mavlink.MAV_MISSION_ACCEPTED
    assert gcs.upload([*waypoints(3), bad]) == result
    assert as_items(gcs.download())[1:] == as_ardupilot_stores(good[1:])


def test_out_of_sequence_item_is_invalid_sequence_and_the_upload_continues(make_sim):
    sim, gcs = make_sim()
    items = waypoints(4)
    gcs.link.mav.mission_count_send(1, 1, 4, 0)
    assert gcs.recv("MISSION_REQUEST").seq == 0
    gcs.send_item(2, items[2])
    assert gcs.recv("MISSION_ACK").type == mavlink.MAV_MISSION_INVALID_SEQUENCE
    for seq in range(4):
        gcs.send_item(seq, items[seq])
    assert gcs.recv("MISSION_ACK").type == mavlink.MAV_MISSION_ACCEPTED
    assert len(sim.mission(1)) == 4


def test_interrupted_upload_keeps_the_previous_mission(make_sim):
    sim, gcs = make_sim()
    old = waypoints(5)
    assert gcs.upload(old) == mavlink.MAV_MISSION_ACCEPTED
    gcs.link.mav.mission_count_send(1, 1, 8, 0)
    assert gcs.recv("MISSION_REQUEST").seq == 0
    gcs.send_item(0, waypoints(8)[0])
    assert len(sim.mission(1)) == 5
    new = waypoints(3)
    assert gcs.upload(new) == mavlink.MAV_MISSION_ACCEPTED  # a new COUNT restarts the upload
    assert as_items(gcs.download())[1:] == as_ardupilot_stores(new[1:])


def test_second_ground_station_mid_upload_is_denied(make_sim):
    sim, gcs = make_sim()
    other = Gcs(sim.connection_string(1), sysid=245, compid=190)
    try:
        gcs.link.mav.mission_count_send(1, 1, 3, 0)
        assert gcs.recv("MISSION_REQUEST") is not None
        other.drain()
        other.link.mav.mission_count_send(1, 1, 2, 0)
        ack = other.recv("MISSION_ACK", where=lambda m: m.target_system == 245)
        assert ack.type == mavlink.MAV_MISSION_DENIED
        items = waypoints(3)
        for seq in range(3):
            gcs.send_item(seq, items[seq])
        assert gcs.recv("MISSION_ACK", where=lambda m: m.target_system == 255).type == 0
    finally:
        other.close()


def test_silent_ground_station_is_re_requested_then_cancelled(make_sim):
    """ArduPilot asks again every second and cancels after 8 s of silence; those are protocol
    timers, on the wall clock, so this vehicle's wall clock is made to run 10x fast."""
    fast_wall = 10.0
    sim, gcs = make_sim(speedup=1.0, wall_clock=lambda: time.monotonic() * fast_wall)
    gcs.link.mav.mission_count_send(1, 1, 3, 0)
    assert gcs.recv("MISSION_REQUEST").seq == 0
    gcs.send_item(0, waypoints(3)[0])
    seen = gcs.collect(1.5, ["MISSION_REQUEST", "MISSION_ACK", "STATUSTEXT"])
    requests = [m for m in seen if m.get_type() == "MISSION_REQUEST"]
    acks = [m.type for m in seen if m.get_type() == "MISSION_ACK"]
    texts = [m.text for m in seen if m.get_type() == "STATUSTEXT"]
    assert acks == [mavlink.MAV_MISSION_OPERATION_CANCELLED]
    assert 7 <= len(requests) <= 8 and {m.seq for m in requests} == {1}  # 1 s apart for 8 s
    assert "Mission upload timeout" in texts
    assert len(sim.mission(1)) == 1


def test_protocol_timers_do_not_shrink_with_the_speed_up(make_sim):
    """At 50x an 8 s simulated silence passes in 0.16 s, but the upload is still open after a
    second of real silence: a slow ground station step is not taken for a departed one."""
    sim, gcs = make_sim(speedup=50.0)
    gcs.link.mav.mission_count_send(1, 1, 3, 0)
    assert gcs.recv("MISSION_REQUEST").seq == 0
    seen = gcs.collect(1.0, ["MISSION_REQUEST", "MISSION_ACK"])
    assert [m.get_type() for m in seen] in ([], ["MISSION_REQUEST"])  # re-asked at most once
    assert sim.vehicle(1).store.uploading
    items = waypoints(3)
    for seq in range(3):
        gcs.send_item(seq, items[seq])
    assert gcs.recv("MISSION_ACK").type == mavlink.MAV_MISSION_ACCEPTED


def test_lost_final_ack_is_recovered_by_resending_the_last_item(make_sim):
    _sim, gcs = make_sim()
    items = waypoints(4)
    assert gcs.upload(items) == mavlink.MAV_MISSION_ACCEPTED
    gcs.send_item(3, items[3])
    assert gcs.recv("MISSION_ACK").type == mavlink.MAV_MISSION_ACCEPTED


def test_fence_and_rally_missions_are_kept_apart(make_sim):
    _sim, gcs = make_sim()
    rally = [Item(mavlink.MAV_CMD_NAV_RALLY_POINT, x=473977000, y=85456000, z=30.0)]
    assert gcs.upload(rally, mission_type=2) == mavlink.MAV_MISSION_ACCEPTED
    assert gcs.upload(waypoints(3)) == mavlink.MAV_MISSION_ACCEPTED
    # ArduPilot gives a rally point back in frame 3 (MissionItemProtocol_Rally::get_item)
    stored = [rally[0]._replace(frame=mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT)]
    assert as_items(gcs.download(mission_type=2)) == stored
    assert len(gcs.download()) == 3


# -- commands, parameters, telemetry ------------------------------------------------------


def arm_attempt(gcs: Gcs, force: bool = False) -> tuple[list[int], list[str]]:
    """One arming command: the COMMAND_ACK results and every STATUSTEXT that came with it."""
    gcs.drain()
    gcs.link.mav.command_long_send(1, 1, 400, 0, 1, 21196 if force else 0, 0, 0, 0, 0, 0)
    ack = gcs.recv("COMMAND_ACK", where=lambda m: m.command == 400)
    seen = gcs.collect(0.2, ["STATUSTEXT"])
    return [ack.result] if ack else [], [m.text for m in seen]


ARDUCOPTER_ARM_TEXTS = {
    "Arm: Accels inconsistent",
    "Arm: Gyros inconsistent",
    "Arm: EKF attitude is bad",
    "Arm: AHRS: not using configured AHRS type",
    "Arm: Need Alt Estimate",
    "Arm: AHRS: waiting for home",
    "Arm: Need Position Estimate",
}


def test_arming_is_refused_with_every_failing_check_until_the_estimate_is_ready(make_sim):
    """As ArduCopter SITL: several texts per refused attempt, "Need Position Estimate" in
    GUIDED once the IMUs agree, the periodic PreArm report; forcing helps only in STABILIZE."""
    sim, gcs = make_sim(estimate_delay_s=1000.0)
    results, texts = arm_attempt(gcs)
    assert results == [mavlink.MAV_RESULT_FAILED]
    assert texts and set(texts) <= ARDUCOPTER_ARM_TEXTS
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 4).result == 0  # disarmed: any mode
    assert sim.wait_until(lambda: sim.state(1).uptime > 25.0, 5.0)  # IMUs agree, home is set
    assert arm_attempt(gcs) == ([mavlink.MAV_RESULT_FAILED], ["Arm: Need Position Estimate"])
    prearm = gcs.recv("STATUSTEXT", 5.0, where=lambda m: m.text.startswith("PreArm:"))
    assert prearm.text == "PreArm: Need Position Estimate"  # every 30 s while disarmed
    assert arm_attempt(gcs, force=True)[0] == [mavlink.MAV_RESULT_FAILED]
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 0).result == 0
    assert arm_attempt(gcs)[0] == [mavlink.MAV_RESULT_ACCEPTED]  # STABILIZE needs no position
    assert sim.state(1).armed


def test_a_command_before_the_end_of_the_boot_is_answered_but_the_boot_sets_the_mode(make_sim):
    """During boot: uploads NO_SPACE ("Only 0 items are supported"), arming "System not
    initialised", a mode accepted and then replaced by STABILIZE at "ArduPilot Ready"."""
    sim, gcs = make_sim(speedup=1.0, booted=False)
    assert sim.state(1).system_status == BOOTING
    assert gcs.upload(waypoints(3), timeout=1.0) == mavlink.MAV_MISSION_NO_SPACE
    assert gcs.recv("STATUSTEXT").text == "Only 0 items are supported"
    assert arm_attempt(gcs) == ([mavlink.MAV_RESULT_FAILED], ["Arm: System not initialised"])
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 4).result == 0
    ready = gcs.recv("STATUSTEXT", 5.0, where=lambda m: m.text == "ArduPilot Ready")
    assert ready is not None
    assert gcs.recv("HEARTBEAT", where=lambda m: m.custom_mode == 0) is not None
    assert wait_booted(gcs)
    assert gcs.upload(waypoints(3)) == mavlink.MAV_MISSION_ACCEPTED


def test_arming_in_auto_fails_and_unknown_commands_are_unsupported(make_sim):
    sim, gcs = make_sim()
    assert sim.wait_until(lambda: sim.state(1).estimate_ready, 3.0)
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 3).result == 0
    assert gcs.recv("HEARTBEAT", where=lambda m: m.custom_mode == 3) is not None
    gcs.drain()
    gcs.link.mav.command_long_send(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)
    seen = gcs.collect(0.3, ["COMMAND_ACK", "STATUSTEXT"])
    assert [m.result for m in seen if m.get_type() == "COMMAND_ACK"] == [mavlink.MAV_RESULT_FAILED]
    assert "Arm: Auto mode not armable" in [m.text for m in seen if m.get_type() == "STATUSTEXT"]
    assert gcs.command(mavlink.MAV_CMD_USER_1).result == mavlink.MAV_RESULT_UNSUPPORTED
    assert gcs.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10).result == (
        mavlink.MAV_RESULT_FAILED
    )  # disarmed


def test_a_re_sent_guided_takeoff_is_carried_out_again_as_on_arducopter(make_sim):
    """ArduPilot never reads `confirmation`: a re-sent NAV_TAKEOFF is a new one, accepted
    while the vehicle is still on the ground and refused once it has lifted off (as a
    lost ACK's re-send is refused: the ground station takes that for a take-off)."""
    sim, gcs = make_sim()
    assert sim.wait_until(lambda: sim.state(1).estimate_ready, 3.0)
    gcs.link.mav.set_mode_send(1, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4)
    assert gcs.recv("COMMAND_ACK", where=lambda m: m.command == 11).result == 0
    assert gcs.command(400, 1).result == 0
    heartbeat = gcs.recv("HEARTBEAT", where=lambda m: m.base_mode & 128)
    assert heartbeat.base_mode == 0xD9 and heartbeat.custom_mode == 4
    takeoff = (mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10)
    assert gcs.command(*takeoff).result == 0
    assert gcs.command(*takeoff, confirmation=1).result == 0  # still on the ground
    assert sim.wait_until(lambda: sim.state(1).alt > 1.0, 5.0)
    assert gcs.command(*takeoff, confirmation=2).result == mavlink.MAV_RESULT_FAILED
    assert sim.wait_until(lambda: sim.state(1).alt > 9.5, 5.0)
    assert gcs.command(*takeoff).result == mavlink.MAV_RESULT_FAILED  # already flying


@pytest.mark.parametrize(
    ("autopilot", "speed_param", "default"),
    [("ardupilot", "WP_SPD", 10.0), ("px4", "MPC_XY_CRUISE", 5.0)],
)
def test_parameters_list_read_and_set(make_sim, autopilot, speed_param, default):
    sim, gcs = make_sim(autopilot)
    gcs.drain()
    gcs.link.mav.param_request_list_send(1, 1)
    values = gcs.collect(0.5, ["PARAM_VALUE"])
    count = values[0].param_count
    assert count >= 10 and sorted(v.param_index for v in values) == list(range(count))
    by_name = {v.param_id: v for v in values}
    assert by_name[speed_param].param_value == default
    gcs.link.mav.param_request_read_send(1, 1, speed_param.encode(), -1)
    assert gcs.recv("PARAM_VALUE").param_index == by_name[speed_param].param_index
    gcs.link.mav.param_request_read_send(1, 1, b"", 2)
    assert (
        gcs.recv("PARAM_VALUE").param_id == sorted(values, key=lambda v: v.param_index)[2].param_id
    )
    gcs.link.mav.param_set_send(1, 1, speed_param.encode(), default / 2, 9)
    reply = gcs.recv("PARAM_VALUE", where=lambda m: m.param_id == speed_param)
    assert reply.param_value == default / 2
    assert sim.vehicle(1).flight.limits().cruise_speed == pytest.approx(
        default / 2  # both in m/s (ArduCopter 4.8: WP_SPD)
    )


def test_ardupilot_streams_nothing_until_asked(make_sim):
    _sim, gcs = make_sim()
    quiet = {m.get_type() for m in gcs.collect(0.5)}
    assert quiet <= {"HEARTBEAT", "STATUSTEXT", "TIMESYNC", "HOME_POSITION", "GPS_GLOBAL_ORIGIN"}
    gcs.link.mav.request_data_stream_send(1, 1, mavlink.MAV_DATA_STREAM_ALL, 4, 1)
    assert gcs.recv("GLOBAL_POSITION_INT", 2.0) is not None
    assert gcs.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 33, 100_000).result == 0
    gcs.drain()
    stamps = [m.time_boot_ms for m in gcs.collect(0.5, ["GLOBAL_POSITION_INT"])][2:]
    assert len(stamps) > 5
    gaps = {b - a for a, b in itertools.pairwise(stamps)}
    assert gaps == {100}  # 10 Hz in simulated time


def test_px4_streams_by_default_with_mavsdk_health_and_version(make_sim):
    sim, gcs = make_sim("px4")
    assert sim.wait_until(lambda: sim.state(1).estimate_ready, 3.0)
    types = {m.get_type() for m in gcs.collect(0.5)}
    assert {
        "GLOBAL_POSITION_INT",
        "SYS_STATUS",
        "ATTITUDE",
        "EXTENDED_SYS_STATE",
        "HOME_POSITION",
        "GPS_RAW_INT",
        "VFR_HUD",
    } <= types
    status = gcs.recv("SYS_STATUS")
    assert status.onboard_control_sensors_health == status.onboard_control_sensors_present
    assert status.onboard_control_sensors_present & mavlink.MAV_SYS_STATUS_PREARM_CHECK
    assert gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, 148).result == 0
    version = gcs.recv("AUTOPILOT_VERSION")
    assert version.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    assert version.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, 242).result == 0
    assert gcs.recv("HOME_POSITION").latitude == 473977420
    heartbeat = gcs.recv("HEARTBEAT")
    assert (heartbeat.autopilot, heartbeat.type) == (mavlink.MAV_AUTOPILOT_PX4, 2)


def test_packets_for_another_system_are_ignored(make_sim):
    sim, gcs = make_sim()
    gcs.target = 2
    assert gcs.command(400, 1, 21196, timeout=0.5) is None
    gcs.link.mav.param_request_list_send(2, 1)
    gcs.link.mav.mission_count_send(2, 1, 3, 0)
    assert gcs.collect(0.5, ["PARAM_VALUE", "MISSION_REQUEST", "MISSION_ACK"]) == []
    assert not sim.state(1).armed


# -- faults -------------------------------------------------------------------------------


def test_hundred_items_through_thirty_percent_loss_each_way(make_sim):
    """Each lost request costs one re-request period (1 s of wall clock on ArduPilot), so the
    vehicle's protocol clock runs 4x fast here to keep the test short; no faster, because
    its upload timeout (8 s) shrinks with it: at 10x a 0.8 s stall of this process beside
    `stress-ng --cpu 2` ended an upload with MAV_MISSION_ERROR."""
    _sim, gcs = make_sim(
        faults=Faults(loss_in=0.3, loss_out=0.3), wall_clock=lambda: time.monotonic() * 4.0
    )
    items = waypoints(100)
    assert gcs.upload(items, timeout=30.0, retry_s=0.05) == mavlink.MAV_MISSION_ACCEPTED
    assert sum(seq == 99 for _, seq in gcs.requests) >= 1
    downloaded = gcs.download(timeout=30.0, retry_s=0.05)
    assert downloaded is not None
    assert as_items(downloaded)[1:] == as_ardupilot_stores(items[1:])


def test_reboot_mid_upload_comes_back_empty_disarmed_at_home(make_sim):
    sim, gcs = make_sim()
    assert gcs.upload(waypoints(4)) == mavlink.MAV_MISSION_ACCEPTED
    gcs.link.mav.mission_count_send(1, 1, 10, 0)
    assert gcs.recv("MISSION_REQUEST").seq == 0
    before = sim.state(1).uptime
    sim.reboot(1)
    gcs.send_item(0, waypoints(10)[0])
    assert gcs.collect(0.7 / SPEEDUP) == []  # silent while rebooting
    heartbeat = gcs.recv("HEARTBEAT", 3.0)
    assert heartbeat is not None and heartbeat.system_status == mavlink.MAV_STATE_BOOT
    state = sim.state(1)
    assert state.uptime >= 1.0 - 1e-9  # silent for a second first (float steps)
    assert state.t - state.uptime >= before  # time_boot_ms counts from the reboot
    assert not state.armed and state.alt == 0.0 and state.mission_total == 0
    assert len(sim.mission(1)) == 1
    assert wait_booted(gcs)
    assert gcs.upload(waypoints(10)) == mavlink.MAV_MISSION_ACCEPTED


def test_vehicle_that_rejects_missions(make_sim):
    sim, gcs = make_sim(faults=Faults(reject_missions=True, reject_at="count"))
    assert gcs.upload(waypoints(3)) == mavlink.MAV_MISSION_ERROR
    assert gcs.requests == []
    sim.set_faults(1, Faults(reject_missions=True))
    assert gcs.upload(waypoints(3)) == mavlink.MAV_MISSION_ERROR
    assert len(gcs.requests) == 3
    sim.set_faults(1, Faults())
    assert gcs.upload(waypoints(3)) == mavlink.MAV_MISSION_ACCEPTED


def test_silence_drops_the_link_for_a_while(make_sim):
    sim, gcs = make_sim()
    sim.silence(1, seconds=10.0)  # 0.5 s of wall time at 20x
    gcs.drain()
    assert gcs.collect(0.3, ["HEARTBEAT"]) == []
    assert gcs.recv("HEARTBEAT", 2.0) is not None


def test_reboot_command_restarts_the_boot_and_is_refused_while_armed(make_sim):
    sim, gcs = make_sim()
    assert gcs.upload(waypoints(4)) == mavlink.MAV_MISSION_ACCEPTED
    reboot = mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN
    assert gcs.command(reboot, 1).result == mavlink.MAV_RESULT_ACCEPTED
    assert gcs.recv("HEARTBEAT", 3.0, where=lambda m: m.system_status == BOOTING) is not None
    assert len(sim.mission(1)) == 1
    assert wait_booted(gcs)
    assert sim.wait_until(lambda: sim.state(1).estimate_ready, 5.0)
    assert gcs.command(400, 1).result == mavlink.MAV_RESULT_ACCEPTED
    assert gcs.command(reboot, 1).result == mavlink.MAV_RESULT_FAILED
    assert gcs.command(reboot, 1, 0, 0, 0, 0, 20190226).result == mavlink.MAV_RESULT_ACCEPTED


def test_downloads_are_denied_while_an_upload_is_open_and_the_legacy_request_warns(make_sim):
    """ArduPilot answers MISSION_REQUEST_INT and REQUEST_LIST with DENIED mid-upload (seen on
    SITL) and says once per upload that MISSION_REQUEST is deprecated."""
    _sim, gcs = make_sim()
    gcs.link.mav.mission_count_send(1, 1, 3, 0)
    assert gcs.recv("MISSION_REQUEST").seq == 0
    gcs.link.mav.mission_request_int_send(1, 1, 0, 0)
    assert gcs.recv("MISSION_ACK").type == mavlink.MAV_MISSION_DENIED
    gcs.link.mav.mission_request_list_send(1, 1, 0)
    assert gcs.recv("MISSION_ACK").type == mavlink.MAV_MISSION_DENIED
    assert gcs.upload(waypoints(3)) == mavlink.MAV_MISSION_ACCEPTED
    said: list[str] = []
    gcs.link.mav.set_callback(
        lambda m: said.append(m.text) if m.get_type() == "STATUSTEXT" else None
    )
    assert gcs.download(legacy=True) is not None
    assert gcs.download(legacy=True) is not None
    gcs.collect(0.2)
    assert [t for t in said if "MISSION_REQUEST" in t] == [
        "got MISSION_REQUEST; use MISSION_REQUEST_INT!"
    ]


def test_refusal_faults_set_while_running_break_a_start_late(make_sim):
    """fail_arming refuses every arm; refuse_takeoff lets the arm through and then refuses
    MISSION_START and NAV_TAKEOFF; refuse_commands answers a command kind as told."""
    sim, gcs = make_sim()
    assert sim.wait_until(lambda: sim.state(1).estimate_ready, 5.0)
    assert gcs.upload(waypoints(4)) == mavlink.MAV_MISSION_ACCEPTED
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 4).result == 0
    sim.set_faults(1, Faults(fail_arming=True))
    assert arm_attempt(gcs) == ([mavlink.MAV_RESULT_FAILED], ["Arm: Hardware safety switch"])
    sim.set_faults(1, Faults(refuse_takeoff=True))
    assert arm_attempt(gcs)[0] == [mavlink.MAV_RESULT_ACCEPTED]
    assert gcs.command(mavlink.MAV_CMD_MISSION_START).result == mavlink.MAV_RESULT_FAILED
    takeoff = (mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10)
    assert gcs.command(*takeoff).result == mavlink.MAV_RESULT_FAILED
    assert sim.state(1).armed and sim.state(1).alt == 0.0
    refused = Faults(
        refuse_commands=frozenset({mavlink.MAV_CMD_COMPONENT_ARM_DISARM}),
        refuse_result=mavlink.MAV_RESULT_DENIED,
    )
    sim.set_faults(1, refused)
    assert gcs.command(400, 0).result == mavlink.MAV_RESULT_DENIED  # cannot even disarm
    assert sim.state(1).armed
    sim.set_faults(1, Faults())
    assert gcs.command(*takeoff).result == mavlink.MAV_RESULT_ACCEPTED
