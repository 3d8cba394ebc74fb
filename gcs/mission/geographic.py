"""Geographic scenarios: an operating area, no-fly zones, starts and goals in WGS84 (a
GeoJSON FeatureCollection, RFC 7946) made into the planner's grid scenario.

The file (docs/planner.md, "Geographic scenarios"): one Polygon with `"role": "area"`;
Polygons or MultiPolygons with `"role": "no-fly"` (a Point with `"role": "no-fly"` and
`"radius_m"` is a circle); per UAV one Point with `"role": "start"` and one with
`"role": "goal"`, both with `"uav": "<id>"` (optional `"speed_m_s"`, `"radius_m"`); Points
with `"role": "rally"` are rally points (gcs/mission/fence.py), inside the area; the
collection's `properties` hold `"cell_size_m"` (and optionally `"name"`, `"margin_m"`,
`"alt_m"`).

The grid lies in the east-north tangent plane of its origin (`GridFrame`): the square
of cell (0, 0) has its south-west corner at the area's south-west corner, and the grid
covers the area. A cell is blocked when its square comes within R + margin of a no-fly
zone or of the area's edge (or leaves the area), R being the largest UAV radius: a UAV
whose centre stays inside free cells, as the planner's exact check keeps it (its disc
never enters a blocked square), then keeps R + margin from every zone and from the
area's edge, wherever in its cell it is. The margin (default 1 m) covers the tangent
plane's distortion, which is millimetres over the kilometres a grid spans.

RFC 7946 draws an edge between two positions as a straight line in longitude and
latitude; edges are therefore cut into pieces of at most `SEGMENT_DEG` degrees before
they are projected, so that a long diagonal edge keeps its shape in metres.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
import shapely
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator
from shapely.geometry.base import BaseGeometry
from shapely.validation import explain_validity

from gcs.mission.geodesy import MAX_EXTENT_M, GridFrame
from planner.model.plan import Plan
from planner.model.scenario import MAX_GRID_SIDE, MAX_UAVS, Grid, Origin, Scenario, UAVSpec

GEOJSON_MEDIA_TYPE = "application/geo+json"
DEFAULT_MARGIN_M = 1.0
"""Metres kept beyond R from every zone and from the area's edge, unless the file says."""
DEFAULT_RADIUS_CELLS = 0.3
"""A UAV's radius when its features give none: the planner's default, in cells."""
SEGMENT_DEG = 1e-4
"""Longest edge piece projected as a straight line: about 11 m; a straight edge in
longitude and latitude strays from the tangent plane's chord by well under a millimetre
over that."""
MAX_CUT_POINTS = 500_000
"""Most pieces the edges near the area are cut into (50 degrees of edges)."""
MAX_FEATURES = 2_000
MAX_RALLY_ALT_M = 32_767
"""A rally point's highest altitude above home: ArduPilot keeps it in an int16 of metres."""
MAX_VERTICES = 100_000

Number = Annotated[float, Field(strict=True)]
"""A JSON number: `true` is not 1 here, nor `"1"`."""
Longitude = Annotated[float, Field(strict=True, ge=-180, le=180)]
Latitude = Annotated[float, Field(strict=True, ge=-90, le=90)]
Position = tuple[Longitude, Latitude] | tuple[Longitude, Latitude, Number]
"""RFC 7946: longitude, latitude and an optional altitude (ignored: the grid is flat)."""


class GeographicError(ValueError):
    """The file cannot become a grid scenario; `feature` names the feature at fault
    (`features[3] (start of 'uav1')`), or is None when it is the file as a whole."""

    def __init__(self, feature: str | None, message: str) -> None:
        super().__init__(f"{feature}: {message}" if feature else message)
        self.feature = feature


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, allow_inf_nan=False)


def _ring(ring: list[Position]) -> list[Position]:
    if len(ring) < 4:
        raise ValueError("a linear ring has at least four positions (RFC 7946, 3.1.6)")
    if tuple(ring[0][:2]) != tuple(ring[-1][:2]):
        raise ValueError("a linear ring ends where it starts (RFC 7946, 3.1.6)")
    return ring


