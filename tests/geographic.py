"""Geographic scenarios for tests, drawn in metres east and north of a base point and
written in WGS84 as the file format says (docs/planner.md, "Geographic scenarios"), and
an independent measure of a trajectory's clearance in metres (shapely + pymap3d, never
the grid)."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pymap3d
import shapely

BASE = (-35.363262, 149.165237)
"""ArduPilot SITL's home (lat, lon): where the examples are."""
EXAMPLE = Path(__file__).parent.parent / "docs/examples/field-with-no-fly-zones.geojson"
Metres = Sequence[tuple[float, float]]


def lon_lat(east: float, north: float) -> list[float]:
    lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, *BASE, 0.0)
    return [round(float(lon), 9), round(float(lat), 9)]


def ring(points: Metres) -> list[list[float]]:
    coords = [lon_lat(e, n) for e, n in points]
    return [*coords, coords[0]]


def rectangle(e0: float, n0: float, e1: float, n1: float) -> list[list[list[float]]]:
    return [ring([(e0, n0), (e1, n0), (e1, n1), (e0, n1)])]


def feature(geometry: dict[str, Any], **properties: Any) -> dict[str, Any]:
    return {"type": "Feature", "properties": properties, "geometry": geometry}


def polygon(rings: list[list[list[float]]], **properties: Any) -> dict[str, Any]:
    return feature({"type": "Polygon", "coordinates": rings}, **properties)


def point(east: float, north: float, **properties: Any) -> dict[str, Any]:
    return feature({"type": "Point", "coordinates": lon_lat(east, north)}, **properties)


def collection(features: list[dict[str, Any]], **properties: Any) -> dict[str, Any]:
    return {
        "type": "FeatureCollection",
        "properties": {"cell_size_m": 10.0, **properties},
        "features": features,
    }


def field(
    uavs: Sequence[tuple[str, tuple[float, float], tuple[float, float]]] = (
        ("a", (25, 25), (275, 175)),
    ),
    zones: Sequence[dict[str, Any]] = (),
    **properties: Any,
) -> dict[str, Any]:
    """A 300 m x 200 m area with the given zones and UAVs (start and goal in metres)."""
    features = [polygon(rectangle(0, 0, 300, 200), role="area", name="field"), *zones]
    for uav, start, goal in uavs:
        features += [point(*start, role="start", uav=uav), point(*goal, role="goal", uav=uav)]
    return collection(features, **properties)


def properties_of(data: dict[str, Any], role: str, uav: str | None = None) -> dict[str, Any]:
    """The properties of the first feature with this role (and UAV)."""
    return next(
        f["properties"]
        for f in data["features"]
        if f["properties"].get("role") == role and (uav is None or f["properties"]["uav"] == uav)
    )


def shape_in_metres(geometry: dict[str, Any], lat0: float, lon0: float) -> shapely.Geometry:
    """A GeoJSON Polygon or MultiPolygon (or a Point with a radius, given as a Polygon's
    centre by the caller) as east-north metres around (lat0, lon0); edges are straight in
    longitude and latitude (RFC 7946), so they are cut finely before projecting."""
    shape = shapely.segmentize(shapely.geometry.shape(geometry), 2e-5)

    def project(coords: np.ndarray) -> np.ndarray:
        east, north, _ = pymap3d.geodetic2enu(coords[:, 1], coords[:, 0], 0.0, lat0, lon0, 0.0)
        return np.column_stack([east, north])

    return shapely.transform(shape, project)


def to_metres(lat: np.ndarray, lon: np.ndarray, lat0: float, lon0: float) -> np.ndarray:
    """East-north metres, shape (n, 2), around (lat0, lon0)."""
    east, north, _ = pymap3d.geodetic2enu(lat, lon, 0.0, lat0, lon0, 0.0)
    return np.column_stack([np.ravel(east), np.ravel(north)])


def densely(points: np.ndarray, step: float) -> np.ndarray:
    """A piecewise-linear path's points (rows; time or position columns alike) sampled
    at most `step` apart along its last two columns, every vertex kept."""
    out = [points[:1]]
    for a, b in itertools.pairwise(points):
        steps = max(1, int(np.ceil(np.hypot(*(b[-2:] - a[-2:])) / step)))
        s = np.linspace(0, 1, steps + 1)[1:, None]
        out.append(a + s * (b - a))
    return np.concatenate(out)


def clearance_m(path_m: np.ndarray, shape_m: shapely.Geometry) -> float:
    """The least distance in metres of any point of a sampled path from a shape."""
    return float(shapely.distance(shapely.points(path_m), shape_m).min())


# ---------------------------------------------------------------- QGroundControl .plan


def lat_lon(east: float, north: float) -> list[float]:
    lon, lat = lon_lat(east, north)
    return [lat, lon]


