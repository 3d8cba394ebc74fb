"""MAVLink 2 signing with plain pymavlink against a vehicle that has a key: what the vehicle
sends is signed with it, and it ignores (and counts) what is unsigned or signed with another
key, commands and the mission protocol alike, while a correctly signed client works."""

from __future__ import annotations

import hashlib
import os
import time
from collections.abc import Iterator
from typing import Any

import pytest

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil

from sitl_mock import Simulator, VehicleConfig

mavutil.set_dialect("ardupilotmega")
mavlink = mavutil.mavlink

KEY = hashlib.sha256(b"vehicle one").digest()
OTHER_KEY = hashlib.sha256(b"someone else").digest()
ANSWER_S = 1.0


@pytest.fixture(params=["udp", "tcp"])
def signing_vehicle(request: pytest.FixtureRequest) -> Iterator[Simulator]:
    config = VehicleConfig(sysid=1, transport=request.param, signing_key=KEY, estimate_delay_s=3.0)
    sim = Simulator([config], speedup=20.0)
    with sim.running():
        yield sim


def client(sim: Simulator, key: bytes | None) -> mavutil.mavfile:
    link = mavutil.mavlink_connection(
        sim.connection_string(1), source_system=255, source_component=190
    )
    if key is not None:
        link.setup_signing(key, sign_outgoing=True)
    link.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    return link


def ack_for(link: mavutil.mavfile, command: int) -> Any:
    deadline = time.monotonic() + ANSWER_S
    while (remaining := deadline - time.monotonic()) > 0:
        msg = link.recv_match(type="COMMAND_ACK", blocking=True, timeout=remaining)
        if msg is not None and msg.command == command:
            return msg
    return None


def hears_the_vehicle(link: mavutil.mavfile, timeout: float = 3.0) -> bool:
    """A HEARTBEAT arrives; a client with another key sees it only as a bad signature."""
    deadline = time.monotonic() + timeout
    while (remaining := deadline - time.monotonic()) > 0:
        if link.recv_match(type="HEARTBEAT", blocking=True, timeout=remaining) is not None:
            return True
        if link.mav.signing.badsig_count > 0:
            return True
    return False


def request_version(link: mavutil.mavfile) -> None:
    link.mav.command_long_send(
        1,
        1,
        mavlink.MAV_CMD_REQUEST_MESSAGE,
        0,
        mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
        0,
        0,
        0,
        0,
        0,
        0,
    )


def test_the_vehicle_signs_what_it_sends(signing_vehicle: Simulator) -> None:
    link = client(signing_vehicle, KEY)
    try:
        heartbeat = link.recv_match(type="HEARTBEAT", blocking=True, timeout=3.0)
        assert heartbeat is not None and heartbeat._signed
        assert link.mav.signing.goodsig_count >= 1 and link.mav.signing.badsig_count == 0
    finally:
        link.close()


@pytest.mark.parametrize("key", [None, OTHER_KEY], ids=["unsigned", "wrong key"])
def test_commands_and_uploads_without_the_key_are_ignored_and_counted(
    signing_vehicle: Simulator, key: bytes | None
) -> None:
    sim = signing_vehicle
    link = client(sim, key)
    try:
        assert hears_the_vehicle(link)
        request_version(link)
        assert ack_for(link, mavlink.MAV_CMD_REQUEST_MESSAGE) is None
        link.mav.command_long_send(1, 1, 400, 0, 1, 21196, 0, 0, 0, 0, 0)
        assert ack_for(link, 400) is None
        link.mav.mission_count_send(1, 1, 3, 0)
        assert (
            link.recv_match(
                type=["MISSION_REQUEST", "MISSION_ACK"], blocking=True, timeout=ANSWER_S
            )
            is None
        )
        assert not sim.state(1).armed and not sim.vehicle(1).store.uploading
        assert sim.rejected_packets(1) >= 4  # heartbeat, two commands, the count
    finally:
        link.close()


def test_a_client_with_the_key_is_answered(signing_vehicle: Simulator) -> None:
    sim = signing_vehicle
    link = client(sim, KEY)
    try:
        booted = "HEARTBEAT.system_status!=1"
        assert (
            link.recv_match(type="HEARTBEAT", blocking=True, timeout=3.0, condition=booted)
            is not None
        )
        request_version(link)
        ack = ack_for(link, mavlink.MAV_CMD_REQUEST_MESSAGE)
        assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED
        link.mav.mission_count_send(1, 1, 0, 0)
        assert link.recv_match(type="MISSION_ACK", blocking=True, timeout=ANSWER_S).type == (
            mavlink.MAV_MISSION_ACCEPTED
        )
        assert sim.rejected_packets(1) == 0
    finally:
        link.close()
