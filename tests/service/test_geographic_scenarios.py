"""POST /scenarios with `Content-Type: application/geo+json` (issue 26): the grid is
derived, stored beside the file and returned; its plans answer in WGS84 too; a file that
describes nothing plannable is a 422 naming the feature."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from gcs.mission.geodesy import GridFrame
from planner.cases import load_case
from sitl_mock import VehicleConfig
from tests.geographic import (
    EXAMPLE,
    clearance_m,
    densely,
    field,
    lon_lat,
    polygon,
    rectangle,
    shape_in_metres,
    to_metres,
)
from tests.inprocess.flying import register
from tests.inprocess.service import InProcessService, until
from tests.inprocess.vehicles import FAST_BOOT

pytestmark = [pytest.mark.virtual_clock]
GEOJSON = {"Content-Type": "application/geo+json"}


async def post(gcs: InProcessService, document: Any) -> Any:
    body = document if isinstance(document, bytes) else json.dumps(document).encode()
    return await gcs.client.post("/scenarios", content=body, headers=GEOJSON)


async def test_a_geographic_scenario_is_derived_stored_planned_and_answered_in_wgs84(
    gcs: InProcessService,
) -> None:
    document = json.loads(EXAMPLE.read_text())
    created = await post(gcs, document)
    assert created.status_code == 201, created.text
    answer = created.json()
    scenario = answer["scenario"]
    assert answer["name"] == "field-with-no-fly-zones" and answer["geographic"] == document
    assert scenario["grid"] == {"width": 50, "height": 43, "cell_size_m": 10.0}
    assert scenario["origin"]["alt_m"] == 584.0 and len(scenario["obstacles"]) > 500
    assert [u["radius"] for u in scenario["uavs"]] == pytest.approx([0.2] * 3)
    stored = (await gcs.client.get(f"/scenarios/{answer['id']}")).json()
    assert stored["geographic"] == document and stored["scenario"] == scenario

    planned = await gcs.client.post(f"/scenarios/{answer['id']}/plans", json={"wait_s": 30})
    assert planned.status_code == 201, planned.text
    body = planned.json()
    assert body["plan"]["feasible"]
    wgs84 = body["trajectories_wgs84"]
    assert set(wgs84) == {"uav1", "uav2", "uav3"}
    assert (await gcs.client.get(f"/plans/{body['id']}")).json()["trajectories_wgs84"] == wgs84

    # measured in metres on WGS84, knowing nothing of the grid: R (2 m) plus the margin
    zones = [f for f in document["features"] if f["properties"]["role"] == "no-fly"]
    area = next(f for f in document["features"] if f["properties"]["role"] == "area")
    for uav in body["plan"]["uavs"]:
        points = np.asarray(wgs84[uav["id"]])
        assert [p[0] for p in uav["trajectory"]] == points[:, 0].tolist()
        lat0, lon0 = points[0, 1:]
        path = densely(to_metres(points[:, 1], points[:, 2], lat0, lon0), 0.05)
        barn = shape_in_metres(zones[0]["geometry"], lat0, lon0)
        assert clearance_m(path, barn) >= 2.0
        mast_lon, mast_lat = zones[1]["geometry"]["coordinates"]
        mast = to_metres(np.array([mast_lat]), np.array([mast_lon]), lat0, lon0)[0]
        assert np.hypot(*(path - mast).T).min() - 40.0 >= 2.0
        edge = shape_in_metres(area["geometry"], lat0, lon0)
        assert (
            clearance_m(path, edge.exterior) >= 2.0
            and edge.contains(__import__("shapely").points(path)).all()
        )


async def test_a_grid_scenario_with_an_origin_is_answered_in_wgs84_too(
    gcs: InProcessService,
) -> None:
    created = await gcs.client.post("/scenarios", json=load_case("case-6").model_dump(mode="json"))
    assert created.status_code == 201 and created.json()["geographic"] is None
    planned = (
        await gcs.client.post(f"/scenarios/{created.json()['id']}/plans", json={"wait_s": 30})
    ).json()
    case = load_case("case-6")
    lat, lon = GridFrame.of(case).to_geodetic(*case.uavs[0].start)
    start = planned["trajectories_wgs84"]["uav1"][0]
    assert start == [0.0, pytest.approx(float(lat), abs=1e-8), pytest.approx(float(lon), abs=1e-8)]
    no_origin = load_case("case-6").model_copy(update={"origin": None}).model_dump(mode="json")
    sid = (await gcs.client.post("/scenarios", json=no_origin)).json()["id"]
    plan = (await gcs.client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30})).json()
    assert plan["trajectories_wgs84"] is None


@pytest.mark.parametrize(
    ("document", "feature", "message"),
    [
        (
            field(
                uavs=[("a", (150, 100), (275, 175))],
                zones=[polygon(rectangle(120, 60, 180, 140), role="no-fly", name="barn")],
            ),
            "features[2] (start of 'a')",
            "the start lies inside no-fly zone features[1] (no-fly zone 'barn')",
        ),
        (
            field(uavs=[("a", (25, 25), (310, 100))]),
            "features[2] (goal of 'a')",
            "the goal lies outside the area",
        ),
        (field(cell_size_m=0.5), "features[0] (the area 'field')", "more than the planner's"),
        (
            {"type": "FeatureCollection", "properties": {"cell_size_m": 5}, "features": []},
            None,
            'no feature has "role": "area"',
        ),
    ],
)
async def test_a_file_that_describes_nothing_plannable_is_a_422_naming_the_feature(
    gcs: InProcessService, document: dict[str, Any], feature: str | None, message: str
) -> None:
    refused = await post(gcs, document)
    assert refused.status_code == 422, refused.text
    assert refused.json()["feature"] == feature and message in refused.json()["detail"]
    assert (await gcs.client.get("/scenarios")).json() == []


async def test_a_malformed_file_is_a_422_saying_where(gcs: InProcessService) -> None:
    document = field()
    del document["properties"]["cell_size_m"]
    refused = await post(gcs, document)
    assert refused.status_code == 422
    assert ["body", "properties", "cell_size_m"] in [e["loc"] for e in refused.json()["detail"]]
    for body in (b"{not json", b""):
        refused = await post(gcs, body)
        assert refused.status_code == 422, (body, refused.text)
        assert refused.json()["detail"][0]["type"] == "json_invalid"
    assert (await post(gcs, b"\xff\xfe\xfa")).status_code == 400  # the guard's: not UTF-8
    grid_as_geojson = await post(gcs, load_case("case-6").model_dump(mode="json"))
    assert grid_as_geojson.status_code == 422  # a grid scenario is not GeoJSON
    assert (await gcs.client.get("/scenarios")).json() == []


async def test_the_api_document_describes_the_three_bodies(gcs: InProcessService) -> None:
    document = (await gcs.client.get("/openapi.json")).json()
    body = document["paths"]["/scenarios"]["post"]["requestBody"]["content"]
    kml = "application/vnd.google-earth.kml+xml"
    assert set(body) == {"application/json", "application/geo+json", kml}
    geo = body["application/geo+json"]["schema"]
    assert "$defs" not in json.dumps(geo) and geo["properties"]["type"]["const"] == (
        "FeatureCollection"
    )


def _vehicle_start(document: dict[str, Any], vehicle: str) -> tuple[dict[str, Any], int]:
    """The file with UAV 'a' starting where `vehicle` is (a null geometry)."""
    features = document["features"]
    index = next(k for k, f in enumerate(features) if f["properties"]["role"] == "start")
    features[index] = {
        "type": "Feature",
        "geometry": None,
        "properties": {"role": "start", "uav": "a", "vehicle": vehicle},
    }
    return document, index


async def test_a_start_is_placed_where_a_registered_vehicle_is_now(gcs: InProcessService) -> None:
    lon, lat = lon_lat(45, 35)
    config = VehicleConfig(sysid=1, home=(lat, lon, 0.0), transport="memory", **FAST_BOOT)
    sim = await gcs.vehicles.start([config])
    vehicle = await register(gcs.client, sim.connection_string(1))
    document, index = _vehicle_start(field(), vehicle)

    async def placed() -> Any:
        answer = await post(gcs, document)
        if answer.status_code == 422:  # connecting, or its EKF has no position yet
            assert answer.json()["feature"] == f"features[{index}] (start of 'a')"
            assert "has no position yet" in answer.json()["detail"], answer.text
            return None
        return answer

    created = await until(placed, 30, "a start placed where the vehicle is")
    assert created.status_code == 201, created.text
    stored = created.json()["geographic"]["features"][index]
    assert stored["geometry"]["coordinates"] == pytest.approx([lon, lat], abs=2e-7)
    assert stored["properties"]["vehicle"] == vehicle
    assert created.json()["scenario"]["uavs"][0]["start"] == [4, 3]  # (45, 35) m, 10 m cells

    unknown, index = _vehicle_start(field(), "no-such-vehicle")
    refused = await post(gcs, unknown)
    assert refused.status_code == 422
    assert refused.json() == {
        "detail": f"features[{index}] (start of 'a'): vehicle 'no-such-vehicle' is not registered",
        "feature": f"features[{index}] (start of 'a')",
    }