Ring = Annotated[list[Position], Field(max_length=MAX_VERTICES)]


class Point(_Model):
    type: Literal["Point"]
    coordinates: Position


class Polygon(_Model):
    type: Literal["Polygon"]
    coordinates: list[Ring] = Field(min_length=1, max_length=1_000)

    @field_validator("coordinates")
    @classmethod
    def _rings(cls, rings: list[list[Position]]) -> list[list[Position]]:
        return [_ring(r) for r in rings]


class MultiPolygon(_Model):
    type: Literal["MultiPolygon"]
    coordinates: list[list[Ring]] = Field(min_length=1, max_length=1_000)

    @field_validator("coordinates")
    @classmethod
    def _rings(cls, polygons: list[list[list[Position]]]) -> list[list[list[Position]]]:
        if any(not p for p in polygons):
            raise ValueError("a polygon has at least its exterior ring")
        return [[_ring(r) for r in p] for p in polygons]


class FeatureProperties(_Model):
    """What we read of a feature's properties; any others (a style, a label) are kept."""

    model_config = ConfigDict(extra="allow")
    role: Literal["area", "no-fly", "start", "goal", "rally"]
    uav: str | None = Field(
        default=None, min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.:-]+$"
    )
    name: str | None = Field(default=None, max_length=200)
    speed_m_s: Number | None = Field(default=None, gt=0, le=1_000)
    radius_m: Number | None = Field(default=None, gt=0, le=100_000)
    vehicle: str | None = Field(
        default=None,
        min_length=1,
        max_length=128,
        description="a start placed where this registered vehicle is when the file is "
        "posted (its geometry null): the service fills in the position",
    )


class Feature(_Model):
    model_config = ConfigDict(extra="allow")  # foreign members (RFC 7946, 6.1)
    type: Literal["Feature"]
    id: str | int | None = None
    geometry: Annotated[Point | Polygon | MultiPolygon, Field(discriminator="type")]
    properties: FeatureProperties


class CollectionProperties(_Model):
    model_config = ConfigDict(extra="allow")
    cell_size_m: Number = Field(gt=0, le=10_000, description="metres per grid cell")
    name: str = Field(default="geographic", max_length=200)
    margin_m: Number = Field(
        default=DEFAULT_MARGIN_M,
        ge=0,
        le=10_000,
        description="kept beyond R from every no-fly zone and from the area's edge",
    )
    alt_m: Number = Field(
        default=0.0, ge=-500, le=9_000, description="ground altitude, metres above MSL"
    )


class GeographicScenario(_Model):
    """The file: a GeoJSON FeatureCollection (RFC 7946, WGS84)."""

    model_config = ConfigDict(extra="allow")
    type: Literal["FeatureCollection"]
    features: list[Feature] = Field(max_length=MAX_FEATURES)
    properties: CollectionProperties


def is_geojson(content_type: str | None) -> bool:
    """Whether a Content-Type names GeoJSON (`application/geo+json`, any parameters)."""
    return (content_type or "").split(";")[0].strip().lower() == GEOJSON_MEDIA_TYPE


def looks_geographic(data: Any) -> bool:
    return isinstance(data, dict) and data.get("type") == "FeatureCollection"


def load_geographic(data: dict[str, Any] | str | bytes) -> GeographicScenario:
    """The file from a dict or JSON text (pydantic.ValidationError if it is malformed)."""
    if isinstance(data, str | bytes):
        return GeographicScenario.model_validate_json(data)
    return GeographicScenario.model_validate(data)


@dataclass(frozen=True)
class DerivedScenario:
    """A geographic scenario made into a grid."""

    scenario: Scenario
    frame: GridFrame
    clearance_m: float
    """R + margin: how far every free cell's square keeps from zones and the area's edge."""


@dataclass(frozen=True)
class _Zone:
    where: str
    shape: BaseGeometry  # in cells
    radius: float = 0.0  # cells: a circle is its centre and this radius


