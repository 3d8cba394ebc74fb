"""Geographic scenarios from the files operators already have: QGroundControl `.plan`
files and KML (Google Earth, most GIS tools). Each is made into the geographic scenario's
GeoJSON (docs/planner.md, "Geographic scenarios"), which `geographic.derive` then checks
and grids like any other, so there is one set of rules and one set of errors.

`.plan` (QGroundControl's format, one vehicle per file): the fence is the scenario's
geometry: the one inclusion polygon or circle is the area, exclusion polygons and circles
are no-fly zones, rally points stay rally points. The vehicle starts at the planned home
position and its goal is the mission's last item with a position; its cruise speed, when
the file sets one, is its speed. A fleet is several files, one per UAV: their fences and
rally points are merged (the same fence in every file counts once).

KML: Placemarks anywhere in the document (folders included). A placemark's role and UAV
come from its `ExtendedData` (`role`, `uav`, `radius_m`, `speed_m_s`) or else from its
name: `area`, `no-fly ...`, `start uav1`, `goal uav1`, `rally ...`; the document's
`ExtendedData` may hold `cell_size_m`, `margin_m` and `alt_m`. A no-fly Point needs a
`radius_m`. Documents with a DOCTYPE are refused before fastkml parses them: entities
are how XML bombs and external-file reads get in, and KML needs none.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pymap3d
from lxml import etree

from gcs.mavlink.mission_item import Autopilot, MissionItem
from gcs.mission.files import MissionFileError, parse_plan
from gcs.mission.geographic import GeographicError

if TYPE_CHECKING:
    from fastkml.features import Placemark

KML_MEDIA_TYPE = "application/vnd.google-earth.kml+xml"
CIRCLE_SIDES = 64
"""An inclusion circle becomes the polygon of this many sides inscribed in it: inside the
circle everywhere, so the area never grows, and within 0.12 % of its radius."""
_ROLES = ("area", "no-fly", "start", "goal", "rally")
_KML_NUMBERS = ("radius_m", "speed_m_s")
_KML_DOCUMENT_NUMBERS = ("cell_size_m", "margin_m", "alt_m")
_GLOBAL_FRAMES = {0, 3, 5, 6, 10, 11}  # MAV_FRAME_GLOBAL* (int and float variants)

Feature = dict[str, Any]


def _collection(features: list[Feature], properties: dict[str, Any]) -> dict[str, Any]:
    return {"type": "FeatureCollection", "features": features, "properties": properties}


def _point(lon: float, lat: float, **properties: Any) -> Feature:
    geometry = {"type": "Point", "coordinates": [lon, lat]}
    return {"type": "Feature", "geometry": geometry, "properties": properties}


# ---------------------------------------------------------------- QGroundControl .plan


def from_plan_files(
    paths: list[Path], cell_size_m: float, name: str | None = None
) -> dict[str, Any]:
    """The geographic scenario of `.plan` files, one UAV per file, named by the file's stem."""
    documents: dict[str, Any] = {}
    for path in paths:
        try:
            documents[path.stem] = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise GeographicError(path.name, f"cannot read a .plan file: {exc}") from None
    return from_plans(documents, cell_size_m, name)


def from_plans(
    documents: Mapping[str, Any], cell_size_m: float, name: str | None = None
) -> dict[str, Any]:
    """The geographic scenario of `.plan` documents keyed by UAV id (see the module)."""
    if not documents:
        raise GeographicError(None, "no .plan file given")
    fences: list[Feature] = []
    ends: list[Feature] = []
    for uav, document in documents.items():
        for feature in _plan_fence(uav, document) + _plan_rally(uav, document):
            if feature not in fences:  # the same fence in every file counts once
                fences.append(feature)
        ends += _plan_ends(uav, document)
    areas = [f for f in fences if f["properties"]["role"] == "area"]
    if len(areas) != 1:
        raise GeographicError(
            "geoFence",
            f"the area is one inclusion polygon or circle; the files hold {len(areas)}",
        )
    properties = {"cell_size_m": cell_size_m, "name": name or "-".join(documents)}
    return _collection(fences + ends, properties)


