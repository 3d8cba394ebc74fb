"""Geographic scenarios from QGroundControl `.plan` files and KML (issue 26, item 2): the
fence becomes the area and the no-fly zones, each file's home and last waypoint a UAV's
start and goal, and every refusal names the file and the part at fault."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import shapely

from gcs.cli.main import main
from gcs.mission.area_imports import CIRCLE_SIDES, from_kml, from_plan_files, from_plans
from gcs.mission.geographic import GeographicError, derive_file
from tests.geographic import (
    BASE,
    YARD_KML,
    kml,
    kml_point,
    kml_polygon,
    lat_lon,
    placemark,
    qgc_plan,
    shape_in_metres,
    to_metres,
)

FLEET = {
    "alpha": qgc_plan((25, 25), (275, 175)),
    "bravo": qgc_plan((275, 25), (25, 175)),
}


def test_two_plan_files_make_a_two_uav_scenario_with_one_fence() -> None:
    data = from_plans(FLEET, cell_size_m=10.0)
    roles = [f["properties"]["role"] for f in data["features"]]
    assert roles.count("area") == 1 and roles.count("no-fly") == 2 and roles.count("rally") == 1
    derived = derive_file(data)
    s = derived.scenario
    assert (s.grid.width, s.grid.height) == (30, 20)
    uavs = {u.id: u for u in s.uavs}
    assert (uavs["alpha"].start, uavs["alpha"].goal) == ((2, 2), (27, 17))
    assert (uavs["bravo"].start, uavs["bravo"].goal) == ((27, 2), (2, 17))
    assert uavs["alpha"].speed == pytest.approx(0.4)  # cruise 4 m/s over 10 m cells
    blocked = s.blocked()
    assert blocked[15, 10]  # the barn's centre, (150, 100) m
    assert blocked[6, 15]  # the mast, (60, 150) m


def test_an_inclusion_circle_is_the_polygon_inscribed_in_it() -> None:
    plans = {"solo": qgc_plan((0, 0), (100, 0), fence=False)}
    circle = {"center": lat_lon(0, 0), "radius": 200.0}
    plans["solo"]["geoFence"]["circles"] = [{"circle": circle, "inclusion": True, "version": 1}]
    area = from_plans(plans, cell_size_m=10.0)["features"][0]
    (ring,) = area["geometry"]["coordinates"]
    assert len(ring) == CIRCLE_SIDES + 1 and ring[0] == ring[-1]
    lon, lat = np.array(ring).T
    assert np.hypot(*to_metres(lat, lon, *BASE).T) == pytest.approx(200.0, abs=0.01)
    shape = shape_in_metres(area["geometry"], *BASE)
    assert shape.area > 0.99 * shapely.Point(0, 0).buffer(200, quad_segs=256).area


def test_plan_files_are_read_from_disk_one_uav_per_file(tmp_path: Path) -> None:
    paths = []
    for name, document in FLEET.items():
        paths.append(tmp_path / f"{name}.plan")
        paths[-1].write_text(json.dumps(document))
    data = from_plan_files(paths, cell_size_m=10.0, name="yard")
    assert data["properties"] == {"cell_size_m": 10.0, "name": "yard"}
    assert {f["properties"].get("uav") for f in data["features"]} == {None, "alpha", "bravo"}


@pytest.mark.parametrize(
    ("change", "where", "message"),
    [
        (lambda p: p["geoFence"].update(polygons=[]), "geoFence", "hold 0"),
        (
            lambda p: p["geoFence"]["circles"][0].update(inclusion=True),
            "geoFence",
            "hold 2",
        ),
        (
            lambda p: p["geoFence"]["polygons"][1].update(polygon=[[1, 2], [3, 4]]),
            "alpha: geoFence.polygons[1]",
            "at least three",
        ),
        (
            lambda p: p["geoFence"]["circles"][0]["circle"].update(center=[91, 0]),
            "alpha: geoFence.circles[0]",
            "not a latitude",
        ),
        (
            lambda p: p["geoFence"]["circles"][0]["circle"].update(radius=-1),
            "alpha: geoFence.circles[0]",
            "positive",
        ),
        (
            lambda p: p["mission"].update(items=p["mission"]["items"][:1]),
            "alpha: mission.items",
            "no goal",
        ),
        (lambda p: p["mission"].pop("plannedHomePosition"), "alpha", "plannedHomePosition"),
    ],
)
def test_a_plan_that_cannot_be_a_scenario_is_refused_naming_the_part(
    change: Any, where: str, message: str
) -> None:
    document = qgc_plan((25, 25), (275, 175))
    change(document)
    with pytest.raises(GeographicError) as refused:
        from_plans({"alpha": document}, cell_size_m=10.0)
    assert refused.value.feature == where and message in str(refused.value)


def test_kml_placemarks_take_their_roles_from_names_or_extended_data() -> None:
    data = from_kml(kml(*YARD_KML))
    assert data["properties"] == {"cell_size_m": 10.0, "name": "yard"}
    derived = derive_file(data)
    (uav,) = derived.scenario.uavs
    assert (uav.id, uav.start, uav.goal, uav.speed) == ("alpha", (2, 2), (27, 17), 0.4)
    blocked = derived.scenario.blocked()
    assert blocked[15, 10] and blocked[6, 15]


def test_a_kml_multigeometry_of_polygons_is_a_multipolygon() -> None:
    two = [(100, 20), (110, 20), (110, 30)], [(200, 20), (210, 20), (210, 30)]
    multi = f"<MultiGeometry>{kml_polygon(two[0])}{kml_polygon(two[1])}</MultiGeometry>"
    data = from_kml(kml(*YARD_KML, placemark("no-fly pair", multi)))
    assert data["features"][-1]["geometry"]["type"] == "MultiPolygon"
    derive_file(data)


@pytest.mark.parametrize(
    ("text", "where", "message"),
    [
        (kml(*YARD_KML, cell=None), None, "no cell size"),
        (kml(placemark("hangar", kml_point(1, 1))), "Placemark 0 (hangar)", "role 'hangar'"),
        (kml(placemark("start a", kml_point(1, 1), speed_m_s="fast")), "Placemark 0", "fast"),
        ("<kml><Document>", None, "not KML"),
        (
            '<!DOCTYPE kml [<!ENTITY x SYSTEM "file:///etc/passwd">]><kml>&x;</kml>',
            None,
            "DOCTYPE",
        ),
        (kml(), None, "no Placemark"),
    ],
)
def test_kml_that_cannot_be_a_scenario_is_refused(
    text: str, where: str | None, message: str
) -> None:
    with pytest.raises(GeographicError) as refused:
        from_kml(text)
    assert (refused.value.feature or "").startswith(where or "") and message in str(refused.value)


def test_mvo_gcs_import_writes_a_geographic_scenario_that_plans(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plans = []
    for name, document in FLEET.items():
        plans.append(tmp_path / f"{name}.plan")
        plans[-1].write_text(json.dumps(document))
    out = tmp_path / "yard.geojson"
    assert main(["import", *map(str, plans), "--cell-size", "10", "--output", str(out)]) == 0
    assert "2 UAVs" in capsys.readouterr().err
    assert main(["plan", str(out), "--time-budget", "0", "--iterations", "50"]) == 0
    kml_file = tmp_path / "yard.kml"
    kml_file.write_text(kml(*YARD_KML))
    assert main(["plan", str(kml_file), "--time-budget", "0", "--iterations", "50"]) == 0
    with pytest.raises(SystemExit) as refused:
        main(["import", str(tmp_path / "missing.plan"), "--cell-size", "10"])
    assert refused.value.code == 2 and "missing.plan" in capsys.readouterr().err


def test_a_utf16_kml_with_an_external_entity_is_refused_before_it_is_read() -> None:
    bomb = '<?xml version="1.0" encoding="UTF-16"?><!DOCTYPE kml [<!ENTITY x SYSTEM '
    bomb += '"file:///etc/passwd">]><kml><Document><name>&x;</name></Document></kml>'
    with pytest.raises(GeographicError, match="DOCTYPE"):
        from_kml(bomb.encode("utf-16"))