@dataclass
class _Ends:
    start: tuple[int, Point, FeatureProperties] | None = None
    goal: tuple[int, Point, FeatureProperties] | None = None


def _where(index: int, p: FeatureProperties) -> str:
    label = {"area": "the area", "no-fly": "no-fly zone", "rally": "rally point"}.get(
        p.role, f"{p.role} of {p.uav!r}"
    )
    if p.name:
        label += f" {p.name!r}"
    return f"features[{index}] ({label})"


def derive(source: GeographicScenario) -> DerivedScenario:
    """The grid scenario of a geographic one; GeographicError naming the feature if the
    file describes nothing plannable."""
    cell = source.properties.cell_size_m
    areas: list[tuple[str, Polygon]] = []
    zones_in: list[tuple[str, Feature]] = []
    rally: list[tuple[str, Point]] = []
    ends: dict[str, _Ends] = {}
    for i, feature in enumerate(source.features):
        where, role, geometry = (
            _where(i, feature.properties),
            feature.properties.role,
            feature.geometry,
        )
        if role == "area":
            if not isinstance(geometry, Polygon):
                raise GeographicError(where, f"the area is a Polygon, not a {geometry.type}")
            areas.append((where, geometry))
        elif role == "no-fly":
            if isinstance(geometry, Point) and feature.properties.radius_m is None:
                raise GeographicError(where, "a Point no-fly zone needs its 'radius_m'")
            zones_in.append((where, feature))
        elif role == "rally":
            if not isinstance(geometry, Point):
                raise GeographicError(where, f"a rally point is a Point, not a {geometry.type}")
            rally.append((where, geometry))
        else:
            _add_end(ends, i, where, feature)
    if not areas:
        raise GeographicError(None, 'no feature has "role": "area": the operating area')
    if len(areas) > 1:
        raise GeographicError(areas[1][0], f"a second area ({areas[0][0]} is the first)")
    area_where, area_in = areas[0]
    for where, geometry in [(area_where, area_in)] + [(w, f.geometry) for w, f in zones_in]:
        _check_valid(where, geometry)
    if not ends:
        raise GeographicError(None, 'no UAV: give each a Point with "role": "start"')
    if len(ends) > MAX_UAVS:
        raise GeographicError(None, f"{len(ends)} UAVs: at most {MAX_UAVS} are planned")

    uavs = _uav_properties(ends, cell)
    radius_m = max(r for _, r, _ in uavs.values()) * cell
    clearance_m = radius_m + source.properties.margin_m
    frame = _frame(area_where, area_in, source.properties)
    _grid_size(area_where, _in_cells(frame, _shape(area_in, cut=False)), cell)  # before cutting
    area = _in_cells(frame, _shape(area_in, where=area_where))
    width, height = _grid_size(area_where, area, cell)
    window = _window(area_in, clearance_m + 2 * cell)
    zones = [_zone(frame, where, feature, cell, window) for where, feature in zones_in]
    zones = [z for z in zones if not z.shape.is_empty]
    blocked, why = _blocked(area, zones, width, height, clearance_m / cell)
    for where, point in rally:
        _check_rally(where, point, frame, area, zones)

    specs: list[UAVSpec] = []
    for uav, (speed, radius, (start, goal)) in uavs.items():
        cells = []
        for end, (index, point, _) in (("start", start), ("goal", goal)):
            where = _where(index, source.features[index].properties)
            cells.append(
                _end_cell(where, end, point, frame, area, zones, blocked, why, clearance_m / cell)
            )
        specs.append(
            UAVSpec(id=uav, start=cells[0], goal=cells[1], speed=speed / cell, radius=radius)
        )
    obstacles = [(int(x), int(y)) for x, y in np.argwhere(blocked)]
    try:
        scenario = Scenario(
            name=source.properties.name,
            grid=Grid(width=width, height=height, cell_size_m=cell),
            origin=Origin(lat=frame.lat0, lon=frame.lon0, alt_m=frame.alt0),
            uavs=specs,
            obstacles=obstacles,
        )
    except ValidationError as exc:
        raise GeographicError(None, _grid_refusal(exc, source, ends)) from None
    return DerivedScenario(scenario, frame, clearance_m)


