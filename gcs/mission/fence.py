"""A geographic scenario's geofence and rally points, as an autopilot holds them.

The fence is a backstop for the plan, in the autopilot itself: one inclusion polygon,
the area's exterior ring (a hole in the area is an exclusion polygon), one exclusion
polygon per no-fly polygon (each polygon of a MultiPolygon; a hole in a no-fly zone is
not flyable for the planner, so it is left out and the whole exterior is excluded) and
one exclusion circle per no-fly Point with `radius_m`. Rally points are the Points with
`"role": "rally"`, their position's third value, if any, being the altitude above home.

`fence_of` is the data (vertices in degrees, what a `.plan`'s `geoFence` and
`rallyPoints` hold too); `fence_items` and `rally_items` are the MAVLink mission items
of the FENCE and RALLY mission types (MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION and
_EXCLUSION, param1 the polygon's vertex count; MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, param1
the radius in metres; MAV_CMD_NAV_RALLY_POINT); `same_fence_item` and `same_rally_item`
say whether what ArduPilot gives back on download is what it was sent.

ArduPilot keeps a fence vertex's latitude and longitude as sent (degE7) and a circle's
radius as a float, and gives them back in frame 0 with z 0
(`MissionItemProtocol_Fence::get_item_as_mission_item`); it keeps a rally point's
altitude in whole metres (int16) and gives it back in frame 3
(`MissionItemProtocol_Rally`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.mission_item import Frame, MissionItem
from gcs.mission.geographic import (
    MAX_RALLY_ALT_M,
    GeographicError,
    GeographicScenario,
    MultiPolygon,
    Point,
    Polygon,
    Position,
)

LatLon = tuple[float, float]
RallyPoint = tuple[float, float] | tuple[float, float, float]
"""(lat, lon) or (lat, lon, altitude above home in metres)."""
Circle = tuple[float, float, float]
"""(lat, lon, radius in metres)."""

FENCE_INCLUSION = mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
FENCE_EXCLUSION = mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
FENCE_CIRCLE_EXCLUSION = mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
RALLY_POINT = mavlink2.MAV_CMD_NAV_RALLY_POINT


@dataclass(frozen=True)
class FencePlan:
    """A scenario's fence and rally points, vertices (lat, lon) in degrees, each polygon
    open (its first vertex not repeated at the end)."""

    inclusion_polygons: tuple[tuple[LatLon, ...], ...] = ()
    exclusion_polygons: tuple[tuple[LatLon, ...], ...] = ()
    exclusion_circles: tuple[Circle, ...] = ()
    rally_points: tuple[RallyPoint, ...] = ()

    @property
    def has_fence(self) -> bool:
        return bool(self.inclusion_polygons or self.exclusion_polygons or self.exclusion_circles)

    @property
    def is_empty(self) -> bool:
        return not self.has_fence and not self.rally_points


def fence_of(source: GeographicScenario) -> FencePlan:
    """The fence and rally points of a geographic scenario (GeographicError naming the
    feature for a rally point that is not a Point or has a negative altitude, or for a
    file without an area)."""
    inclusion: list[tuple[LatLon, ...]] = []
    exclusion: list[tuple[LatLon, ...]] = []
    circles: list[Circle] = []
    rally: list[RallyPoint] = []
    for i, feature in enumerate(source.features):
        role, geometry = feature.properties.role, feature.geometry
        where = f"features[{i}] (rally point)"
        if role == "area" and isinstance(geometry, Polygon):
            inclusion.append(_open_ring(geometry.coordinates[0]))
            exclusion.extend(_open_ring(hole) for hole in geometry.coordinates[1:])
        elif role == "no-fly":
            if isinstance(geometry, Polygon):
                exclusion.append(_open_ring(geometry.coordinates[0]))
            elif isinstance(geometry, MultiPolygon):
                exclusion.extend(_open_ring(p[0]) for p in geometry.coordinates)
            elif feature.properties.radius_m is not None:
                lon, lat = geometry.coordinates[:2]
                circles.append((lat, lon, float(feature.properties.radius_m)))
        elif role == "rally":
            if not isinstance(geometry, Point):
                raise GeographicError(where, f"a rally point is a Point, not a {geometry.type}")
            rally.append(_rally_point(where, geometry))
    if not inclusion:
        raise GeographicError(None, 'no feature has "role": "area": the operating area')
    return FencePlan(tuple(inclusion), tuple(exclusion), tuple(circles), tuple(rally))


def _open_ring(ring: list[Position]) -> tuple[LatLon, ...]:
    """(lat, lon) vertices without the closing repeat or consecutive duplicates."""
    out: list[LatLon] = []
    for position in ring[:-1]:
        vertex = (float(position[1]), float(position[0]))
        if not out or out[-1] != vertex:
            out.append(vertex)
    while len(out) > 1 and out[-1] == out[0]:
        out.pop()
    return tuple(out)


def _rally_point(where: str, point: Point) -> RallyPoint:
    lon, lat = float(point.coordinates[0]), float(point.coordinates[1])
    if len(point.coordinates) < 3:
        return (lat, lon)
    alt = float(point.coordinates[2])
    if not 0 <= alt <= MAX_RALLY_ALT_M:
        raise GeographicError(
            where, f"a rally point's altitude is 0 to {MAX_RALLY_ALT_M} m above home, not {alt:g}"
        )
    return (lat, lon, alt)


# ---------------------------------------------------------------- as MAVLink mission items


def _deg_e7(value: float) -> int:
    return round(value * 1e7)


def fence_items(plan: FencePlan) -> tuple[MissionItem, ...]:
    """The FENCE mission type's items: each polygon's vertices in turn (param1 its vertex
    count), then the circles (param1 the radius)."""
    items: list[MissionItem] = []
    for command, polygons in (
        (FENCE_INCLUSION, plan.inclusion_polygons),
        (FENCE_EXCLUSION, plan.exclusion_polygons),
    ):
        for polygon in polygons:
            for lat, lon in polygon:
                items.append(
                    MissionItem(
                        command,
                        Frame.GLOBAL,
                        (float(len(polygon)), 0.0, 0.0, 0.0),
                        _deg_e7(lat),
                        _deg_e7(lon),
                    )
                )
    for lat, lon, radius in plan.exclusion_circles:
        items.append(
            MissionItem(
                FENCE_CIRCLE_EXCLUSION,
                Frame.GLOBAL,
                (radius, 0.0, 0.0, 0.0),
                _deg_e7(lat),
                _deg_e7(lon),
            )
        )
    return tuple(items)


def rally_items(plan: FencePlan, default_alt_m: float) -> tuple[MissionItem, ...]:
    """The RALLY mission type's items, at each point's altitude or `default_alt_m` above
    home (ArduPilot keeps whole metres: the altitude is rounded here)."""
    return tuple(
        MissionItem(
            RALLY_POINT,
            Frame.GLOBAL_RELATIVE_ALT,
            (0.0, 0.0, 0.0, 0.0),
            _deg_e7(point[0]),
            _deg_e7(point[1]),
            float(round(point[2] if len(point) == 3 else default_alt_m)),
        )
        for point in plan.rally_points
    )


def same_fence_item(sent: MissionItem, read: MissionItem) -> bool:
    """Whether `read` is what ArduPilot gives back for a stored fence item `sent`: the
    command, param1 (vertex count or radius, float32) and the position; not the frame
    nor z, which it does not keep."""
    return (
        int(sent.command) == int(read.command)
        and _same_f32(sent.params[0], read.params[0])
        and (sent.x, sent.y) == (read.x, read.y)
    )


def same_rally_item(sent: MissionItem, read: MissionItem) -> bool:
    """Whether `read` is what ArduPilot gives back for a stored rally point `sent`: the
    position and the altitude in whole metres, above home."""
    return (
        int(read.command) == RALLY_POINT
        and int(sent.command) == RALLY_POINT
        and (sent.x, sent.y) == (read.x, read.y)
        and int(read.frame)
        in (mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)
        and math.trunc(sent.z) == math.trunc(read.z)
    )


def _same_f32(a: float, b: float) -> bool:
    return bool(np.float32(a) == np.float32(b))
