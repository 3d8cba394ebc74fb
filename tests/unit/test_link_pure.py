"""The pure parts under the link: connection strings, modes, typed errors, state updates."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.actions import is_not_ready
from gcs.mavlink.endpoint import Endpoint
from gcs.mavlink.errors import (
    CommandDeniedError,
    CommandFailedError,
    CommandTemporarilyRejectedError,
    CommandUnsupportedError,
    LinkError,
)
from gcs.mavlink.errors import command_error as to_command_error
from gcs.mavlink.mission_item import Autopilot
from gcs.mavlink.modes import UnknownModeError, custom_mode, mode_name, px4_custom_mode
from gcs.mavlink.vehicle_state import LandedState, VehicleState

CODEC = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)


@pytest.mark.parametrize(
    ("url", "expected"),
    [
        ("udpout:127.0.0.1:14560", Endpoint("udpout", "127.0.0.1", 14560)),
        ("udpin:0.0.0.0:14550", Endpoint("udpin", "0.0.0.0", 14550)),
        ("udp:0.0.0.0:14550", Endpoint("udpin", "0.0.0.0", 14550)),
        ("tcp:localhost:5760", Endpoint("tcp", "localhost", 5760)),
        ("UDPOUT:LocalHost.:014560", Endpoint("udpout", "localhost", 14560)),
        ("tcp:[::1]:5760", Endpoint("tcp", "::1", 5760)),
        ("tcp:[0:0::1]:5760", Endpoint("tcp", "::1", 5760)),
    ],
)
def test_connection_strings_as_mavutil_names_them(url: str, expected: Endpoint) -> None:
    assert Endpoint.parse(url) == expected


def test_one_endpoint_has_one_canonical_spelling() -> None:
    spellings = ["udp:127.0.0.1:14550", "udpin:127.0.0.1:014550", " UDPIN:127.0.0.1:14550"]
    assert {str(Endpoint.parse(s)) for s in spellings} == {"udpin:127.0.0.1:14550"}
    assert str(Endpoint.parse("tcp:[::1]:5760")) == "tcp:[::1]:5760"
    assert Endpoint.parse("udpin:0.0.0.0:14550").is_wildcard
    assert Endpoint.parse("tcp:[::1]:5760").is_loopback


@pytest.mark.parametrize("url", ["serial:/dev/ttyUSB0", "udpout:127.0.0.1", "tcp::x", "14550"])
def test_bad_connection_strings_say_what_is_expected(url: str) -> None:
    with pytest.raises(LinkError, match=r"expected udpout:HOST:PORT|IPv6 address in brackets"):
        Endpoint.parse(url)


@pytest.mark.parametrize(
    ("url", "why"),
    [
        ("udpout:127.0.0.1:0", "from 1 to 65535"),
        ("udpout:127.0.0.1:65536", "from 1 to 65535"),
        ("udpout:127.0.0.1:١٤٥٦٠", "a number from 1 to 65535"),
        ("udpout:::1:14560", "IPv6 address in brackets"),
        ("tcp:[::g]:5760", "not an IPv6 address"),
        ("tcp:999.1.1.1:5760", "not a valid IPv4 address"),
        ("tcp:bad_name:5760", "neither an IP address nor a host name"),
    ],
)
def test_what_cannot_work_is_refused_saying_why(url: str, why: str) -> None:
    with pytest.raises(LinkError, match=why):
        Endpoint.parse(url)


def test_px4_modes_pack_main_and_sub_mode() -> None:
    assert custom_mode(Autopilot.PX4, "AUTO") == 4 << 16 | 4 << 24  # AUTO.MISSION
    assert custom_mode(Autopilot.PX4, "LOITER") == 4 << 16 | 3 << 24
    assert custom_mode(Autopilot.PX4, "RTL") == 4 << 16 | 5 << 24
    assert custom_mode(Autopilot.PX4, "LAND") == 4 << 16 | 6 << 24
    assert custom_mode(Autopilot.PX4, "TAKEOFF") == 4 << 16 | 2 << 24
    assert px4_custom_mode(3) == 3 << 16


@pytest.mark.parametrize("name", ["AUTO", "LOITER", "RTL", "LAND", "TAKEOFF", "POSCTL"])
def test_px4_mode_names_round_trip(name: str) -> None:
    assert mode_name(Autopilot.PX4, custom_mode(Autopilot.PX4, name)) == name


def test_arducopter_modes_are_numbers() -> None:
    assert custom_mode(Autopilot.ARDUPILOT, "guided") == 4
    assert custom_mode(Autopilot.ARDUPILOT, "AUTO") == 3
    assert mode_name(Autopilot.ARDUPILOT, 9) == "LAND"
    assert mode_name(Autopilot.ARDUPILOT, 99) == "MODE(99)"


def test_unknown_mode_lists_the_known_ones() -> None:
    with pytest.raises(UnknownModeError, match="GUIDED"):
        custom_mode(Autopilot.ARDUPILOT, "MISSION")


@pytest.mark.parametrize(
    ("result", "cls"),
    [
        (1, CommandTemporarilyRejectedError),
        (2, CommandDeniedError),
        (3, CommandUnsupportedError),
        (4, CommandFailedError),
    ],
)
def test_command_results_map_to_typed_errors(result: int, cls: type) -> None:
    error = to_command_error(1, 400, result, "PreArm: Need Position Estimate")
    assert isinstance(error, cls)
    assert "COMPONENT_ARM_DISARM" in str(error)
    assert "PreArm: Need Position Estimate" in str(error)


def test_prearm_failures_mean_not_ready_yet_but_other_failures_do_not() -> None:
    assert is_not_ready(to_command_error(1, 400, 4, "PreArm: Need Position Estimate"))
    assert is_not_ready(to_command_error(1, 400, 4, "Arm: Need Position Estimate"))
    assert is_not_ready(to_command_error(1, 400, 1))
    assert not is_not_ready(to_command_error(1, 400, 4, "Arm: Mode not armable"))
    assert not is_not_ready(to_command_error(1, 400, 2, "PreArm: whatever"))
    seen_on_sitl = (
        "Arm: Accels inconsistent",
        "Arm: Gyros inconsistent; Arm: EKF attitude is bad",
        "Arm: AHRS: waiting for home",
        "Arm: System not initialised",
    )
    assert all(is_not_ready(to_command_error(1, 400, 4, text)) for text in seen_on_sitl)
    assert not is_not_ready(to_command_error(1, 400, 4, "Arm: Hardware safety switch"))


def _state(autopilot: int = 3) -> VehicleState:
    return VehicleState(sysid=1, autopilot=autopilot)


def test_state_follows_heartbeat_position_and_mission() -> None:
    state = _state()
    state.apply(CODEC.heartbeat_encode(2, 3, 0xD9, 4, 4), now=1.0)
    state.apply(
        CODEC.global_position_int_encode(
            5000, -353632620, 1491652370, 600000, 20000, 300, 400, 0, 9000
        ),
        now=1.1,
    )
    state.apply(CODEC.mission_current_encode(3, 7, 3), now=1.2)
    state.apply(CODEC.mission_item_reached_encode(2), now=1.3)
    state.apply(CODEC.mission_item_reached_encode(2), now=1.4)  # PX4 repeats
    state.apply(CODEC.extended_sys_state_encode(0, LandedState.IN_AIR), now=1.5)
    assert (state.armed, state.mode, state.airborne) == (True, "GUIDED", True)
    assert state.position is not None and state.position.relative_alt_m == pytest.approx(20.0)
    assert state.groundspeed_m_s == pytest.approx(5.0)
    assert state.heading_deg == pytest.approx(90.0)
    assert (state.mission_seq, state.mission_total, state.mission_state) == (3, 7, 3)
    assert state.reached == {2}
    assert state.time_boot_ms == 5000 and state.last_heard == 1.5


def test_statustext_is_kept_for_error_messages() -> None:
    state = _state()
    state.apply(CODEC.statustext_encode(3, b"PreArm: Need Position Estimate"), now=2.0)
    assert state.recent_text(since=1.9) == "PreArm: Need Position Estimate"
    assert state.recent_text(since=2.1) == ""
