"""Safety in metres (issue 26, item 3): over random areas, no-fly zones and fleets
anywhere on the Earth, no point of any planned trajectory, at any time, comes within R
of a no-fly zone or leaves the area (or comes within R of its edge), measured on WGS84
in metres around each zone and the area, independently of the grid: the trajectories
are sampled every 1/100 of a cell, taken to latitude and longitude by the grid's frame
and from there to metres by pymap3d; the zones and the area are projected from their
GeoJSON by shapely and pymap3d, not by the code under test."""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np
import pymap3d
import shapely
import shapely.ops
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gcs.mission.geographic import GeographicError, derive_file
from planner.pipeline import PlannerSettings, plan
from tests.geographic import clearance_m, densely, shape_in_metres, to_metres

EXAMPLES = 40
PLANNED_AT_LEAST = 0.6
"""Share of the generated instances that must be planned and checked, so that the
property cannot hold by skipping (starts in one cell, goals walled off, a plan the
small budget cannot find)."""
SETTINGS = PlannerSettings(time_budget_s=None, iterations=30, population=20, seed=3)


def _geodetic(east: np.ndarray, north: np.ndarray, lat0: float, lon0: float) -> np.ndarray:
    lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, lat0, lon0, 0.0)
    return np.column_stack([np.round(lon, 9), np.round(lat, 9)])


def _star(cx: float, cy: float, radii: list[float], turn: float) -> np.ndarray:
    """A simple polygon round (cx, cy): one vertex per radius at even angles."""
    angles = turn + np.linspace(0, 2 * math.pi, len(radii), endpoint=False)
    r = np.asarray(radii)
    return np.column_stack([cx + r * np.cos(angles), cy + r * np.sin(angles)])


@st.composite
def instances(draw: st.DrawFn) -> dict[str, Any]:
    """A geographic scenario: an area of 150-400 m with up to three zones (polygons or
    circles) and one to three UAVs whose starts and goals keep clear of the zones."""
    lat0 = draw(st.floats(-70, 70))
    lon0 = draw(st.floats(-179, 179))
    cell = draw(st.sampled_from([8.0, 10.0, 15.0]))
    margin = draw(st.floats(0.1, 2.0))
    radius = draw(st.floats(0.5, 0.45 * cell))
    half = draw(st.floats(75, 180)), draw(st.floats(75, 130))
    jitter = draw(st.lists(st.floats(0.75, 1.0), min_size=8, max_size=8))
    area_m = _star(0, 0, jitter, draw(st.floats(0, math.pi))) * np.array(half)
    features: list[dict[str, Any]] = [_polygon(area_m, lat0, lon0, role="area")]
    zones_m = []
    for _ in range(draw(st.integers(1, 4))):
        cx = draw(st.floats(-0.7, 0.7)) * half[0]
        cy = draw(st.floats(-0.7, 0.7)) * half[1]
        if draw(st.booleans()):
            r = draw(st.floats(8, 50))
            zones_m.append(shapely.Point(cx, cy).buffer(r))
            lon_lat = _geodetic(np.array([cx]), np.array([cy]), lat0, lon0)[0]
            features.append(_feature("Point", lon_lat.tolist(), role="no-fly", radius_m=r))
        else:
            k = draw(st.integers(3, 7))
            radii = draw(st.lists(st.floats(10, 60), min_size=k, max_size=k))
            ring = _star(cx, cy, radii, draw(st.floats(0, math.pi)))
            zones_m.append(shapely.Polygon(ring))
            features.append(_polygon(ring, lat0, lon0, role="no-fly"))
    # where a start or goal is sure of a free cell: R + margin + a cell's diagonal clear
    keep = radius + margin + 1.5 * cell
    free = shapely.Polygon(area_m).buffer(-keep)
    for zone in zones_m:
        free = free.difference(zone.buffer(keep))
    if free.is_empty:
        return {"skip": "no room", "features": features}
    x0, y0, x1, y1 = free.bounds
    for uav in range(draw(st.integers(1, 3))):
        for role in ("start", "goal"):
            u, v = draw(st.floats(0, 1)), draw(st.floats(0, 1))
            here = shapely.Point(x0 + u * (x1 - x0), y0 + v * (y1 - y0))
            if not free.contains(here):
                here = shapely.ops.nearest_points(free, here)[0]
            lon_lat = _geodetic(np.array([here.x]), np.array([here.y]), lat0, lon0)[0]
            properties = {"role": role, "uav": f"u{uav}", "radius_m": radius}
            features.append(_feature("Point", lon_lat.tolist(), **properties))
    return {
        "type": "FeatureCollection",
        "properties": {"cell_size_m": cell, "margin_m": margin},
        "features": features,
    }


