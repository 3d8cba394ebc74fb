"""How far a mission paused while it speeds up goes on, on the mock and on real ArduCopter
SITL: what the passing order's stop (`gcs.fleet.gatekeeper`) must allow for when it pauses
a vehicle coming out of a corner or off a standstill.

The vehicle takes off to 10 m and flies a 300 m leg north on a 10 m/s track. Each time
its speed first reaches one of `PAUSE_AT_M_S` (still speeding up), it is paused
(DO_PAUSE_CONTINUE 0); once it stands, MISSION_SET_CURRENT sends it to the same leg
again, flown afresh from rest. Printed per vehicle and pause: the speed and acceleration
reported with the pause, metres to a standstill (below 0.1 m/s) and seconds, from its own
GLOBAL_POSITION_INT (its own clock). Run where a SITL binary is built:

    unshare -n bash -c 'ip link set lo up; .venv/bin/python bench/pause_vs_sitl.py \
        --sitl /path/to/arducopter'
"""

from __future__ import annotations

import math
import time

import numpy as np
import pymap3d
from mock_vs_sitl import (
    HOME,
    MOCK_URL,
    SITL_URL,
    leg_north,
    mission_started,
    sitl_and_mock,
    sitl_parser,
)
from pymavlink import mavutil

MAV = mavutil.mavlink
TRACK_M_S, LEG_M, ALT_M = 10.0, 300.0, 10.0
PAUSE_AT_M_S = (2.0, 4.0, 6.0)
STILL_M_S = 0.1
LEG_ITEM = 3


def fly(connection: str) -> list[tuple[float, float, float, float]]:
    """(speed, acceleration, metres, seconds) of each pause."""
    with mission_started(connection, leg_north(TRACK_M_S, LEG_M, ALT_M), {33: 5e4}) as flying:
        return _pauses(*flying)


def _pauses(link: mavutil.mavfile, target: int) -> list[tuple[float, float, float, float]]:
    def send(command: int, *params: float) -> None:
        padded = [*params, *[0.0] * (7 - len(params))]
        link.mav.command_long_send(target, 1, command, 0, *padded)

    found: list[tuple[float, float, float, float]] = []
    wanted = list(PAUSE_AT_M_S)
    last: tuple[float, float] | None = None  # (t, speed) of the report before
    paused: tuple[float, float, float, float] | None = None  # t, north, speed, accel
    leg_started = False
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and wanted:
        msg = link.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=1)
        if msg is None or msg.get_srcSystem() != target:
            continue
        now = msg.time_boot_ms / 1e3
        _, north, _ = pymap3d.geodetic2enu(msg.lat / 1e7, msg.lon / 1e7, HOME[2], *HOME)
        speed = math.hypot(msg.vx, msg.vy) / 100
        accel = 0.0 if last is None or now <= last[0] else (speed - last[1]) / (now - last[0])
        last = (now, speed)
        leg_started = leg_started or speed > 0.5
        if paused is None and leg_started and speed >= wanted[0]:
            send(MAV.MAV_CMD_DO_PAUSE_CONTINUE, 0)
            paused = (now, north, speed, accel)
        elif paused is not None and speed < STILL_M_S:
            t0, north0, speed0, accel0 = paused
            found.append((speed0, accel0, north - north0, now - t0))
            wanted.pop(0)
            paused, leg_started = None, False
            link.mav.mission_set_current_send(target, 1, LEG_ITEM)
    send(MAV.MAV_CMD_DO_SET_MODE, 1, 9)  # LAND
    return found


def main() -> int:
    args = sitl_parser(__doc__).parse_args()
    with sitl_and_mock(args.sitl, args.speedup):
        rows = {"ArduCopter SITL": fly(SITL_URL), "sitl_mock": fly(MOCK_URL)}
    print(f"paused while speeding up on a {TRACK_M_S:g} m/s track:")
    print("speed, acceleration at the pause; metres and seconds to a standstill")
    print("| pause | " + " | ".join(rows) + " |")
    print("| --- |" + " --- |" * len(rows))
    for k, at in enumerate(PAUSE_AT_M_S):
        cells = [
            " ".join(f"{v:.2f}" for v in np.round(found[k], 2)) if k < len(found) else "-"
            for found in rows.values()
        ]
        print(f"| at {at:g} m/s | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
