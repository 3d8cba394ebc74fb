"""Signed streams that stay acceptable over time, and refusals that say why (issue 28).

pymavlink checks a new stream's first timestamp against its own clock and refuses one
more than a minute behind ("bad new stream"). A sender that only adds a tick per packet
(pymavlink's own signing, and the mock's before) falls behind the clock as it runs:
a ground station that started listening a minute later heard nothing and said only
"no HEARTBEAT". The mock now keeps its clock current as ArduPilot does, and the ground
station says why each refused packet was refused.
"""

from __future__ import annotations

import time

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.connection import SIGNING_EPOCH
from gcs.mavlink.signature_check import why_refused
from sitl_mock.codec import Encoder

KEY = bytes(range(32))
OTHER = bytes(32)


def receiver(key: bytes, wall: float) -> mavlink2.MAVLink:
    """A receiver that starts listening at `wall`, as pymavlink (and the service) do."""
    mav = mavlink2.MAVLink(None)
    mav.robust_parsing = True
    mav.signing.secret_key = key
    mav.signing.timestamp = int((wall - SIGNING_EPOCH) * 100_000)
    return mav


def test_a_vehicle_that_ran_for_ten_minutes_is_heard_by_a_new_listener() -> None:
    now = [time.time()]
    encoder = Encoder(1, key=KEY, wall=lambda: now[0])
    for _ in range(6000):  # ten minutes of 10 Hz telemetry
        encoder.encode(beat())
        now[0] += 0.1
    late = receiver(KEY, now[0])
    [msg] = late.parse_buffer(encoder.encode(beat()))
    assert msg.get_type() == "HEARTBEAT"


def test_each_refusal_is_named() -> None:
    wall = time.time()
    signed = Encoder(1, key=KEY, wall=lambda: wall).encode(beat())
    unsigned = Encoder(1).encode(beat())
    old = Encoder(1, key=KEY, wall=lambda: wall - 120).encode(beat())
    ours = int((wall - SIGNING_EPOCH) * 100_000)
    assert why_refused(unsigned, KEY, ours).startswith("unsigned")
    assert why_refused(signed, OTHER, ours) == "signed with another key"
    assert "120 s behind" in why_refused(old, KEY, ours)
    [bad] = receiver(KEY, wall).parse_buffer(old)  # and pymavlink does refuse it
    assert bad.get_type() == "BAD_DATA"


def beat() -> mavlink2.MAVLink_message:
    return mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3, 3
    )
