"""The console's geographic mode in a real browser (Debian's Chromium under Playwright)
against a real `mvo-gcs serve` with three mock vehicles near ArduPilot SITL's home: the
map opens on the vehicles; the operator draws the area and a no-fly zone by clicking on
the map, starts one UAV where a vehicle is and places the other's start and goals, is
told which feature a refused file got wrong, derives the grid, plans, sees both paths
go round the zone, and flies them (both land at their goals). The plan is checked in
metres from the API's `trajectories_wgs84` (tests/geographic.py, never the grid), and on
the screen from the paths the page drew.

Every wait is for a condition with a generous bound; nothing sleeps to let things
settle. A browser console error fails the test (the refused file's 422 aside).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import shapely

from sitl_mock import Simulator, VehicleConfig
from tests.browser.chromium import NEEDS_CHROMIUM, Browser
from tests.geographic import (
    BASE,
    EXAMPLE,
    YARD_KML,
    clearance_m,
    densely,
    kml,
    lon_lat,
    shape_in_metres,
    to_metres,
)
from tests.service_process import TOKEN, ServiceProcess

pytestmark = NEEDS_CHROMIUM
pytest.importorskip("playwright.sync_api", reason="playwright is not installed")

# Metres east and north of BASE. The area is 298 m x 198 m, so that clicks a metre off
# still make a grid of 30 x 20 cells of 10 m. Cell (0, 0) has its south-west corner at the
# area's: the vehicles stand at cells' centres, as a flight wants a vehicle within 3 m of
# its planned start (a start is its cell's centre).
VEHICLES = {1: (46.0, 106.0), 2: (46.0, 166.0), 3: (256.0, 46.0)}
AREA = [(1.0, 1.0), (299.0, 1.0), (299.0, 199.0), (1.0, 199.0)]
ZONE = [(120.0, 50.0), (180.0, 50.0), (180.0, 150.0), (120.0, 150.0)]
GOAL_IN_ZONE = (150.0, 100.0)
GOALS = {"uav1": (260.0, 100.0), "uav2": (260.0, 40.0)}
START_UAV2 = VEHICLES[2]
NAMES = {1: "alpha", 2: "bravo", 3: "charlie"}
KML = "application/vnd.google-earth.kml+xml"
CLICK_M = 3.0  # a click lands within a pixel or two of where it was aimed (~0.5 m each)


@pytest.fixture
def vehicles() -> Iterator[Simulator]:
    configs = []
    for sysid, (east, north) in VEHICLES.items():
        lon, lat = lon_lat(east, north)
        configs.append(VehicleConfig(sysid=sysid, port=0, home=(lat, lon, 584.0)))
    sim = Simulator(configs, speedup=20.0, seed=1)
    with sim.running():
        yield sim


PARKED = """() => [...document.querySelectorAll('.parked-vehicle')].map((el) => {
  const r = el.getBoundingClientRect();
  return {id: el.dataset.vehicle, lat: Number(el.dataset.lat), lon: Number(el.dataset.lon),
          px: [r.left + r.width / 2, r.top + r.height / 2]};
})"""

# Every point of an SVG path every 1/200 of its length, in the page's pixels.
SAMPLED = """(selector) => [...document.querySelectorAll(selector)].map((p) => {
  const m = p.getScreenCTM(), n = 200, length = p.getTotalLength(), pts = [];
  for (let i = 0; i <= n; i++) {
    const q = p.getPointAtLength(length * i / n);
    pts.push([m.a * q.x + m.c * q.y + m.e, m.b * q.x + m.d * q.y + m.f]);
  }
  return {uav: p.dataset.uav ?? null, pts};
})"""


class MapFrame:
    """Metres (east, north of BASE) to the page's pixels, fitted to where the page drew the
    parked vehicles (affine: Web Mercator is, over a few hundred metres, to far below a
    pixel)."""

    def __init__(self, parked: list[dict[str, Any]]) -> None:
        assert len(parked) == 3, parked
        lat = np.array([p["lat"] for p in parked])
        lon = np.array([p["lon"] for p in parked])
        metres = to_metres(lat, lon, *BASE)
        a = np.column_stack([metres, np.ones(len(parked))])
        self.matrix = np.linalg.solve(a, np.array([p["px"] for p in parked]))
        self.px_per_m = float(np.linalg.norm(self.matrix[0]))

    def pixel(self, east: float, north: float) -> tuple[float, float]:
        x, y = np.array([east, north, 1.0]) @ self.matrix
        return float(x), float(y)


def click(b: Browser, frame: MapFrame, at: tuple[float, float]) -> None:
    b.page.mouse.click(*frame.pixel(*at))


def tool(b: Browser, name: str) -> None:
    b.page.check(f"input[name='geo-tool'][value='{name}']")


def metres_of(coordinates: list[list[float]]) -> np.ndarray:
    c = np.array(coordinates)
    return to_metres(c[:, 1], c[:, 0], *BASE)


def test_an_operator_draws_an_area_and_a_zone_and_the_paths_go_round_it(
    service: ServiceProcess, vehicles: Simulator, browser: Browser, shots: Path
) -> None:
    b, page = browser, browser.page
    with service.client() as client:
        ids = {}
        for k in vehicles.sysids:  # as `mvo-gcs demo` does before the operator arrives
            body = {"connection": vehicles.connection_string(k), "name": NAMES[k]}
            answer = client.post("/vehicles", json=body)
            assert answer.status_code == 201, answer.text
            ids[k] = answer.json()["id"]

        # The map opens on the vehicles, where they are: all on the map, close enough to
        # draw on (not the world at 3000 km a scale bar).
        page.goto(service.url + "/")
        b.wait_js("() => document.body.dataset.ready === 'true'", 30)
        b.wait_js(
            "() => [...document.querySelectorAll('.parked-vehicle')]"
            ".filter((el) => el.dataset.lat).length === 3",
            60,
        )
        parked = b.js(PARKED)
        box = page.locator("#map").bounding_box()
        for v in parked:
            x, y = v["px"]
            assert box["x"] < x < box["x"] + box["width"], v
            assert box["y"] < y < box["y"] + box["height"], v
        frame = MapFrame(parked)
        assert 1.0 < frame.px_per_m < 6.0, frame.px_per_m
        assert page.inner_text(".leaflet-control-scale-line").endswith(" m")
        for v in parked:  # where the page drew each vehicle is where it is
            sysid = next(k for k, i in ids.items() if i == v["id"])
            east, north = to_metres(np.array(v["lat"]), np.array(v["lon"]), *BASE)[0]
            assert np.hypot(east - VEHICLES[sysid][0], north - VEHICLES[sysid][1]) < 1.0, v

        # Draw the area (four corners, Close shape) and a zone (double-click its last).
        page.fill("#geo-name", "yard")
        page.fill("#geo-cell", "10")
        tool(b, "area")
        for corner in AREA:
            click(b, frame, corner)
        page.click("#geo-close-btn")
        tool(b, "no-fly")
        for corner in ZONE[:-1]:
            click(b, frame, corner)
        page.mouse.dblclick(*frame.pixel(*ZONE[-1]))
        b.wait_js("() => document.querySelectorAll('#geo-features li').length === 2", 10)
        assert page.locator("path.geo-area").count() == 1
        assert page.locator("path.geo-zone").count() == 1

        # uav1 starts where vehicle 1 is; uav2 where clicked. uav2's goal, first, in the zone.
        page.select_option("#geo-uav-table select[data-uav='uav1']", ids[1])
        tool(b, "goal")
        click(b, frame, GOALS["uav1"])
        page.click("#geo-add-uav-btn")
        tool(b, "start")
        click(b, frame, START_UAV2)
        tool(b, "goal")
        click(b, frame, GOAL_IN_ZONE)
        b.wait_js("() => document.querySelectorAll('.geo-goal').length === 2", 10)

        # Refused: the message names the feature, its row is marked.
        page.click("#geo-submit-btn")
        page.wait_for_selector("#token-dialog[open]")
        page.fill("#token-input", TOKEN)
        page.click("#token-ok")
        page.locator("#geo-errors .field-error").wait_for()
        refusal = page.inner_text("#geo-errors")
        assert "goal of 'uav2'" in refusal, refusal
        assert page.locator("#geo-uav-table td[aria-invalid='true'].geo-goal-cell").count() == 1
        assert page.locator(".geo-goal.geo-refused").count() == 1
        b.js("() => document.querySelector('#area-section').scrollIntoView()")
        b.shot(shots, "console-area-refused.png")

        # Moved out of the zone, the grid is derived: blocked cells and ends on the map.
        click(b, frame, GOALS["uav2"])
        page.click("#geo-submit-btn")
        b.wait_js("() => document.querySelectorAll('.cell-start').length === 2", 60)
        scenario_id = page.inner_text("#scenario-status").removeprefix("stored as ").strip()
        stored = client.get(f"/scenarios/{scenario_id}").json()
        grid = stored["scenario"]
        assert page.locator("path.obstacle").count() == len(grid["obstacles"]) > 0
        assert (grid["grid"]["width"], grid["grid"]["height"]) == (30, 20)
        assert "grid 30\u00d720 of 10 m" in page.inner_text("#geo-status")

        # The file the page posted is what was drawn, in coordinates.
        features = stored["geographic"]["features"]
        by_role = {(f["properties"]["role"], f["properties"].get("uav")): f for f in features}
        area_m = metres_of(by_role["area", None]["geometry"]["coordinates"][0])
        assert np.abs(area_m[:-1] - np.array(AREA)).max() < CLICK_M, area_m
        zone = by_role["no-fly", None]["geometry"]
        zone_m = metres_of(zone["coordinates"][0])
        assert np.abs(zone_m[:-1] - np.array(ZONE)).max() < CLICK_M, zone_m
        start1 = by_role["start", "uav1"]
        assert start1["properties"]["vehicle"] == ids[1]
        placed = metres_of([start1["geometry"]["coordinates"]])[0]
        assert np.hypot(*(placed - np.array(VEHICLES[1]))) < 1.0, placed
        assert stored["geographic"]["properties"]["name"] == "yard"

        # Plan: both paths drawn together, and they go round the zone.
        page.fill("#pl-budget", "3")
        page.click("#plan-btn")
        b.wait_js("() => document.querySelectorAll('path.plan-path').length === 2", 90)
        plan_id = page.inner_text("#plan-id").strip()
        answer = client.get(f"/plans/{plan_id}").json()
        assert answer["plan"]["feasible"], answer["plan"]["metrics"]
        zone_shape = shape_in_metres(zone, *BASE)
        cell = grid["grid"]["cell_size_m"]
        kept = {u["id"]: u["radius"] * cell + 1.0 for u in grid["uavs"]}  # R + margin (1 m)
        paths_m = {}
        for uav, points in answer["trajectories_wgs84"].items():
            t_lat_lon = np.array(points)
            path = densely(to_metres(t_lat_lon[:, 1], t_lat_lon[:, 2], *BASE), 0.5)
            paths_m[uav] = path
            straight = shapely.LineString([path[0], path[-1]])
            assert straight.intersects(zone_shape), f"{uav}: the zone is not in its way"
            assert clearance_m(path, zone_shape) >= kept[uav] - 0.01, uav
            assert np.hypot(*(path[-1] - np.array(GOALS[uav]))) < cell, uav
        assert set(paths_m) == {"uav1", "uav2"}

        # On the screen: each drawn path runs from its start to its goal where the plan
        # says, and stays out of the zone as the page drew it.
        frame = MapFrame(b.js(PARKED))  # the view moved onto the grid
        zone_px = shapely.Polygon(b.js(SAMPLED, "path.geo-zone")[0]["pts"])
        for drawn in b.js(SAMPLED, "path.plan-path"):
            uav, pts = drawn["uav"], np.array(drawn["pts"])
            ends = paths_m[uav][[0, -1]]
            for end, px in zip(ends, pts[[0, -1]], strict=True):
                assert np.hypot(*(np.array(frame.pixel(*end)) - px)) < 3.0, (uav, end, px)
            gap_px = float(shapely.distance(shapely.points(pts), zone_px).min())
            assert gap_px > 0.8 * kept[uav] * frame.px_per_m, (uav, gap_px)
        assert page.input_value("#binding-table select[data-uav='uav1']") == ids[1]
        b.js("() => document.querySelector('#area-section').scrollIntoView()")
        b.shot(shots, "console-area.png")

        # Fly it as any plan: uav1 on alpha (it starts there), uav2 on bravo; each lands
        # at its goal, drawn there.
        assert page.input_value("#binding-table select[data-uav='uav2']") == ids[2]
        b.wait_js(
            "() => document.querySelectorAll('#vehicle-table tr[data-online=true]').length === 3",
            60,
        )
        page.click("#upload-btn")
        b.wait_js(
            "() => ['uploaded', 'upload_failed']"
            ".includes(document.querySelector('#flight-state').textContent)",
            120,
        )
        assert page.inner_text("#flight-state") == "uploaded", page.inner_text("#upload-results")
        page.click("#start-btn")
        b.wait_js("() => document.querySelectorAll('.vehicle').length === 2", 60)
        b.wait_js("() => document.querySelector('#flight-state').textContent === 'landed'", 180)
        for uav, goal in GOALS.items():
            drawn = page.locator(f".vehicle[data-uav='{uav}']")
            lat, lon = (float(drawn.get_attribute(f"data-{k}")) for k in ("lat", "lon"))
            at = to_metres(np.array(lat), np.array(lon), *BASE)[0]
            assert np.hypot(*(at - np.array(goal))) < cell, (uav, at)

    unexpected = [m for m in b.errors if "status of 422" not in m]
    assert not unexpected, unexpected
    assert not b.foreign, f"the page loaded from outside the service: {b.foreign}"
    assert not service.problems(), service.problems()


def test_an_operator_imports_geojson_and_kml_files(
    service: ServiceProcess, browser: Browser, tmp_path: Path
) -> None:
    """GeoJSON is read into the editor (drawn, editable) and posted when the operator
    derives the grid; KML is posted as it is, the service's GeoJSON of it comes back;
    a QGroundControl .plan file is pointed to `mvo-gcs import`."""
    b, page = browser, browser.page
    example = json.loads(EXAMPLE.read_text())
    zones = sum(f["properties"]["role"] == "no-fly" for f in example["features"])
    uavs = sum(f["properties"]["role"] == "start" for f in example["features"])
    page.goto(service.url + "/")
    b.wait_js("() => document.body.dataset.ready === 'true'", 30)

    page.set_input_files("#geo-file", EXAMPLE)
    b.wait_js("(n) => document.querySelectorAll('path.geo-zone').length === n", 10, zones)
    assert page.locator("path.geo-area").count() == 1
    assert page.locator("#geo-uav-table tbody tr").count() == uavs
    assert float(page.input_value("#geo-cell")) == example["properties"]["cell_size_m"]
    page.click("#geo-submit-btn")
    page.wait_for_selector("#token-dialog[open]")
    page.fill("#token-input", TOKEN)
    page.click("#token-ok")
    b.wait_js("(n) => document.querySelectorAll('.cell-start').length === n", 60, uavs)
    assert "grid 50\u00d743 of 10 m" in page.inner_text("#geo-status")
    first = page.inner_text("#scenario-status")

    page.set_input_files(
        "#geo-file",
        files=[{"name": "yard.kml", "mimeType": KML, "buffer": kml(*YARD_KML).encode()}],
    )
    b.wait_js(
        "(before) => document.querySelector('#scenario-status').textContent !== before",
        60,
        first,
    )
    scenario_id = page.inner_text("#scenario-status").removeprefix("stored as ").strip()
    with service.client() as client:
        stored = client.get(f"/scenarios/{scenario_id}").json()
    assert stored["geographic"]["properties"]["cell_size_m"] == 10.0
    assert page.locator("path.geo-zone").count() == 2  # the barn and the mast
    assert page.locator(".geo-start[data-uav='alpha']").count() == 1

    plan_file = tmp_path / "alpha.plan"
    plan_file.write_text(json.dumps({"fileType": "Plan", "version": 1}))
    page.set_input_files("#geo-file", plan_file)
    page.locator("#geo-errors .field-error").wait_for()
    assert "mvo-gcs import" in page.inner_text("#geo-errors")
    assert not b.errors, b.errors
    assert not b.foreign, b.foreign