def derive_file(data: dict[str, Any] | str | bytes) -> DerivedScenario:
    if isinstance(data, dict) and (unplaced := vehicle_starts(data)):
        where, vehicle = unplaced[0][1:]
        raise GeographicError(
            where,
            f"starts where vehicle {vehicle!r} is now: only the service that reaches it "
            "can place it (POST /scenarios)",
        )
    return derive(load_geographic(data))


def vehicle_starts(data: Any) -> list[tuple[int, str, str]]:
    """The starts still to be placed where a vehicle is (`"vehicle"` given, geometry
    null), as (feature index, where, vehicle id), in the raw file before it is read."""
    features = data.get("features") if isinstance(data, dict) else None
    found = []
    for index, feature in enumerate(features if isinstance(features, list) else []):
        properties = feature.get("properties") if isinstance(feature, dict) else None
        if not isinstance(properties, dict) or feature.get("geometry") is not None:
            continue
        vehicle, uav = properties.get("vehicle"), properties.get("uav")
        if properties.get("role") == "start" and isinstance(vehicle, str) and vehicle:
            found.append((index, f"features[{index}] (start of {uav!r})", vehicle))
    return found


def placed_at(data: dict[str, Any], index: int, lat: float, lon: float) -> dict[str, Any]:
    """A copy of the file with feature `index` a Point at (lat, lon)."""
    features = list(data["features"])
    point = {"type": "Point", "coordinates": [round(lon, 7), round(lat, 7)]}
    features[index] = {**features[index], "geometry": point}
    return {**data, "features": features}


def _add_end(ends: dict[str, _Ends], index: int, where: str, feature: Feature) -> None:
    p = feature.properties
    if not isinstance(feature.geometry, Point):
        raise GeographicError(where, f"a {p.role} is a Point, not a {feature.geometry.type}")
    if p.uav is None:
        raise GeographicError(where, f'a {p.role} names its UAV: "uav": "<id>"')
    entry = ends.setdefault(p.uav, _Ends())
    role: Literal["start", "goal"] = "start" if p.role == "start" else "goal"
    earlier = getattr(entry, role)
    if earlier is not None:
        raise GeographicError(where, f"UAV {p.uav!r} already has a {role}: features[{earlier[0]}]")
    setattr(entry, role, (index, feature.geometry, p))


Pair = tuple[tuple[int, Point, FeatureProperties], tuple[int, Point, FeatureProperties]]


def _uav_properties(ends: dict[str, _Ends], cell: float) -> dict[str, tuple[float, float, Pair]]:
    """Per UAV: speed (m/s), radius (cells) and its start and goal features."""
    out: dict[str, tuple[float, float, Pair]] = {}
    for uav, entry in ends.items():
        for missing, other in (("goal", entry.start), ("start", entry.goal)):
            if getattr(entry, missing) is None and other is not None:
                raise GeographicError(
                    _where(other[0], other[2]),
                    f"UAV {uav!r} has no {missing}: a Point with "
                    f'"role": "{missing}", "uav": "{uav}"',
                )
        assert entry.start is not None and entry.goal is not None
        values: dict[str, float] = {}
        for key in ("speed_m_s", "radius_m"):
            given = {i: getattr(p, key) for i, _, p in (entry.start, entry.goal)}
            found = {v for v in given.values() if v is not None}
            if len(found) > 1:
                raise GeographicError(
                    _where(entry.goal[0], entry.goal[2]),
                    f"{key} of UAV {uav!r} differs from its start's (features[{entry.start[0]}])",
                )
            if found:
                values[key] = found.pop()
        radius = values.get("radius_m", DEFAULT_RADIUS_CELLS * cell) / cell
        if radius >= 0.5:
            raise GeographicError(
                _where(entry.start[0], entry.start[2]),
                f"radius_m {radius * cell:g} of UAV {uav!r} is not below half a cell "
                f"({cell / 2:g} m): a UAV must fit in its cell; use larger cells",
            )
        out[uav] = (values.get("speed_m_s", cell), radius, (entry.start, entry.goal))
    return out