def _plan_fence(uav: str, document: Any) -> list[Feature]:
    fence = _field(document, "geoFence", dict, uav, default={})
    features = []
    for k, polygon in enumerate(_field(fence, "polygons", list, uav, default=[])):
        where = f"{uav}: geoFence.polygons[{k}]"
        vertices = [_lat_lon(v, where) for v in _field(polygon, "polygon", list, where)]
        if len(vertices) < 3:
            raise GeographicError(where, "a fence polygon has at least three vertices")
        ring = [[lon, lat] for lat, lon in vertices + vertices[:1]]
        role = "area" if _field(polygon, "inclusion", bool, where) else "no-fly"
        geometry = {"type": "Polygon", "coordinates": [ring]}
        features.append({"type": "Feature", "geometry": geometry, "properties": {"role": role}})
    for k, circle in enumerate(_field(fence, "circles", list, uav, default=[])):
        where = f"{uav}: geoFence.circles[{k}]"
        shape = _field(circle, "circle", dict, where)
        lat, lon = _lat_lon(_field(shape, "center", list, where), where)
        radius = _field(shape, "radius", float, where)
        if not radius > 0:
            raise GeographicError(where, f"radius must be positive, got {radius}")
        if _field(circle, "inclusion", bool, where):
            features.append(_circle_area(lat, lon, radius))
        else:
            features.append(_point(lon, lat, role="no-fly", radius_m=radius))
    return features


def _circle_area(lat: float, lon: float, radius: float) -> Feature:
    """An inclusion circle as the polygon inscribed in it, on the ellipsoid (pymap3d)."""
    angles = 2 * math.pi * np.arange(CIRCLE_SIDES) / CIRCLE_SIDES
    east, north = radius * np.cos(angles), radius * np.sin(angles)
    lats, lons, _ = pymap3d.enu2geodetic(east, north, 0.0, lat, lon, 0.0)
    ring = [[float(x), float(y)] for x, y in zip(lons, lats, strict=True)]
    geometry = {"type": "Polygon", "coordinates": [ring + ring[:1]]}
    return {"type": "Feature", "geometry": geometry, "properties": {"role": "area"}}


def _plan_rally(uav: str, document: Any) -> list[Feature]:
    rally = _field(document, "rallyPoints", dict, uav, default={})
    features = []
    for k, point in enumerate(_field(rally, "points", list, uav, default=[])):
        where = f"{uav}: rallyPoints.points[{k}]"
        lat, lon = _lat_lon(point, where, allow_altitude=True)
        feature = _point(lon, lat, role="rally")
        if len(point) == 3:  # QGC: the altitude above home
            feature["geometry"]["coordinates"].append(float(point[2]))
        features.append(feature)
    return features


def _plan_ends(uav: str, document: Any) -> list[Feature]:
    """Start at the planned home, goal at the last item with a position."""
    try:
        mission = parse_plan(json.dumps(document), source=uav)
    except MissionFileError as exc:
        raise GeographicError(uav, str(exc).removeprefix(f"{uav}: ")) from None
    home = mission.home
    assert home is not None, "parse_plan always reads plannedHomePosition"
    items = mission.items[1:] if mission.autopilot == Autopilot.ARDUPILOT else mission.items
    positioned = [i for i in items if _has_position(i)]  # ArduPilot's item 0 is home
    if not positioned:
        raise GeographicError(f"{uav}: mission.items", "no item with a position: no goal")
    goal = positioned[-1]
    extra: dict[str, Any] = {}
    speed = document["mission"].get("cruiseSpeed")
    if isinstance(speed, int | float) and not isinstance(speed, bool) and speed > 0:
        extra["speed_m_s"] = float(speed)
    return [
        _point(home[1], home[0], role="start", uav=uav, **extra),
        _point(goal.lon, goal.lat, role="goal", uav=uav),
    ]


def _has_position(item: MissionItem) -> bool:
    return int(item.frame) in _GLOBAL_FRAMES and (item.x, item.y) != (0, 0)


def _lat_lon(value: Any, where: str, allow_altitude: bool = False) -> tuple[float, float]:
    sizes = (2, 3) if allow_altitude else (2,)
    if not (
        isinstance(value, list)
        and len(value) in sizes
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    ):
        raise GeographicError(where, f"expected [latitude, longitude], got {value!r}")
    lat, lon = float(value[0]), float(value[1])
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise GeographicError(where, f"[{lat}, {lon}] is not a latitude and longitude")
    return lat, lon


def _field(obj: Any, key: str, kind: type, where: str, default: Any = None) -> Any:
    if not isinstance(obj, dict):
        raise GeographicError(where, "must be a JSON object")
    if key not in obj:
        if default is not None:
            return default
        raise GeographicError(where, f"{key} is missing")
    value = obj[key]
    number = kind is float and isinstance(value, int) and not isinstance(value, bool)
    if not (isinstance(value, kind) or number):
        raise GeographicError(where, f"{key} must be {kind.__name__}, got {value!r}")
    return float(value) if number else value


# ---------------------------------------------------------------- KML


