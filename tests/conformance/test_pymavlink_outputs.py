"""Vehicles that announce themselves: with `outputs` (`--out udp:HOST:PORT`) every vehicle
sends to a listening ground station through one shared socket, as MAVProxy's outputs do,
so a plain pymavlink `udpin:` listener on that one port sees each by its system id and can
talk to each (what it sends back reaches all; each keeps what is addressed to it)."""

from __future__ import annotations

import os
import socket
import time
from typing import Any

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil

from sitl_mock import Simulator, VehicleConfig

mavutil.set_dialect("ardupilotmega")
mavlink = mavutil.mavlink

SYSIDS = (1, 2, 3)
SEEN_S = 5.0


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def heard(link: mavutil.mavfile, timeout: float) -> dict[int, Any]:
    """The first HEARTBEAT of each system id heard within `timeout` wall seconds."""
    found: dict[int, object] = {}
    deadline = time.monotonic() + timeout
    while len(found) < len(SYSIDS) and (remaining := deadline - time.monotonic()) > 0:
        msg = link.recv_match(type="HEARTBEAT", blocking=True, timeout=remaining)
        if msg is not None:
            found.setdefault(msg.get_srcSystem(), msg)
    return found


def acks_from(link: mavutil.mavfile, seconds: float) -> list[int]:
    systems = []
    deadline = time.monotonic() + seconds
    while (remaining := deadline - time.monotonic()) > 0:
        msg = link.recv_match(type="COMMAND_ACK", blocking=True, timeout=remaining)
        if msg is not None:
            systems.append(msg.get_srcSystem())
    return systems


def test_a_udpin_listener_sees_and_addresses_several_vehicles_on_one_port() -> None:
    port = free_udp_port()
    listener = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255)
    configs = [
        VehicleConfig(sysid=k, transport="tcp", outputs=(f"udp:127.0.0.1:{port}",)) for k in SYSIDS
    ]
    sim = Simulator(configs, speedup=20.0)
    try:
        with sim.running():
            found = heard(listener, SEEN_S)
            assert sorted(found) == list(SYSIDS)
            assert all(hb.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA for hb in found.values())
            listener.mav.command_long_send(
                2,
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
            assert acks_from(listener, 1.0) == [2]
            listener.mav.param_set_send(3, 1, b"WP_SPD", 5.0, mavlink.MAV_PARAM_TYPE_REAL32)
            reply = listener.recv_match(type="PARAM_VALUE", blocking=True, timeout=SEEN_S)
            assert reply is not None and reply.get_srcSystem() == 3
            assert sim.vehicle(3).params.get("WP_SPD") == 5.0
            assert sim.vehicle(1).params.get("WP_SPD") == 10.0
    finally:
        listener.close()