def _shape(
    geometry: Polygon | MultiPolygon,
    cut: bool = True,
    where: str = "",
    window: BaseGeometry | None = None,
) -> BaseGeometry:
    """The geometry in longitude and latitude, its edges cut into SEGMENT_DEG pieces
    (unless `cut` is False: a vertex where two edges cross would hide the crossing),
    and only what lies in `window` (a valid geometry's part near the area: an edge is
    straight in longitude and latitude, so the clipping is exact)."""

    def polygon(rings: list[list[Position]]) -> shapely.Polygon:
        return shapely.Polygon([p[:2] for p in rings[0]], [[p[:2] for p in r] for r in rings[1:]])

    if isinstance(geometry, Polygon):
        shape: BaseGeometry = polygon(geometry.coordinates)
    else:
        shape = shapely.MultiPolygon([polygon(p) for p in geometry.coordinates])
    if window is not None:
        shape = shape.intersection(window)
    if not cut:
        return shape
    if shape.length / SEGMENT_DEG > MAX_CUT_POINTS:
        raise GeographicError(
            where,
            f"edges {shape.length:.2f} degrees long in all: more than "
            f"{MAX_CUT_POINTS * SEGMENT_DEG:g} degrees near the area is too detailed to grid",
        )
    return shapely.segmentize(shape, SEGMENT_DEG)


def _check_valid(where: str, geometry: Point | Polygon | MultiPolygon) -> None:
    if isinstance(geometry, Point):
        return
    try:
        shape = _shape(geometry, cut=False)
        valid = shape.is_valid
    except (shapely.errors.GEOSException, ValueError) as exc:
        raise GeographicError(where, f"not a valid {geometry.type}: {exc}") from None
    if not valid:
        # explain_validity names the problem and where, e.g. "Self-intersection[149.1 -35.3]"
        raise GeographicError(
            where, f"not a valid {geometry.type} (OGC simple features): {explain_validity(shape)}"
        )
    if shape.area == 0:
        raise GeographicError(where, f"the {geometry.type} encloses nothing")


def _frame(where: str, area: Polygon, properties: CollectionProperties) -> GridFrame:
    """The grid's frame: cell (0, 0) is centred half a cell east and north of the area's
    south-west corner in the frame's own tangent plane (found in a few steps, since the
    plane turns a little with its origin)."""
    lon, lat = np.array([p[:2] for p in area.coordinates[0]], dtype=float).T
    if lon.max() - lon.min() > 180:
        raise GeographicError(where, "the area crosses the antimeridian or spans half the Earth")
    cell = properties.cell_size_m
    frame = GridFrame(float(lat.min()), float(lon.min()), properties.alt_m, cell)
    for _ in range(6):
        x, y = frame.to_cells(lat, lon)
        dx, dy = float(x.min()) + 0.5, float(y.min()) + 0.5
        lat0, lon0 = frame.to_geodetic(dx, dy)
        frame = GridFrame(float(lat0), float(lon0), properties.alt_m, cell)
        if math.hypot(dx, dy) < 1e-9:
            break
    return frame


def _in_cells(frame: GridFrame, shape: BaseGeometry) -> BaseGeometry:
    def project(coords: np.ndarray) -> np.ndarray:
        x, y = frame.to_cells(coords[:, 1], coords[:, 0])
        return np.column_stack([x, y])

    return shapely.transform(shape, project)


