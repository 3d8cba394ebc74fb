"""How a vehicle stopped by the passing order approaches again, on the mock and on real
ArduCopter SITL: the commands the ground station sends to one that must wait
(`gcs.fleet.gatekeeper`), one after the other on a straight leg.

The vehicle takes off to 10 m and flies a 200 m leg at 5 m/s. Once at cruise it is
paused (DO_PAUSE_CONTINUE 0); stopped, it is given an approach speed (DO_CHANGE_SPEED
1 m/s) and resumed (DO_PAUSE_CONTINUE 1; `--variant` sends the speed at other moments);
6 s later its approach is raised to 3 m/s,
and 6 s after that it gets its cruise back (5 m/s). Printed per vehicle: the speed
1 s, 2 s, 4 s and 6 s after each command, and how far it went in each phase, from its
own GLOBAL_POSITION_INT (its own clock). Run where a SITL binary is built:

    unshare -n bash -c 'ip link set lo up; .venv/bin/python bench/approach_vs_sitl.py \
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
CRUISE_M_S, LEG_M, ALT_M = 5.0, 200.0, 10.0
PHASES = (("resumed at 1 m/s", 1.0), ("raised to 3 m/s", 3.0), ("cruise again", 5.0))
PHASE_S = 6.0
VARIANTS = {
    "at-resume": "DO_CHANGE_SPEED once stopped, then the resume (what the ground station does)",
    "resume-first": "the resume, then DO_CHANGE_SPEED",
    "before": "DO_CHANGE_SPEED just before the pause",
    "after-pause": "DO_CHANGE_SPEED just after the pause",
    "restart": "once stopped, MISSION_SET_CURRENT (the leg afresh from rest), then DO_CHANGE_SPEED",
}
LEG_ITEM = 3


def fly(connection: str, variant: str) -> tuple[np.ndarray, list[tuple[str, float]]]:
    """The track (t, metres north, speed) and when each command was sent (own clock)."""
    with mission_started(connection, leg_north(CRUISE_M_S, LEG_M, ALT_M), {33: 5e4}) as flying:
        return _approach(*flying, variant)


def _approach(
    link: mavutil.mavfile, target: int, variant: str
) -> tuple[np.ndarray, list[tuple[str, float]]]:
    def send(command: int, *params: float) -> None:
        padded = [*params, *[0.0] * (7 - len(params))]
        link.mav.command_long_send(target, 1, command, 0, *padded)

    track: list[tuple[float, float, float]] = []
    sent: list[tuple[str, float]] = []
    step, step_at = "cruise", 0.0
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and step != "done":
        msg = link.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=1)
        if msg is None or msg.get_srcSystem() != target:
            continue
        now = msg.time_boot_ms / 1e3
        _, north, _ = pymap3d.geodetic2enu(msg.lat / 1e7, msg.lon / 1e7, HOME[2], *HOME)
        speed = math.hypot(msg.vx, msg.vy) / 100
        track.append((now, north, speed))
        if step == "cruise" and speed > CRUISE_M_S - 0.2 and north > 20:
            if variant == "before":
                send(MAV.MAV_CMD_DO_CHANGE_SPEED, 1, PHASES[0][1], -1)
            send(MAV.MAV_CMD_DO_PAUSE_CONTINUE, 0)
            if variant == "after-pause":
                send(MAV.MAV_CMD_DO_CHANGE_SPEED, 1, PHASES[0][1], -1)
            sent.append(("paused", now))
            step = "pausing"
        elif step == "pausing" and speed < 0.05:
            if variant == "at-resume":
                send(MAV.MAV_CMD_DO_CHANGE_SPEED, 1, PHASES[0][1], -1)
            if variant == "restart":
                link.mav.mission_set_current_send(target, 1, LEG_ITEM)
                send(MAV.MAV_CMD_DO_CHANGE_SPEED, 1, PHASES[0][1], -1)
            else:
                send(MAV.MAV_CMD_DO_PAUSE_CONTINUE, 1)
            if variant == "resume-first":
                send(MAV.MAV_CMD_DO_CHANGE_SPEED, 1, PHASES[0][1], -1)
            sent.append((PHASES[0][0], now))
            step, step_at = "1", now
        elif step in ("1", "2") and now - step_at >= PHASE_S:
            name, speed_m_s = PHASES[int(step)]
            send(MAV.MAV_CMD_DO_CHANGE_SPEED, 1, speed_m_s, -1)
            sent.append((name, now))
            step, step_at = str(int(step) + 1), now
        elif step == "3" and now - step_at >= PHASE_S:
            step = "done"
    send(MAV.MAV_CMD_DO_SET_MODE, 1, 9)  # LAND
    return np.array(track), sent


def describe(track: np.ndarray, sent: list[tuple[str, float]]) -> dict[str, str]:
    rows = {}
    times = [t for _, t in sent] + [track[-1, 0]]
    for k, (name, at) in enumerate(sent):
        speeds = [np.interp(at + d, track[:, 0], track[:, 2]) for d in (1.0, 2.0, 4.0, 6.0)]
        gone = np.interp(times[k + 1], track[:, 0], track[:, 1]) - np.interp(
            at, track[:, 0], track[:, 1]
        )
        rows[name] = " / ".join(f"{v:.2f}" for v in speeds) + f" m/s; {gone:.1f} m"
    return rows


def main() -> int:
    parser = sitl_parser(__doc__)
    parser.add_argument("--variant", choices=VARIANTS, default="at-resume")
    parser.add_argument("--only-sitl", action="store_true", help="leave the mock out")
    args = parser.parse_args()
    with sitl_and_mock(args.sitl, args.speedup):
        rows = {"ArduCopter SITL": describe(*fly(SITL_URL, args.variant))}
        if not args.only_sitl:
            rows["sitl_mock"] = describe(*fly(MOCK_URL, args.variant))
    names = list(rows)
    print(f"variant {args.variant}: {VARIANTS[args.variant]}")
    print("speed 1 / 2 / 4 / 6 s after the command; distance until the next command")
    print("| command | " + " | ".join(names) + " |")
    print("| --- |" + " --- |" * len(names))
    for phase in rows[names[0]]:
        print(f"| {phase} | " + " | ".join(rows[n].get(phase, "-") for n in names) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
