"""Where a mission's items lie along the path they fly (`gcs.mission.flight_plan`)."""

from __future__ import annotations

import numpy as np

from gcs.mission.build import build_mission
from gcs.mission.flight_plan import along_path, item_places, timed_visits
from gcs.mission.flight_timing import fly
from gcs.mission.geodesy import GridFrame
from gcs.mission.motion import CopterLimits
from gcs.mission.passing_order import PlannedPath

FRAME = GridFrame(-35.36, 149.16, 584.0, 10.0)


def test_a_path_that_steps_aside_and_back_has_its_later_items_on_the_later_pass() -> None:
    # out 20 m north, back to the start, then 30 m east: the third item is where the
    # first pass began, but the vehicle gets there 40 m along (fuzzed flight 3983)
    cells = np.array([[0.0, 1, 1], [4, 1, 3], [8, 1, 1], [14, 4, 1]])
    mission = build_mission(cells, 0.5, FRAME, holds=False)
    path = PlannedPath.of("uav1", cells, FRAME.cell_size_m, 3.0)

    places = list(item_places(mission, path, FRAME).values())

    assert np.allclose(places, [20.0, 40.0, 70.0], atol=0.01)
    timed = fly({"uav1": path}, {"uav1": np.full(3, 5.0)}, {"uav1": CopterLimits(5.0)})
    arrivals = [v.arrive for v in timed_visits(mission, timed["uav1"], FRAME)]
    assert arrivals == sorted(arrivals), arrivals


def test_a_place_is_never_looked_for_behind_where_the_last_one_was() -> None:
    """On a path out 20 m and back, a waypoint at the far end looked for from 30 m on is
    not the far end (20 m, behind): it is the nearest point from 30 m on."""
    cells = np.array([[0.0, 1, 1], [4, 1, 3], [8, 1, 1]])
    path = PlannedPath.of("uav1", cells, FRAME.cell_size_m, 3.0)
    far_end = path.xy[1]
    assert along_path(path, far_end) == 20.0
    assert along_path(path, far_end, after_m=30.0) == 30.0
    assert along_path(path, far_end, after_m=45.0) == path.length