def _grid_size(where: str, area: BaseGeometry, cell: float) -> tuple[int, int]:
    x0, y0, x1, y1 = area.bounds
    width = max(1, math.ceil(x1 + 0.5 - 1e-3))  # 1e-3: a sliver outside is of no use
    height = max(1, math.ceil(y1 + 0.5 - 1e-3))
    across_m = (x1 - x0) * cell, (y1 - y0) * cell
    if width > MAX_GRID_SIDE or height > MAX_GRID_SIDE:
        need = max(across_m) / (MAX_GRID_SIDE - 1)  # a cell's slack on each side
        raise GeographicError(
            where,
            f"the area is {across_m[0]:.0f} m x {across_m[1]:.0f} m: {width} x {height} cells "
            f"of {cell:g} m, more than the planner's {MAX_GRID_SIDE} x {MAX_GRID_SIDE}; use "
            f"cells of at least {math.ceil(need * 100) / 100:g} m or a smaller area",
        )
    if max(width, height) * cell > MAX_EXTENT_M:
        raise GeographicError(
            where,
            f"the area spans {max(across_m) / 1000:.0f} km: a flat grid is flown only up "
            f"to {MAX_EXTENT_M / 1000:.0f} km across",
        )
    return width, height


def _window(area: Polygon, metres: float) -> BaseGeometry:
    """The area's bounds in longitude and latitude, grown by at least `metres` (twice
    that at the equator): no zone further from the area can block one of its cells."""
    lon, lat = np.array([p[:2] for p in area.coordinates[0]], dtype=float).T
    pad_lat = 2 * metres / 110_000
    pad_lon = pad_lat / max(math.cos(math.radians(float(np.abs(lat).max()))), 1e-3)
    return shapely.box(
        lon.min() - pad_lon, lat.min() - pad_lat, lon.max() + pad_lon, lat.max() + pad_lat
    )


def _zone(
    frame: GridFrame, where: str, feature: Feature, cell: float, window: BaseGeometry
) -> _Zone:
    geometry = feature.geometry
    if isinstance(geometry, Point):
        lon, lat = geometry.coordinates[:2]
        x, y = frame.to_cells(lat, lon)
        radius = (feature.properties.radius_m or 0.0) / cell
        return _Zone(where, shapely.Point(float(x), float(y)), radius)
    return _Zone(where, _in_cells(frame, _shape(geometry, where=where, window=window)))


def _blocked(
    area: BaseGeometry, zones: list[_Zone], width: int, height: int, clearance: float
) -> tuple[np.ndarray, np.ndarray]:
    """Blocked cells indexed [x, y], and why each is (-1: the area, k: zones[k])."""
    xs, ys = np.meshgrid(np.arange(width), np.arange(height), indexing="ij")
    boxes = shapely.box(xs - 0.5, ys - 0.5, xs + 0.5, ys + 0.5)
    why = np.full((width, height), -2, dtype=int)
    shapely.prepare(area)
    edge = area.boundary
    shapely.prepare(edge)
    # the prepared geometry first: shapely prepares only the first argument's
    out = ~shapely.contains(area, boxes) | shapely.dwithin(edge, boxes, clearance)
    why[out] = -1
    for k, zone in enumerate(zones):
        shapely.prepare(zone.shape)
        near = shapely.dwithin(zone.shape, boxes, zone.radius + clearance)
        why[near & (why == -2)] = k
    return why != -2, why


def _end_cell(
    where: str,
    end: str,
    point: Point,
    frame: GridFrame,
    area: BaseGeometry,
    zones: list[_Zone],
    blocked: np.ndarray,
    why: np.ndarray,
    clearance: float,
) -> tuple[int, int]:
    lon, lat = point.coordinates[:2]
    x, y = (float(v) for v in frame.to_cells(lat, lon))
    here = shapely.Point(x, y)
    cell_m = frame.cell_size_m
    if not area.covers(here):
        raise GeographicError(where, f"the {end} lies outside the area")
    for zone in zones:
        gap = (zone.shape.distance(here) - zone.radius) * cell_m
        if gap <= 0:
            raise GeographicError(where, f"the {end} lies inside no-fly zone {zone.where}")
        if gap < clearance * cell_m:
            raise GeographicError(
                where,
                f"the {end} is {gap:.1f} m from no-fly zone {zone.where}: closer than "
                f"R + margin = {clearance * cell_m:.1f} m",
            )
    cx, cy = round(x), round(y)
    if not (0 <= cx < blocked.shape[0] and 0 <= cy < blocked.shape[1]) or blocked[cx, cy]:
        reason = (
            "the area's edge"
            if not (0 <= cx < blocked.shape[0] and 0 <= cy < blocked.shape[1]) or why[cx, cy] < 0
            else f"no-fly zone {zones[why[cx, cy]].where}"
        )
        raise GeographicError(
            where,
            f"the {end}'s cell ({cx}, {cy}) is blocked: its square comes within R + margin "
            f"= {clearance * cell_m:.1f} m of {reason}; move the {end} or use smaller cells",
        )
    return cx, cy


