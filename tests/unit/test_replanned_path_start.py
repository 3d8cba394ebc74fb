"""A replanned vehicle's path begins where the vehicle is: stopped for the replan, it
comes to rest on its way to where its new path begins (only foreseen), and its mission
flies it there first (fuzzed flight 7648: 12 m short of it, out of the order's sight,
another was let by 5.65 m from it)."""

from __future__ import annotations

import numpy as np
import pytest

from gcs.mavlink.mission_item import Autopilot, Command
from gcs.mission.build import build_mission
from gcs.mission.flight_plan import begun_where_it_is
from gcs.mission.geodesy import GridFrame
from gcs.mission.passing_order import PlannedPath

FRAME = GridFrame(-35.3632, 149.1652, 584.0, 10.0)


def _path(corners: list[list[float]], speed: float, t0: float = 0.0) -> PlannedPath:
    xy = np.asarray(corners, dtype=float)
    t = t0 + np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))]) / speed
    return PlannedPath("a", xy, t, t, 3.0)


def test_the_way_to_the_new_start_along_the_old_path_comes_first() -> None:
    old = _path([[0, 0], [30, 0], [30, 40]], 5.0)
    new = _path([[30, 10], [80, 10]], 5.0, t0=10.0)

    begun = begun_where_it_is(old, 20.0, new)

    assert begun.xy.tolist() == [[20, 0], [30, 0], [30, 10], [80, 10]]  # round the corner
    assert begun.arrive.tolist() == pytest.approx([6.0, 8.0, 10.0, 20.0])  # flown before it
    assert begun.leave.tolist() == pytest.approx(begun.arrive.tolist())


def test_a_vehicle_already_there_keeps_its_new_path() -> None:
    old = _path([[0, 0], [100, 0]], 5.0)
    new = _path([[20, 0], [20, 50]], 5.0, t0=4.0)
    assert begun_where_it_is(old, 20.0, new) is new


def test_a_new_start_off_the_old_path_is_flown_to_straight() -> None:
    """The vehicle is past where its new path begins (it was held, or went on): it
    flies back to it."""
    old = _path([[0, 0], [100, 0]], 5.0)
    new = _path([[20, 5], [20, 50]], 5.0, t0=4.0)

    begun = begun_where_it_is(old, 30.0, new)

    assert begun.xy[:2].tolist() == [[30, 0], [20, 5]]
    assert begun.arrive[1] - begun.arrive[0] == pytest.approx(np.hypot(10, 5) / 5.0)


def test_an_airborne_vehicles_mission_flies_to_its_new_paths_start_first() -> None:
    """A NAV_TAKEOFF in the air is done at once: without a waypoint at the first place,
    the vehicle went straight from wherever it stopped for the next one."""
    points = [[0, 0, 0], [3, 3, 0], [5, 3, 2]]  # [t, x, y]: east, then north
    grounded = build_mission(points, 1.0, FRAME, Autopilot.ARDUPILOT, holds=False)
    airborne = build_mission(points, 1.0, FRAME, Autopilot.ARDUPILOT, holds=False, airborne=True)

    def waypoints(items: tuple) -> list[tuple[int, int]]:
        return [(i.x, i.y) for i in items if i.command == Command.NAV_WAYPOINT][1:]  # no home

    takeoff = next(i for i in airborne.items if i.command == Command.NAV_TAKEOFF)
    assert waypoints(airborne.items) == [(takeoff.x, takeoff.y), *waypoints(grounded.items)]
