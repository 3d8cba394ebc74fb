"""A geographic scenario against a real `mvo-gcs serve` (issue 26): the GeoJSON example
posted as `application/geo+json` comes back as its derived grid, is stored with the file
beside it across a restart, and is planned with every trajectory in WGS84 too; a client
that knows nothing of the grid measures the clearance from the zones itself."""

from __future__ import annotations

import json
from collections.abc import Iterator

import numpy as np
import pytest

from gcs.mission.fence import fence_of
from gcs.mission.geographic import load_geographic
from tests.geographic import (
    EXAMPLE,
    YARD_KML,
    clearance_m,
    densely,
    kml,
    kml_point,
    placemark,
    shape_in_metres,
    to_metres,
)
from tests.service_process import ServiceProcess

GEOJSON = {"Content-Type": "application/geo+json"}
KML = {"Content-Type": "application/vnd.google-earth.kml+xml"}


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServiceProcess]:
    """One service for the module's tests (a start is seconds of the machine's time):
    each posts and reads its own scenario; the first restarts it and reads back."""
    proc = ServiceProcess(tmp_path_factory.mktemp("geographic") / "data")
    proc.start()
    yield proc
    proc.stop()


def test_a_geographic_scenario_is_derived_planned_and_answered_in_wgs84(
    service: ServiceProcess,
) -> None:
    document = json.loads(EXAMPLE.read_text())
    with service.client() as client:
        created = client.post("/scenarios", content=EXAMPLE.read_bytes(), headers=GEOJSON)
        assert created.status_code == 201, created.text
        scenario = created.json()
        assert scenario["geographic"] == document
        assert scenario["scenario"]["grid"] == {"width": 50, "height": 43, "cell_size_m": 10.0}
        planned = client.post(f"/scenarios/{scenario['id']}/plans", json={"wait_s": 60})
        assert planned.status_code == 201, planned.text
        answer = planned.json()
        assert answer["plan"]["feasible"]

        refused = client.post(
            "/scenarios",
            content=json.dumps({**document, "features": document["features"][1:]}),
            headers={"Content-Type": "application/geo+json; charset=utf-8"},
        )
        assert refused.status_code == 422
        assert refused.json()["detail"] == 'no feature has "role": "area": the operating area'

    service.stop()
    service.start()
    with service.client() as client:
        stored = client.get(f"/scenarios/{scenario['id']}").json()
        assert stored["geographic"] == document and stored["scenario"] == scenario["scenario"]
        again = client.get(f"/plans/{answer['id']}").json()
        assert again["trajectories_wgs84"] == answer["trajectories_wgs84"]

    zones = [f for f in document["features"] if f["properties"]["role"] == "no-fly"]
    radius_m = 2.0
    for uav, points in answer["trajectories_wgs84"].items():
        points = np.asarray(points)
        assert points[0, 0] == 0.0 and (np.diff(points[:, 0]) >= 0).all(), uav
        barn = zones[0]["geometry"]["coordinates"][0][0]  # measured around its corner
        path = densely(to_metres(points[:, 1], points[:, 2], barn[1], barn[0]), 0.05)
        assert clearance_m(path, shape_in_metres(zones[0]["geometry"], barn[1], barn[0])) >= (
            radius_m + 1.0
        )
        mast_lon, mast_lat = zones[1]["geometry"]["coordinates"]
        path = densely(to_metres(points[:, 1], points[:, 2], mast_lat, mast_lon), 0.05)
        assert np.hypot(*path.T).min() - zones[1]["properties"]["radius_m"] >= radius_m + 1.0


def test_a_kml_scenario_is_stored_as_geojson_and_its_plan_files_carry_the_fence(
    service: ServiceProcess,
) -> None:
    """Issue 26, item 2: KML in, the fence and rally points out in QGroundControl's
    `.plan`, and MAVSDK-style readers get what the flight would upload."""
    with service.client() as client:
        created = client.post("/scenarios", content=kml(*YARD_KML), headers=KML)
        assert created.status_code == 201, created.text
        stored = created.json()
        roles = [f["properties"]["role"] for f in stored["geographic"]["features"]]
        assert sorted(roles) == ["area", "goal", "no-fly", "no-fly", "rally", "start"]
        planned = client.post(f"/scenarios/{stored['id']}/plans", json={"wait_s": 60})
        assert planned.status_code == 201, planned.text
        plan_id = planned.json()["id"]
        answer = client.get(f"/plans/{plan_id}/missions/alpha.plan")
        assert answer.status_code == 200, answer.text
        document = answer.json()
        fence = fence_of(load_geographic(stored["geographic"]))
        polygons = document["geoFence"]["polygons"]
        assert [p["inclusion"] for p in polygons] == [True, False]
        assert polygons[0]["polygon"] == [list(v) for v in fence.inclusion_polygons[0]]
        (circle,) = document["geoFence"]["circles"]
        assert circle["inclusion"] is False and circle["circle"]["radius"] == 15.0
        (rally,) = document["rallyPoints"]["points"]
        assert rally[:2] == list(fence.rally_points[0][:2])

        refused = client.post(
            "/scenarios", content=kml(placemark("hangar", kml_point(1, 1))), headers=KML
        )
        assert refused.status_code == 422
        assert refused.json()["feature"] == "Placemark 0 (hangar)"
        broken = client.post("/scenarios", content=b"<kml><Document>", headers=KML)
        assert broken.status_code == 422 and "not KML" in broken.json()["detail"]