def _check_rally(
    where: str, point: Point, frame: GridFrame, area: BaseGeometry, zones: list[_Zone]
) -> None:
    """A rally point lies in the area and outside every zone: the vehicle's fence would
    otherwise keep it from the point it returns to."""
    lon, lat = point.coordinates[:2]
    if len(point.coordinates) == 3 and not 0 <= point.coordinates[2] <= MAX_RALLY_ALT_M:
        raise GeographicError(
            where, f"a rally point's altitude is 0 to {MAX_RALLY_ALT_M} m above home"
        )
    x, y = (float(v) for v in frame.to_cells(lat, lon))
    here = shapely.Point(x, y)
    if not area.covers(here):
        raise GeographicError(where, "the rally point lies outside the area")
    for zone in zones:
        if zone.shape.distance(here) <= zone.radius:
            raise GeographicError(where, f"the rally point lies inside no-fly zone {zone.where}")


def _grid_refusal(exc: ValidationError, source: GeographicScenario, ends: dict[str, _Ends]) -> str:
    """The grid scenario's refusal, its `uavs[i].start` named as the file's features."""
    features = [
        {
            "start": _where(e.start[0], e.start[2]) if e.start else "",
            "goal": _where(e.goal[0], e.goal[2]) if e.goal else "",
        }
        for e in ends.values()
    ]

    def name(match: re.Match[str]) -> str:
        i, end = int(match.group(1)), match.group(2) or "start"
        return features[i][end] if i < len(features) else match.group(0)

    messages = [e["msg"].removeprefix("Value error, ") for e in exc.errors()]
    text = "; ".join(re.sub(r"uavs\[(\d+)\](?:\.(start|goal))?", name, m) for m in messages)
    return f"the derived grid cannot be planned: {text}"


def wgs84_trajectories(frame: GridFrame, plan: Plan) -> dict[str, list[list[float]]]:
    """Each UAV's trajectory as `[t, lat, lon]` points (degrees, 8 decimals: about 1 mm)."""
    out: dict[str, list[list[float]]] = {}
    for uav in plan.uavs:
        points = np.asarray(uav.trajectory, dtype=float).reshape(-1, 3)
        lat, lon = frame.to_geodetic(points[:, 1], points[:, 2])
        rows = np.column_stack([points[:, 0], np.round(lat, 8), np.round(lon, 8)])
        out[uav.id] = rows.tolist()
    return out


def frame_of(grid: Grid, origin: Origin | None) -> GridFrame | None:
    """A scenario's frame from its grid and origin; None without an origin or beyond
    the span a flat grid is flown over."""
    if origin is None or max(grid.width, grid.height) * grid.cell_size_m > MAX_EXTENT_M:
        return None
    return GridFrame(origin.lat, origin.lon, origin.alt_m, grid.cell_size_m)


def geojson_schema() -> dict[str, Any]:
    """The file's JSON schema with its definitions inlined (for an OpenAPI document)."""
    schema = GeographicScenario.model_json_schema()
    defs = schema.pop("$defs", {})

    def inline(node: Any) -> Any:
        if isinstance(node, dict):
            ref = node.get("$ref")
            if isinstance(ref, str) and ref.startswith("#/$defs/"):
                return inline(defs[ref.removeprefix("#/$defs/")])
            # a discriminator's mapping names $defs; the `type` constants say it all
            return {k: inline(v) for k, v in node.items() if k != "discriminator"}
        if isinstance(node, list):
            return [inline(v) for v in node]
        return node

    return dict(inline(schema))
