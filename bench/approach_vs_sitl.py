"""How a vehicle stopped by the passing order approaches again, on the mock and on real
ArduCopter SITL: the commands the ground station sends to one that must wait
(`gcs.fleet.gatekeeper`), one after the other on a straight leg.

The vehicle takes off to 10 m and flies a 200 m leg at `--cruise` (5 m/s). Once at
`--pause-at` (the cruise; 20 m on at least) it is paused (DO_PAUSE_CONTINUE 0); once slower than
`--stopped` (0.05 m/s) it is given an approach speed (`--approach`, DO_CHANGE_SPEED
1 m/s) and sent on, the `--variant`'s way; 6 s later its approach is raised to 3 m/s,
and 6 s after that it gets its cruise back. Printed per vehicle: the speed 1 s, 2 s, 4 s
and 6 s after each command, the highest in the 4 s after it, and how far it went in each
phase, from its own GLOBAL_POSITION_INT (its own clock). Run where a SITL binary is built:

    unshare -n bash -c 'ip link set lo up; .venv/bin/python bench/approach_vs_sitl.py \
        --sitl /path/to/arducopter'
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

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
LEG_M, ALT_M = 200.0, 10.0
PHASE_S = 6.0
GAP_S = 0.05
"""Between two commands of a variant that sends several (wall seconds; SITL runs at
speed-up 2): about what the ground station's wait for an acknowledgement takes."""
LEG_ITEM = 3
AUTO, BRAKE = 3, 17  # ArduCopter's custom modes
VARIANTS = {
    "at-resume": "DO_CHANGE_SPEED once stopped, then the resume",
    "resume-first": "the resume, then DO_CHANGE_SPEED",
    "before": "DO_CHANGE_SPEED just before the pause",
    "after-pause": "DO_CHANGE_SPEED just after the pause",
    "restart": "once stopped, MISSION_SET_CURRENT (the leg afresh from rest), then at once "
    "DO_CHANGE_SPEED",
    "restart-then-speed": "MISSION_SET_CURRENT, then DO_CHANGE_SPEED and the resume a moment "
    "later each (the ground station until 2026-12-06)",
    "speed-then-restart": "DO_CHANGE_SPEED, then MISSION_SET_CURRENT and the resume a moment "
    "later each (the ground station's order now)",
    "restart-only": "MISSION_SET_CURRENT alone",
    "brake-auto-then-speed": "stopped with BRAKE instead; AUTO, then DO_CHANGE_SPEED a moment "
    "later",
    "brake-auto-with-speed": "stopped with BRAKE instead; AUTO and DO_CHANGE_SPEED at once",
}


def fly(
    connection: str, variant: str, cruise: float, pause_at: float, stopped: float, approach: float
) -> tuple[np.ndarray, list[tuple[str, float]]]:
    """The track (t, metres north, speed) and when each command was sent (own clock)."""
    with mission_started(connection, leg_north(cruise, LEG_M, ALT_M), {33: 5e4}) as flying:
        link, target = flying
        phases = [(f"sent on at {approach:g} m/s", approach), ("raised to 3 m/s", 3.0)]
        phases.append(("cruise again", cruise))
        return _approach(link, target, variant, (pause_at, stopped, cruise), phases)


def _approach(
    link: mavutil.mavfile,
    target: int,
    variant: str,
    at: tuple[float, float, float],
    phases: list[tuple[str, float]],
) -> tuple[np.ndarray, list[tuple[str, float]]]:
    def send(command: int, *params: float) -> None:
        padded = [*params, *[0.0] * (7 - len(params))]
        link.mav.command_long_send(target, 1, command, 0, *padded)

    speed_m_s = phases[0][1]
    moves: dict[str, Callable[[], None]] = {
        "speed": lambda: send(MAV.MAV_CMD_DO_CHANGE_SPEED, 1, speed_m_s, -1),
        "resume": lambda: send(MAV.MAV_CMD_DO_PAUSE_CONTINUE, 1),
        "restart": lambda: link.mav.mission_set_current_send(target, 1, LEG_ITEM),
        "auto": lambda: send(MAV.MAV_CMD_DO_SET_MODE, 1, AUTO),
    }
    sent_on = {
        "at-resume": ["speed", "resume"],
        "resume-first": ["resume", "speed"],
        "before": ["resume"],
        "after-pause": ["resume"],
        "restart": ["restart", "speed"],
        "restart-then-speed": ["restart", "wait", "speed", "wait", "resume"],
        "speed-then-restart": ["speed", "wait", "restart", "wait", "resume"],
        "restart-only": ["restart"],
        "brake-auto-then-speed": ["auto", "wait", "speed"],
        "brake-auto-with-speed": ["auto", "speed"],
    }[variant]
    pause_at, stopped, cruise = at
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
        if step == "cruise" and speed > pause_at - 0.2 and (north > 20 or pause_at < cruise):
            if variant == "before":
                moves["speed"]()
            if variant.startswith("brake"):
                send(MAV.MAV_CMD_DO_SET_MODE, 1, BRAKE)
            else:
                send(MAV.MAV_CMD_DO_PAUSE_CONTINUE, 0)
            if variant == "after-pause":
                moves["speed"]()
            sent.append(("braked" if variant.startswith("brake") else "paused", now))
            step = "pausing"
        elif step == "pausing" and speed < stopped:
            for move in sent_on:
                time.sleep(GAP_S) if move == "wait" else moves[move]()
            sent.append((phases[0][0], now))
            step, step_at = "1", now
        elif step in ("1", "2") and now - step_at >= PHASE_S:
            name, phase_speed = phases[int(step)]
            send(MAV.MAV_CMD_DO_CHANGE_SPEED, 1, phase_speed, -1)
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
        after = (track[:, 0] >= at) & (track[:, 0] <= at + 4.0)
        top = float(track[after, 2].max()) if after.any() else math.nan
        rows[name] = " / ".join(f"{v:.2f}" for v in speeds) + f" m/s (top {top:.2f}); {gone:.1f} m"
    return rows


def main() -> int:
    parser = sitl_parser(__doc__)
    parser.add_argument("--variant", choices=VARIANTS, default="at-resume")
    parser.add_argument("--cruise", type=float, default=5.0, help="the mission's speed, m/s")
    parser.add_argument("--pause-at", type=float, default=None, help="m/s (default: cruise)")
    parser.add_argument("--stopped", type=float, default=0.05, help="sent on below this, m/s")
    parser.add_argument("--approach", type=float, default=1.0, help="m/s")
    parser.add_argument("--only-sitl", action="store_true", help="leave the mock out")
    args = parser.parse_args()
    pause_at = args.cruise if args.pause_at is None else args.pause_at
    flown = (args.variant, args.cruise, pause_at, args.stopped, args.approach)
    with sitl_and_mock(args.sitl, args.speedup):
        rows = {"ArduCopter SITL": describe(*fly(SITL_URL, *flown))}
        if not args.only_sitl:
            rows["sitl_mock"] = describe(*fly(MOCK_URL, *flown))
    names = list(rows)
    print(f"variant {args.variant}: {VARIANTS[args.variant]}")
    print(f"cruise {args.cruise:g} m/s, paused at {pause_at:g} m/s, sent on below "
          f"{args.stopped:g} m/s")  # fmt: skip
    print("speed 1 / 2 / 4 / 6 s after the command (top: the highest in 4 s); distance until")
    print("the next command")
    print("| command | " + " | ".join(names) + " |")
    print("| --- |" + " --- |" * len(names))
    for phase in rows[names[0]]:
        print(f"| {phase} | " + " | ".join(rows[n].get(phase, "-") for n in names) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
