"""Geographic scenarios (issue 26): a GeoJSON FeatureCollection in WGS84 made into the
planner's grid, every refusal naming the feature at fault."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest
import shapely
from pydantic import ValidationError

from gcs.cli.main import main
from gcs.mission.geographic import GeographicError, derive_file, wgs84_trajectories
from planner.model.scenario import MAX_GRID_SIDE
from planner.pipeline import PlannerSettings, plan
from tests.geographic import (
    BASE,
    EXAMPLE,
    collection,
    feature,
    field,
    lon_lat,
    point,
    polygon,
    properties_of,
    rectangle,
    ring,
    shape_in_metres,
    to_metres,
)

BARN = polygon(rectangle(120, 60, 180, 140), role="no-fly", name="barn")


def refusal(data: dict[str, Any]) -> GeographicError:
    with pytest.raises(GeographicError) as refused:
        derive_file(data)
    return refused.value


def test_the_grid_starts_at_the_areas_south_west_corner_and_covers_it() -> None:
    derived = derive_file(field())
    s, frame = derived.scenario, derived.frame
    assert (s.grid.width, s.grid.height, s.grid.cell_size_m) == (30, 20, 10.0)
    x, y = frame.to_cells(*BASE)  # the area's south-west corner
    assert (float(x), float(y)) == pytest.approx((-0.5, -0.5), abs=1e-4)  # 1 mm
    assert s.origin is not None and s.origin.alt_m == 0.0
    uav = s.uavs[0]
    assert (uav.id, uav.start, uav.goal) == ("a", (2, 2), (27, 17))
    assert (uav.speed, uav.radius) == (1.0, pytest.approx(0.3))  # the defaults, in cells
    # R + margin = 3 m + 1 m: only the ring of cells along the edge is blocked
    blocked = s.blocked()
    assert blocked[0].all() and blocked[-1].all() and blocked[:, 0].all() and blocked[:, -1].all()
    assert not blocked[1:-1, 1:-1].any()


def test_speeds_and_radii_in_metres_become_cells() -> None:
    data = field(cell_size_m=20.0, name="wide", alt_m=584.0)
    properties_of(data, "start").update(speed_m_s=5.0, radius_m=4.0)
    s = derive_file(data).scenario
    assert (s.name, s.grid.cell_size_m, s.uavs[0].speed, s.uavs[0].radius) == (
        "wide",
        20.0,
        0.25,
        0.2,
    )
    assert s.origin is not None and s.origin.alt_m == 584.0


def test_a_cell_is_blocked_exactly_when_it_comes_within_r_plus_margin_of_a_zone() -> None:
    circle = point(60, 150, role="no-fly", name="mast", radius_m=25.0)
    data = field(zones=[BARN, circle], margin_m=2.5)
    properties_of(data, "start")["radius_m"] = 2.0
    derived = derive_file(data)
    s, frame = derived.scenario, derived.frame
    assert derived.clearance_m == 4.5
    barn = shape_in_metres(BARN["geometry"], *BASE)
    mast_lon, mast_lat = circle["geometry"]["coordinates"]
    mast = shapely.Point(to_metres(np.array([mast_lat]), np.array([mast_lon]), *BASE)[0])
    area = shape_in_metres(data["features"][0]["geometry"], *BASE)
    blocked = s.blocked()
    for x in range(s.grid.width):
        for y in range(s.grid.height):
            lat, lon = frame.to_geodetic(
                [x - 0.5, x + 0.5, x + 0.5, x - 0.5], [y - 0.5] * 2 + [y + 0.5] * 2
            )
            square = shapely.Polygon(to_metres(lat, lon, *BASE))
            gaps = (
                square.distance(barn),
                square.distance(mast) - 25.0,
                square.distance(area.exterior) if area.contains(square) else -1.0,
            )
            # 1 mm either way: the grid's tangent plane is not the base point's
            if min(gaps) > 4.5 + 1e-3:
                assert not blocked[x, y], (x, y, gaps)
            elif min(gaps) < 4.5 - 1e-3:
                assert blocked[x, y], (x, y, gaps)


def test_multipolygons_and_holes_are_zones_as_drawn() -> None:
    two = feature(
        {
            "type": "MultiPolygon",
            "coordinates": [rectangle(100, 0, 120, 150), rectangle(200, 50, 220, 200)],
        },
        role="no-fly",
    )
    s = derive_file(field(zones=[two])).scenario
    blocked = s.blocked()
    assert blocked[11, 5] and blocked[21, 15] and not blocked[16, 10]
    assert plan(s, PlannerSettings(time_budget_s=None, iterations=20)).feasible


def test_the_example_file_is_planned_and_answered_in_wgs84() -> None:
    derived = derive_file(EXAMPLE.read_text())
    s = derived.scenario
    assert [u.id for u in s.uavs] == ["uav1", "uav2", "uav3"]
    result = plan(s, PlannerSettings(time_budget_s=None, iterations=50))
    assert result.feasible
    wgs84 = wgs84_trajectories(derived.frame, result)
    for uav in result.uavs:
        points = np.array(wgs84[uav.id])
        assert points[:, 0].tolist() == [p[0] for p in uav.trajectory]
        x, y = derived.frame.to_cells(points[:, 1], points[:, 2])
        grid = np.array(uav.trajectory)[:, 1:]
        assert np.allclose(np.column_stack([x, y]), grid, atol=1e-3)  # 1e-8 deg: 1 mm


def test_mvo_gcs_plan_takes_a_geojson_file(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", str(EXAMPLE), "--time-budget", "0", "--iterations", "30"]) == 0
    answer = json.loads(capsys.readouterr().out)
    assert answer["feasible"] and set(answer["trajectories_wgs84"]) == {"uav1", "uav2", "uav3"}
    lat, lon = answer["trajectories_wgs84"]["uav1"][0][1:]
    assert (lat, lon) == pytest.approx((-35.3655, 149.1645), abs=5e-5)  # its start's cell


def test_a_geojson_file_that_cannot_be_planned_is_one_line(
    tmp_path: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "bad.geojson"
    path.write_text(json.dumps(field(uavs=[("a", (25, 25), (400, 100))])))
    with pytest.raises(SystemExit) as exited:
        main(["plan", str(path)])
    assert exited.value.code == 2
    err = capsys.readouterr().err
    assert "features[2] (goal of 'a'): the goal lies outside the area" in err, err


# -- refusals -------------------------------------------------------------------------


def test_a_self_intersecting_ring_is_named_with_where_it_crosses() -> None:
    bow_tie = polygon([ring([(100, 50), (200, 150), (200, 50), (100, 150)])], role="no-fly")
    error = refusal(field(zones=[bow_tie]))
    assert error.feature == "features[1] (no-fly zone)"
    assert "Self-intersection" in str(error) and "not a valid Polygon" in str(error)


def test_a_self_intersecting_area_is_named() -> None:
    data = field()
    data["features"][0] = polygon(
        [ring([(0, 0), (300, 200), (300, 0), (0, 200)])], role="area", name="field"
    )
    assert refusal(data).feature == "features[0] (the area 'field')"


def test_a_start_inside_a_zone_or_within_its_margin() -> None:
    inside = refusal(field(uavs=[("a", (150, 100), (275, 175))], zones=[BARN]))
    assert inside.feature == "features[2] (start of 'a')"
    assert "inside no-fly zone features[1] (no-fly zone 'barn')" in str(inside)
    near = refusal(field(uavs=[("a", (117.5, 100), (275, 175))], zones=[BARN]))
    assert near.feature == "features[2] (start of 'a')"
    assert "is 2.5 m from no-fly zone features[1]" in str(near)
    assert "R + margin = 4.0 m" in str(near)


def test_a_goal_outside_the_area() -> None:
    error = refusal(field(uavs=[("a", (25, 25), (310, 100))]))
    assert error.feature == "features[2] (goal of 'a')"
    assert str(error).endswith("the goal lies outside the area")


def test_a_start_whose_cell_is_blocked() -> None:
    # 8 m from the barn (more than R + margin), but its cell's square comes within 3 m
    error = refusal(field(uavs=[("a", (112, 100), (275, 175))], zones=[BARN]))
    assert error.feature == "features[2] (start of 'a')"
    assert "cell (11, 10) is blocked" in str(error)
    assert "no-fly zone features[1] (no-fly zone 'barn')" in str(error)
    edge = refusal(field(uavs=[("a", (6, 102), (275, 175))]))
    assert "cell (0, 10) is blocked" in str(edge)
    assert "the area's edge" in str(edge)


def test_an_area_too_large_for_the_grid_says_which_cells_would_do() -> None:
    error = refusal(field(cell_size_m=0.5))
    assert error.feature == "features[0] (the area 'field')"
    assert "the area is 300 m x 200 m: 600 x 40" in str(error)
    assert f"cells of 0.5 m, more than the planner's {MAX_GRID_SIDE} x" in str(error)
    assert "use cells of at least 0.61 m" in str(error)


@pytest.mark.parametrize(
    ("change", "feature", "message"),
    [
        (lambda d: d["features"].pop(0), None, 'no feature has "role": "area"'),
        (
            lambda d: d["features"].append(point(50, 50, role="start", uav="a")),
            "features[3] (start of 'a')",
            "UAV 'a' already has a start: features[1]",
        ),
        (
            lambda d: d["features"].append(point(50, 50, role="start", uav="b")),
            "features[3] (start of 'b')",
            "UAV 'b' has no goal",
        ),
        (
            lambda d: d["features"].append(point(50, 50, role="goal", uav="b")),
            "features[3] (goal of 'b')",
            "UAV 'b' has no start",
        ),
        (
            lambda d: d["features"].append(point(50, 50, role="no-fly")),
            "features[3] (no-fly zone)",
            "a Point no-fly zone needs its 'radius_m'",
        ),
        (
            lambda d: d["features"].append(polygon(rectangle(0, 0, 9, 9), role="area")),
            "features[3] (the area)",
            "a second area (features[0] (the area 'field') is the first)",
        ),
        (
            lambda d: d["features"][1]["properties"].update(radius_m=5.0),
            "features[1] (start of 'a')",
            "radius_m 5 of UAV 'a' is not below half a cell (5 m)",
        ),
        (
            lambda d: d["features"][2]["properties"].pop("uav"),
            "features[2] (goal of None)",
            'a goal names its UAV: "uav": "<id>"',
        ),
    ],
)
def test_each_refusal_names_the_feature(change: Any, feature: str | None, message: str) -> None:
    data = field()
    change(data)
    error = refusal(data)
    assert error.feature == feature and message in str(error), str(error)


def test_starts_too_close_are_the_grids_refusal_in_the_files_terms() -> None:
    error = refusal(field(uavs=[("a", (25, 25), (275, 175)), ("b", (21, 21), (280, 20))]))
    assert "features[2] (start of 'a')" not in str(error)  # uavs[0] is named by its start
    assert "features[1] (start of 'a') 'a' and features[3] (start of 'b') 'b' start closer" in str(
        error
    )


def test_a_goal_walled_off_by_zones_is_named() -> None:
    moat = polygon(
        [
            ring([(200, 100), (280, 100), (280, 190), (200, 190)]),
            ring([(220, 120), (260, 120), (260, 170), (220, 170)]),
        ],
        role="no-fly",
        name="moat",
    )
    error = refusal(field(uavs=[("a", (25, 25), (240, 145))], zones=[moat]))
    assert "features[3] (goal of 'a')" in str(error) and "cannot be reached" in str(error)


@pytest.mark.parametrize(
    ("change", "where"),
    [
        (lambda d: d["properties"].pop("cell_size_m"), ("properties", "cell_size_m")),
        (lambda d: d["features"][0]["properties"].update(role="zone"), ("features", 0)),
        (lambda d: d["features"][1]["properties"].update(speed_m_s=True), ("features", 1)),
        (lambda d: d["features"][0]["geometry"]["coordinates"][0].pop(), ("features", 0)),
        (lambda d: d["features"][1]["geometry"].update(coordinates=[200, 10]), ("features", 1)),
        (lambda d: d.update(type="Feature"), ("type",)),
    ],
)
def test_a_malformed_file_is_refused_naming_where(change: Any, where: tuple[Any, ...]) -> None:
    data = field()
    change(data)
    with pytest.raises(ValidationError) as refused:
        derive_file(data)
    assert any(tuple(e["loc"][: len(where)]) == where for e in refused.value.errors()), (
        refused.value.errors()
    )


def test_foreign_members_and_other_properties_are_kept_out_of_the_way() -> None:
    data = field()
    data["bbox"] = [0, 0, 1, 1]
    data["features"][0]["properties"]["fill"] = "#ff0000"
    data["features"][0]["id"] = 7
    data["features"][1]["geometry"]["coordinates"] = [*lon_lat(25, 25), 584.0]  # altitude
    assert derive_file(data).scenario.uavs[0].start == (2, 2)
    assert collection([])["type"] == "FeatureCollection"


def test_zones_far_from_the_area_are_clipped_away_before_they_are_cut() -> None:
    """A continent-sized zone elsewhere costs nothing (its edges, cut every 11 m,
    would be millions of points) and blocks nothing; one that covers the area does."""
    far = polygon([[[-10.0, 10.0], [60.0, 10.0], [60.0, 60.0], [-10.0, 60.0], [-10.0, 10.0]]])
    far["properties"] = {"role": "no-fly"}
    s = derive_file(field(zones=[far])).scenario
    assert len(s.obstacles) == 30 * 2 + 18 * 2  # the edge's ring only
    covering = polygon(
        [[[140.0, -40.0], [160.0, -40.0], [160.0, -30.0], [140.0, -30.0], [140.0, -40.0]]]
    )
    covering["properties"] = {"role": "no-fly", "name": "all"}
    assert "inside no-fly zone features[1] (no-fly zone 'all')" in str(
        refusal(field(zones=[covering]))
    )


def test_an_area_the_size_of_a_continent_is_refused_before_it_is_cut() -> None:
    data = field()
    data["features"][0] = polygon(
        [[[100.0, -40.0], [150.0, -40.0], [150.0, -10.0], [100.0, -10.0], [100.0, -40.0]]],
        role="area",
    )
    assert "more than the planner's 500 x 500" in str(refusal(data))


def test_a_start_where_a_vehicle_is_cannot_be_placed_without_the_service() -> None:
    data = field()
    data["features"][1] = feature(None, role="start", uav="a", vehicle="v1")  # type: ignore[arg-type]
    error = refusal(data)
    assert error.feature == "features[1] (start of 'a')"
    assert "where vehicle 'v1' is now" in str(error)