def qgc_plan(
    home: tuple[float, float],
    goal: tuple[float, float],
    *,
    fence: bool = True,
    cruise: float = 4.0,
) -> dict[str, Any]:
    """A `.plan` as QGroundControl saves one: takeoff, a waypoint, the goal, land there;
    its fence a 300 x 200 m area with a barn and a mast, one rally point."""
    items = [
        {"command": 22, "frame": 3, "params": [0, 0, 0, None, 0, 0, 20]},
        {"command": 16, "frame": 3, "params": [0, 0, 0, None, *lat_lon(150, 20), 20]},
        {"command": 16, "frame": 3, "params": [0, 0, 0, None, *lat_lon(*goal), 20]},
        {"command": 21, "frame": 3, "params": [0, 0, 0, None, 0, 0, 0]},
    ]
    geo_fence: dict[str, Any] = {"version": 2, "circles": [], "polygons": []}
    if fence:
        area = [lat_lon(0, 0), lat_lon(300, 0), lat_lon(300, 200), lat_lon(0, 200)]
        barn = [lat_lon(120, 60), lat_lon(180, 60), lat_lon(180, 140), lat_lon(120, 140)]
        geo_fence["polygons"] = [
            {"inclusion": True, "polygon": area, "version": 1},
            {"inclusion": False, "polygon": barn, "version": 1},
        ]
        mast = {"center": lat_lon(60, 150), "radius": 15}
        geo_fence["circles"] = [{"circle": mast, "inclusion": False, "version": 1}]
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "QGroundControl",
        "geoFence": geo_fence,
        "rallyPoints": {"version": 2, "points": [[*lat_lon(20, 180), 30]] if fence else []},
        "mission": {
            "version": 2,
            "firmwareType": 3,
            "vehicleType": 2,
            "cruiseSpeed": cruise,
            "hoverSpeed": 5,
            "globalPlanAltitudeMode": 1,
            "plannedHomePosition": [*lat_lon(*home), 584],
            "items": [
                {"type": "SimpleItem", "autoContinue": True, "doJumpId": k + 1, **item}
                for k, item in enumerate(items)
            ],
        },
    }


# ---------------------------------------------------------------- KML, as Google Earth writes it


def placemark(name: str, geometry: str, **data: Any) -> str:
    extended = "".join(f'<Data name="{k}"><value>{v}</value></Data>' for k, v in data.items())
    extended = f"<ExtendedData>{extended}</ExtendedData>" if data else ""
    return f"<Placemark><name>{name}</name>{extended}{geometry}</Placemark>"


def kml_polygon(*rings: Metres) -> str:
    def coordinates(points: Metres) -> str:
        closed = [*points, points[0]]
        return " ".join(",".join(str(c) for c in lon_lat(e, n)) for e, n in closed)

    outer, *inner = rings
    holes = "".join(
        f"<innerBoundaryIs><LinearRing><coordinates>{coordinates(r)}</coordinates>"
        "</LinearRing></innerBoundaryIs>"
        for r in inner
    )
    return (
        f"<Polygon><outerBoundaryIs><LinearRing><coordinates>{coordinates(outer)}"
        f"</coordinates></LinearRing></outerBoundaryIs>{holes}</Polygon>"
    )


def kml_point(east: float, north: float) -> str:
    coordinates = ",".join(str(c) for c in lon_lat(east, north))
    return f"<Point><coordinates>{coordinates}</coordinates></Point>"


def kml(*placemarks: str, cell: float | None = 10.0) -> str:
    """A KML document of placemarks in one folder, the cell size in its ExtendedData."""
    data = (
        f'<ExtendedData><Data name="cell_size_m"><value>{cell}</value></Data></ExtendedData>'
        if cell
        else ""
    )
    return (
        '<?xml version="1.0" encoding="UTF-8"?><kml xmlns="http://www.opengis.net/kml/2.2">'
        f"<Document><name>yard</name>{data}<Folder><name>plan</name>"
        f"{''.join(placemarks)}</Folder></Document></kml>"
    )


SQUARE = [(0, 0), (300, 0), (300, 200), (0, 200)]
YARD_KML = [
    # a 300 x 200 m yard: its area, a barn, a mast, one UAV's start and goal, a rally point
    placemark("area", kml_polygon(SQUARE)),
    placemark("barn", kml_polygon([(120, 60), (180, 60), (180, 140), (120, 140)]), role="no-fly"),
    placemark("no-fly mast", kml_point(60, 150), radius_m=15),
    placemark("start alpha", kml_point(25, 25), speed_m_s=4),
    placemark("goal alpha", kml_point(275, 175)),
    placemark("rally", kml_point(20, 180)),
]
