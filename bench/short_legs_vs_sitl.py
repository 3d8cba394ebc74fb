"""Short legs at cruise speed: ArduCopter SITL against the mock, waypoint by waypoint.

A plan on a grid of 10 m cells flies legs of 10 to 30 m with turns between them; at
10 m/s ArduCopter cannot reach its cruise speed on such legs, and how fast it gets
through them decides how long a flight takes. One mission per vehicle: take off to 10 m,
DO_CHANGE_SPEED to `--speed`, then waypoints without holds along `LEGS` (length, turn
before the leg), land at the last. Prints, per waypoint, when each vehicle reported it
reached (MISSION_ITEM_REACHED, the vehicle's own time from the first leg's start) and
the highest ground speed on the leg into it, beside the ground station's timing of the
same path (`gcs.mission.flight_timing`, WP_RADIUS_M 2 m as the vehicles use it). Run
inside a loopback-only namespace:

    unshare -n bash -c 'ip link set lo up; .venv/bin/python bench/short_legs_vs_sitl.py \\
        --sitl /work/ardupilot/build/sitl/bin/arducopter'
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d
from mock_vs_sitl import (  # bench/ is on the path of a script run from it
    HOME,
    MAV,
    MOCK_URL,
    REL,
    SITL_URL,
    Flight,
    _record,
    mission_started,
    sitl_and_mock,
    sitl_parser,
)

from gcs.mission.flight_timing import fly
from gcs.mission.motion import CopterLimits
from gcs.mission.passing_order import PlannedPath

ALT_M = 10.0
LEGS = [(30.0, 0.0), (22.0, 20.0), (22.0, 45.0), (14.0, 45.0), (22.0, 90.0), (10.0, 30.0),
        (22.0, -45.0), (30.0, 30.0), (14.0, -90.0), (22.0, 20.0)]  # fmt: skip
"""(metres, degrees turned left before the leg): gentle, diagonal and square corners,
legs of one to three cells (a mission has no waypoint where its path runs straight on)."""


def waypoints() -> list[tuple[float, float]]:
    points, heading, here = [], 0.0, np.zeros(2)
    for length, turn in LEGS:
        heading += math.radians(turn)
        here = here + length * np.array([math.cos(heading), math.sin(heading)])
        points.append((float(here[0]), float(here[1])))
    return points


def mission(speed: float) -> list:
    def place(east: float, north: float) -> tuple[int, int]:
        lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, *HOME)
        return round(lat * 1e7), round(lon * 1e7)

    nan, home = math.nan, place(0.0, 0.0)
    points = waypoints()
    return [
        (MAV.MAV_FRAME_GLOBAL, MAV.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, 0, *home, HOME[2]),
        (REL, MAV.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, *home, ALT_M),
        (MAV.MAV_FRAME_MISSION, MAV.MAV_CMD_DO_CHANGE_SPEED, 1, speed, -1, 0, 0, 0, 0),
        (REL, MAV.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, nan, *home, ALT_M),  # start at rest here
        *[(REL, MAV.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, nan, *place(*p), ALT_M) for p in points[:-1]],
        (REL, MAV.MAV_CMD_NAV_LAND, 0, 0, 0, nan, *place(*points[-1]), 0.0),
    ]


FIRST_SEQ = 4  # the first leg's waypoint


def rows(flight: Flight) -> list[tuple[float, float]]:
    """(seconds from the first leg's start to reaching, top speed on the leg) per leg."""
    start = next(t for t, seq in flight.current if seq == FIRST_SEQ)
    reached = {seq: t - start for t, seq in flight.reached}
    current = dict((seq, t) for t, seq in flight.current)
    out, t0 = [], start
    for k in range(len(LEGS)):
        seq = FIRST_SEQ + k
        end = start + reached[seq] if seq in reached else current.get(seq + 1, math.nan)
        track = flight.track
        on_leg = (track[:, 0] >= t0) & (track[:, 0] <= end)
        out.append((end - start, float(track[on_leg, 4].max()) if on_leg.any() else math.nan))
        t0 = end
    return out


def timing(speed: float) -> list[float]:
    """When the ground station's timing has the vehicle at each waypoint, from the start."""
    points = np.array([(0.0, 0.0), *waypoints()])
    clock = np.arange(len(points), dtype=float)  # the plan's own clock plays no part here
    path = PlannedPath("uav", points, clock, clock, 3.0)
    limits = CopterLimits(speed_m_s=speed, radius_m=2.0)
    timed = fly({"uav": path}, {"uav": np.full(len(points) - 1, speed)}, {"uav": limits})
    return [timed["uav"].time_at(float(s)) for s in path.s[1:]]


def main() -> int:
    parser = sitl_parser(__doc__)
    parser.add_argument("--speed", type=float, default=10.0)
    args = parser.parse_args()
    intervals = {33: 4e4, 42: 1e5}
    flights = {}
    with sitl_and_mock(args.sitl, args.speedup):
        for name, url in (("ArduCopter SITL", SITL_URL), ("sitl_mock", MOCK_URL)):
            with mission_started(url, mission(args.speed), intervals) as (link, target):
                flights[name] = rows(_record(link, target))
    names, timed = list(flights), timing(args.speed)
    print(f"Legs at {args.speed:g} m/s; reached s (top speed on the leg, m/s)")
    print("| leg | length m | turn | " + " | ".join(names) + " | timing |")
    print("| --- | ---: | ---: |" + " ---: |" * (len(names) + 1))
    for k, (length, turn) in enumerate(LEGS[:-1]):  # the last leg ends in LAND
        cells = " | ".join(f"{flights[n][k][0]:.2f} ({flights[n][k][1]:.2f})" for n in names)
        print(f"| {k + 1} | {length:g} | {turn:g}° | {cells} | {timed[k]:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
