"""A geographic scenario's geofence and rally points (gcs/mission/fence.py): what the
autopilot is given as its backstop, and how ArduPilot gives it back."""

from __future__ import annotations

from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.mission_item import Frame, MissionItem
from gcs.mission.fence import (
    FencePlan,
    fence_items,
    fence_of,
    rally_items,
    same_fence_item,
    same_rally_item,
)
from gcs.mission.geographic import GeographicError, derive_file, load_geographic
from tests.geographic import EXAMPLE, feature, field, lon_lat, point, polygon, rectangle

BARN = polygon(rectangle(120, 60, 180, 140), role="no-fly", name="barn")
MAST = point(60, 150, role="no-fly", name="mast", radius_m=15.0)


def lat_lon(east: float, north: float) -> tuple[float, float]:
    lon, lat = lon_lat(east, north)
    return (lat, lon)


def test_the_area_is_the_inclusion_polygon_and_zones_are_exclusions() -> None:
    data = field(zones=[BARN, MAST])
    data["features"].append(point(30, 180, role="rally", name="north gate"))
    data["features"].append(
        feature({"type": "Point", "coordinates": [*lon_lat(280, 20), 25.0]}, role="rally")
    )
    plan = fence_of(load_geographic(data))
    assert plan.inclusion_polygons == (
        (lat_lon(0, 0), lat_lon(300, 0), lat_lon(300, 200), lat_lon(0, 200)),
    )
    assert plan.exclusion_polygons == (
        (lat_lon(120, 60), lat_lon(180, 60), lat_lon(180, 140), lat_lon(120, 140)),
    )
    assert plan.exclusion_circles == ((*lat_lon(60, 150), 15.0),)
    assert plan.rally_points == (lat_lon(30, 180), (*lat_lon(280, 20), 25.0))
    assert plan.has_fence and not plan.is_empty
    derive_file(data)  # the rally points are part of a valid scenario


def test_multipolygon_zones_and_holes_in_the_area_are_exclusion_polygons() -> None:
    area = polygon([*rectangle(0, 0, 300, 200), rectangle(200, 20, 220, 40)[0]], role="area")
    two = feature(
        {
            "type": "MultiPolygon",
            "coordinates": [rectangle(100, 100, 120, 120), rectangle(150, 10, 170, 30)],
        },
        role="no-fly",
    )
    data = field(zones=[two])
    data["features"][0] = area
    plan = fence_of(load_geographic(data))
    assert len(plan.inclusion_polygons) == 1
    assert [p[0] for p in plan.exclusion_polygons] == [
        lat_lon(200, 20),
        lat_lon(100, 100),
        lat_lon(150, 10),
    ]
    assert all(len(p) == 4 for p in plan.exclusion_polygons)


def test_a_scenario_without_zones_or_rally_points_has_only_its_area() -> None:
    plan = fence_of(load_geographic(field()))
    assert len(plan.inclusion_polygons) == 1
    assert plan.exclusion_polygons == plan.exclusion_circles == plan.rally_points == ()


def test_the_documented_example_gives_a_fence() -> None:
    plan = fence_of(load_geographic(EXAMPLE.read_text()))
    assert len(plan.inclusion_polygons[0]) == 5
    assert len(plan.exclusion_polygons) == 1 and len(plan.exclusion_circles) == 1


@pytest.mark.parametrize(
    ("rally", "message"),
    [
        (polygon(rectangle(10, 10, 20, 20), role="rally"), "a rally point is a Point"),
        (point(400, 100, role="rally"), "the rally point lies outside the area"),
        (point(150, 100, role="rally"), "the rally point lies inside no-fly zone"),
    ],
)
def test_rally_points_are_refused_naming_the_feature(rally: dict[str, Any], message: str) -> None:
    data = field(zones=[BARN])
    data["features"].append(rally)
    with pytest.raises(GeographicError, match=message) as refused:
        derive_file(data)
    assert refused.value.feature is not None and "rally point" in refused.value.feature


def test_a_negative_rally_altitude_is_refused() -> None:
    data = field()
    data["features"].append(
        feature({"type": "Point", "coordinates": [*lon_lat(30, 30), -5.0]}, role="rally")
    )
    with pytest.raises(GeographicError, match="altitude"):
        fence_of(load_geographic(data))
    with pytest.raises(GeographicError, match="altitude"):
        derive_file(data)


def test_fence_items_carry_vertex_counts_and_radii() -> None:
    plan = FencePlan(
        inclusion_polygons=(((1.0, 2.0), (1.0, 2.001), (1.001, 2.001)),),
        exclusion_polygons=(((1.0002, 2.0002), (1.0002, 2.0004), (1.0004, 2.0004), (1.0004, 2.0)),),
        exclusion_circles=((1.0005, 2.0005, 12.5),),
        rally_points=((1.0001, 2.0001), (1.0003, 2.0003, 42.4)),
    )
    items = fence_items(plan)
    assert [i.command for i in items] == [
        *[mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION] * 3,
        *[mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION] * 4,
        mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
    ]
    assert [i.params[0] for i in items] == [3, 3, 3, 4, 4, 4, 4, 12.5]
    assert (items[1].x, items[1].y) == (10_000_000, 20_010_000)
    rally = rally_items(plan, default_alt_m=15.0)
    assert [(r.command, r.frame, r.z) for r in rally] == [
        (mavlink2.MAV_CMD_NAV_RALLY_POINT, Frame.GLOBAL_RELATIVE_ALT, 15.0),
        (mavlink2.MAV_CMD_NAV_RALLY_POINT, Frame.GLOBAL_RELATIVE_ALT, 42.0),
    ]


def test_read_back_comparison_is_ardupilots() -> None:
    sent = MissionItem(
        mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, Frame.GLOBAL, (12.5, 0, 0, 0), 1, 2
    )
    # ArduPilot gives a fence item back in frame 0, z 0
    assert same_fence_item(sent, MissionItem(sent.command, 0, (12.5, 0, 0, 0), 1, 2, 0.0))
    assert not same_fence_item(sent, MissionItem(sent.command, 0, (12.0, 0, 0, 0), 1, 2))
    assert not same_fence_item(sent, MissionItem(sent.command, 0, (12.5, 0, 0, 0), 1, 3))
    rally = MissionItem(mavlink2.MAV_CMD_NAV_RALLY_POINT, Frame.GLOBAL_RELATIVE_ALT, x=1, y=2, z=30)
    assert same_rally_item(rally, MissionItem(rally.command, 3, x=1, y=2, z=30.0))
    assert not same_rally_item(rally, MissionItem(rally.command, 3, x=1, y=2, z=29.0))