def is_kml(content_type: str | None) -> bool:
    return (content_type or "").split(";")[0].strip().lower() == KML_MEDIA_TYPE


def from_kml(text: str | bytes, cell_size_m: float | None = None) -> dict[str, Any]:
    """The geographic scenario a KML document draws (see the module for its conventions);
    `cell_size_m` overrides the document's."""
    data = text.encode() if isinstance(text, str) else text
    _refuse_doctype(data)
    from fastkml import KML  # imported here: a tenth of a second that only KML pays
    from fastkml.exceptions import FastKMLError

    try:
        # bytes, not str: the parser then honours the encoding the document declares
        document = KML.from_string(data)  # type: ignore[arg-type]
    except (SyntaxError, FastKMLError, ValueError) as exc:  # lxml's and ElementTree's
        raise GeographicError(None, f"not KML: {exc}") from None
    properties = _kml_numbers(_data(document.features[0]) if document.features else {})
    if cell_size_m is not None:
        properties["cell_size_m"] = cell_size_m
    if "cell_size_m" not in properties:
        raise GeographicError(None, "no cell size: give cell_size_m in the document's ExtendedData")
    features = [_kml_feature(k, p) for k, p in enumerate(_placemarks(document))]
    if not features:
        raise GeographicError(None, "the KML document has no Placemark")
    names = [getattr(f, "name", None) for f in document.features]
    properties.setdefault("name", names[0] or "kml")
    return _collection(features, properties)


def _refuse_doctype(data: bytes) -> None:
    """A first parse that loads and resolves nothing: a DOCTYPE (in any encoding) means
    entities, which fastkml's parser would expand."""
    parser = etree.XMLParser(resolve_entities=False, load_dtd=False, no_network=True)
    try:
        tree = etree.fromstring(data, parser).getroottree()
    except etree.LxmlError as exc:
        raise GeographicError(None, f"not KML: {exc}") from None
    if tree.docinfo.doctype or tree.docinfo.internalDTD is not None:
        raise GeographicError(None, "KML with a DOCTYPE (entities) is refused")


def _placemarks(node: Any) -> Iterator[Placemark]:
    """Every Placemark, in document order, through Documents and Folders."""
    from fastkml import Placemark

    for feature in getattr(node, "features", None) or []:
        if isinstance(feature, Placemark):
            yield feature
        else:
            yield from _placemarks(feature)


def _data(feature: Any) -> dict[str, str]:
    extended = getattr(feature, "extended_data", None)
    elements = extended.elements if extended is not None else []
    return {e.name: e.value for e in elements if getattr(e, "name", None)}


def _kml_numbers(
    data: dict[str, str], names: tuple[str, ...] = _KML_DOCUMENT_NUMBERS
) -> dict[str, Any]:
    numbers: dict[str, Any] = {}
    for key in names:
        if key in data:
            try:
                numbers[key] = float(data[key])
            except ValueError:
                raise GeographicError(None, f"{key} {data[key]!r} is not a number") from None
    return numbers


def _kml_feature(index: int, placemark: Placemark) -> Feature:
    label = placemark.name or f"Placemark {index}"
    where = f"Placemark {index} ({label})"
    data = _data(placemark)
    words = (placemark.name or "").split()
    role = data.get("role") or (words[0].lower() if words else "")
    if role not in _ROLES:
        raise GeographicError(where, f"role {role!r} is none of {', '.join(_ROLES)}")
    properties: dict[str, Any] = {"role": role, "name": label}
    uav = data.get("uav") or (words[1] if role in ("start", "goal") and len(words) > 1 else None)
    if uav:
        properties["uav"] = uav
    try:
        properties |= _kml_numbers(data, _KML_NUMBERS)
    except GeographicError as exc:
        raise GeographicError(where, str(exc)) from None
    if placemark.geometry is None:
        raise GeographicError(where, "has no geometry")
    geometry = _plain(placemark.geometry.__geo_interface__)
    return {"type": "Feature", "geometry": geometry, "properties": properties}


def _plain(geometry: Mapping[str, Any]) -> dict[str, Any]:
    """pygeoif's geometry as GeoJSON: lists instead of tuples, no bbox, and a KML
    MultiGeometry of polygons as a MultiPolygon."""
    kind = geometry["type"]
    if kind == "GeometryCollection":
        parts = [_plain(g) for g in geometry["geometries"]]
        if parts and all(p["type"] == "Polygon" for p in parts):
            return {"type": "MultiPolygon", "coordinates": [p["coordinates"] for p in parts]}
        return {"type": kind, "coordinates": None}  # refused by the file's own check
    return {"type": kind, "coordinates": json.loads(json.dumps(geometry["coordinates"]))}