def _feature(kind: str, coordinates: Any, **properties: Any) -> dict[str, Any]:
    return {
        "type": "Feature",
        "properties": properties,
        "geometry": {"type": kind, "coordinates": coordinates},
    }


def _polygon(ring_m: np.ndarray, lat0: float, lon0: float, **properties: Any) -> dict[str, Any]:
    ring = _geodetic(ring_m[:, 0], ring_m[:, 1], lat0, lon0).tolist()
    return _feature("Polygon", [[*ring, ring[0]]], **properties)


def _centre(geometry: dict[str, Any]) -> tuple[float, float]:
    """(lat, lon) of a zone's centre: the frame its distances are measured in."""
    lon, lat = shapely.geometry.shape(geometry).centroid.coords[0]
    return lat, lon


def test_no_planned_trajectory_comes_within_r_of_a_zone_or_leaves_the_area() -> None:
    outcomes: Counter[str] = Counter()
    closest: list[float] = []

    @settings(
        max_examples=EXAMPLES,
        deadline=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )
    @given(instances())
    def check(document: dict[str, Any]) -> None:
        if "skip" in document:
            outcomes["no room"] += 1
            return
        try:
            derived = derive_file(document)
        except GeographicError:
            outcomes["refused"] += 1  # starts in one cell, a goal walled off
            return
        result = plan(derived.scenario, SETTINGS)
        if not result.feasible:
            outcomes["not planned"] += 1
            return
        outcomes["planned"] += 1
        cell = derived.frame.cell_size_m
        radius_m = {u.id: u.radius * cell for u in derived.scenario.uavs}
        margin = document["properties"]["margin_m"]
        zones, area = [], None
        for f in document["features"]:
            role = f["properties"]["role"]
            if role == "area":
                area = f["geometry"]
            elif role == "no-fly":
                zones.append(f)
        assert area is not None
        for uav in result.uavs:
            grid = densely(np.asarray(uav.trajectory, dtype=float), 0.01)
            lat, lon = derived.frame.to_geodetic(grid[:, 1], grid[:, 2])
            r = radius_m[uav.id]
            for zone in zones:
                if zone["geometry"]["type"] == "Point":
                    lon0, lat0 = zone["geometry"]["coordinates"]
                    path = to_metres(lat, lon, lat0, lon0)
                    gap = float(np.hypot(*path.T).min()) - zone["properties"]["radius_m"]
                else:
                    lat0, lon0 = _centre(zone["geometry"])
                    shape = shape_in_metres(zone["geometry"], lat0, lon0)
                    gap = clearance_m(to_metres(lat, lon, lat0, lon0), shape)
                assert gap >= r, (uav.id, zone, gap, r)
                closest.append(gap - r - margin)
            lat0, lon0 = _centre(area)
            shape = shape_in_metres(area, lat0, lon0)
            path = to_metres(lat, lon, lat0, lon0)
            assert shapely.contains(shape, shapely.points(path)).all(), uav.id
            gap = clearance_m(path, shape.exterior)
            assert gap >= r, (uav.id, "area edge", gap, r)
            closest.append(gap - r - margin)

    check()
    total = sum(outcomes.values())
    assert outcomes["planned"] >= PLANNED_AT_LEAST * total, outcomes
    # and the margin the file asked for too (1 mm: the tangent plane's, and sampling)
    assert min(closest) >= -1e-3, min(closest)
