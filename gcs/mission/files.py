"""Missions as files other ground stations open: QGroundControl `.plan` and `.waypoints`.

Both formats are written the way their reference tools write them, so that QGC, MAVSDK's
`import_qgroundcontrol_mission` and pymavlink's `mavwp.MAVWPLoader` read them back:

- `.plan` (QGC `MissionController::save`): JSON; home is not an item but
  `mission.plannedHomePosition` [lat, lon, AMSL m], so an ArduPilot mission's item 0
  goes there and its items start at seq 1. Each item is a `SimpleItem` whose `params` are
  MAVLink's seven (param1-4, lat, lon, alt) with NaN written as null; `Altitude`,
  `AltitudeMode` and `AMSLAltAboveTerrain` are QGC's editor fields, written for items
  with a position and ignored on reading.
- `.waypoints` (`QGC WPL 110`, Mission Planner's text format): a header line, then one
  TAB-separated line per item, INDEX CURRENT FRAME COMMAND P1 P2 P3 P4 LAT LON ALT
  AUTOCONTINUE. Line 0 is always home (QGC's loader takes it as the planned home), so a
  PX4 mission's home is written there and its items start at index 1. The format does not
  say which autopilot it is for: the reader is told.

Latitude and longitude are written in degrees with 7 decimals, which reproduces degE7
exactly; frame 2 (MISSION) items carry raw integers there, as MAVSDK reads them. Reading
a malformed file raises `MissionFileError`, which says what is wrong and where.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from gcs.mavlink.mission_item import Autopilot, Command, Frame, Mission, MissionItem
from gcs.mission.fence import FencePlan, LatLon

GROUND_STATION = "mvo-gcs"
VEHICLE_TYPE_QUADROTOR = 2  # MAV_TYPE, what QGC writes as vehicleType
DEFAULT_HOVER_SPEED = 5.0  # m/s, QGC's multirotor default when a mission sets no speed
WAYPOINTS_HEADER = "QGC WPL 110"
WAYPOINTS_FIELDS: tuple[str, ...] = ("INDEX", "CURRENT", "FRAME", "COMMAND", "P1", "P2", "P3")
WAYPOINTS_FIELDS += ("P4", "LAT", "LON", "ALT", "AUTOCONTINUE")
# QGroundControlQmlGlobal::AltMode: 1 relative to home, 2 AMSL, 4 terrain frame.
_ALTITUDE_MODE = {0: 2, 3: 1, 5: 2, 6: 1, 10: 4, 11: 4}

Home = tuple[float, float, float]


class MissionFileError(ValueError):
    """A mission file that cannot be read; `line` (1-based) or `item` (0-based) says where."""

    def __init__(
        self, what: str, *, source: str = "<text>", line: int | None = None, item: int | None = None
    ) -> None:
        where = f"line {line}: " if line is not None else ""
        where += f"mission.items[{item}]: " if item is not None else ""
        super().__init__(f"{source}: {where}{what}")
        self.what, self.source, self.line, self.item = what, source, line, item


# ---------------------------------------------------------------- .plan (QGroundControl)


def write_plan(mission: Mission, path: str | Path) -> None:
    Path(path).write_text(plan_text(mission))


def plan_text(
    mission: Mission,
    notes: str | None = None,
    fence: FencePlan | None = None,
    rally_alt_m: float = 0.0,
) -> str:
    document = plan_document(mission, notes, fence, rally_alt_m)
    return json.dumps(document, indent=4, allow_nan=False) + "\n"


def plan_document(
    mission: Mission,
    notes: str | None = None,
    fence: FencePlan | None = None,
    rally_alt_m: float = 0.0,
) -> dict[str, Any]:
    """The `.plan` JSON of a mission, with the fence and rally points when given (those
    without an altitude of their own at `rally_alt_m` above home); `notes` go in a
    top-level key of their own, which QGroundControl and MAVSDK pass over."""
    home, items = _split_home(mission)
    speed = next(
        (i.params[1] for i in items if i.command == Command.DO_CHANGE_SPEED and i.params[1] > 0),
        DEFAULT_HOVER_SPEED,
    )
    document: dict[str, Any] = {
        "fileType": "Plan",
        "version": 1,
        "groundStation": GROUND_STATION,
        "mission": {
            "version": 2,
            "firmwareType": int(mission.autopilot),
            "vehicleType": VEHICLE_TYPE_QUADROTOR,
            "cruiseSpeed": speed,
            "hoverSpeed": speed,
            "globalPlanAltitudeMode": 1,
            "plannedHomePosition": list(home),
            "items": [_simple_item(item, k + 1) for k, item in enumerate(items)],
        },
        **_fence_and_rally(fence or FencePlan(), rally_alt_m),
    }
    if notes:
        document["notes"] = notes
    return document


def _fence_and_rally(fence: FencePlan, rally_alt_m: float) -> dict[str, Any]:
    """QGC's `geoFence` (version 2: polygons and circles, each with `inclusion`, vertices
    [lat, lon], open rings) and `rallyPoints` (version 2: [lat, lon, alt above home])."""

    def polygon(vertices: tuple[LatLon, ...], inclusion: bool) -> dict[str, Any]:
        return {"inclusion": inclusion, "polygon": [list(v) for v in vertices], "version": 1}

    polygons = [polygon(p, True) for p in fence.inclusion_polygons]
    polygons += [polygon(p, False) for p in fence.exclusion_polygons]
    circles = [
        {"circle": {"center": [lat, lon], "radius": radius}, "inclusion": False, "version": 1}
        for lat, lon, radius in fence.exclusion_circles
    ]
    rally = [[p[0], p[1], p[2] if len(p) == 3 else rally_alt_m] for p in fence.rally_points]
    return {
        "geoFence": {"version": 2, "circles": circles, "polygons": polygons},
        "rallyPoints": {"version": 2, "points": rally},
    }


def _split_home(mission: Mission) -> tuple[Home, tuple[MissionItem, ...]]:
    """plannedHomePosition and the items after it: ArduPilot's item 0 is home."""
    if mission.autopilot == Autopilot.ARDUPILOT and mission.items:
        first = mission.items[0]
        return (first.lat, first.lon, float(first.z)), mission.items[1:]
    if mission.home is None:
        raise ValueError("the mission has no home to write as plannedHomePosition")
    lat, lon, amsl = mission.home
    return (float(lat), float(lon), float(amsl)), mission.items


def _simple_item(item: MissionItem, jump_id: int) -> dict[str, Any]:
    x, y = _coordinate_out(item.x, item.frame), _coordinate_out(item.y, item.frame)
    saved: dict[str, Any] = {
        "type": "SimpleItem",
        "command": int(item.command),
        "frame": int(item.frame),
        "params": [*(_json_float(p) for p in item.params), x, y, _json_float(item.z)],
        "autoContinue": bool(item.autocontinue),
        "doJumpId": jump_id,
    }
    if int(item.frame) in _ALTITUDE_MODE:
        saved |= {
            "Altitude": _json_float(item.z),
            "AltitudeMode": _ALTITUDE_MODE[int(item.frame)],
            "AMSLAltAboveTerrain": None,  # QGC's terrain query result; we have none
        }
    return saved


def _json_float(value: float) -> float | None:
    if math.isinf(value):
        raise ValueError(f"{value} cannot be written to a mission file")
    return None if math.isnan(value) else float(value)


def read_plan(path: str | Path) -> Mission:
    return parse_plan(Path(path).read_text(), source=str(path))


def parse_plan(text: str, *, source: str = "<text>") -> Mission:
    """A mission from `.plan` JSON; the autopilot comes from `firmwareType`."""
    try:
        root = json.loads(text)
    except json.JSONDecodeError as error:
        raise MissionFileError(f"not JSON: {error.msg}", source=source, line=error.lineno) from None
    check = _Checker(source)
    check.equal(root, "fileType", "Plan")
    check.equal(root, "version", 1)
    mission = check.field(root, "mission", dict)
    check.equal(mission, "version", 2, "mission.")
    firmware = check.field(mission, "firmwareType", int, "mission.")
    if firmware not in {a.value for a in Autopilot}:
        raise check.error(f"mission.firmwareType {firmware} is neither 3 (ArduPilot) nor 12 (PX4)")
    autopilot = Autopilot(firmware)
    home = check.numbers(check.field(mission, "plannedHomePosition", list, "mission."), 3)
    raw_items = check.field(mission, "items", list, "mission.")
    items = [check.item(raw, k) for k, raw in enumerate(raw_items)]
    if autopilot == Autopilot.ARDUPILOT:
        items.insert(0, _home_item(home))
    return Mission(tuple(items), autopilot, (home[0], home[1], home[2]))


def _home_item(home: Sequence[float]) -> MissionItem:
    """ArduPilot's item 0 from a planned home: frame GLOBAL, altitude AMSL."""
    return MissionItem(
        Command.NAV_WAYPOINT,
        Frame.GLOBAL,
        x=_coordinate_in(home[0], Frame.GLOBAL),
        y=_coordinate_in(home[1], Frame.GLOBAL),
        z=float(home[2]),
    )


class _Checker:
    """Reads `.plan` fields, raising MissionFileError that names the field."""

    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, what: str, item: int | None = None) -> MissionFileError:
        return MissionFileError(what, source=self.source, item=item)

    def field(
        self, obj: Any, key: str, kind: type, prefix: str = "", item: int | None = None
    ) -> Any:
        if not isinstance(obj, dict) or key not in obj:
            raise self.error(f"{prefix}{key} is missing", item)
        value = obj[key]
        if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
            raise self.error(f"{prefix}{key} must be {kind.__name__}, got {value!r}", item)
        return value

    def equal(self, obj: Any, key: str, expected: Any, prefix: str = "") -> None:
        value = self.field(obj, key, type(expected), prefix)
        if value != expected:
            raise self.error(f"{prefix}{key} is {value!r}, expected {expected!r}")

    def numbers(self, values: list[Any], count: int, item: int | None = None) -> list[float]:
        """`count` numbers, null read as NaN (QGC writes NaN as null)."""
        ok = len(values) == count and all(
            v is None or (isinstance(v, int | float) and not isinstance(v, bool)) for v in values
        )
        if not ok:
            raise self.error(f"expected {count} numbers or nulls, got {values!r}", item)
        return [math.nan if v is None else float(v) for v in values]

    def item(self, raw: Any, k: int) -> MissionItem:
        if not isinstance(raw, dict):
            raise self.error("must be an object", k)
        kind = raw.get("type")
        if kind != "SimpleItem":
            raise self.error(f"type {kind!r} is not supported, only SimpleItem", k)
        frame = self.field(raw, "frame", int, item=k)
        params = self.numbers(self.field(raw, "params", list, item=k), 7, k)
        return MissionItem(
            command=self.field(raw, "command", int, item=k),
            frame=frame,
            params=(params[0], params[1], params[2], params[3]),
            x=_coordinate_in(params[4], frame),
            y=_coordinate_in(params[5], frame),
            z=params[6],
            autocontinue=self.field(raw, "autoContinue", bool, item=k),
        )


def _coordinate_out(value: int, frame: int) -> float | int:
    """degE7 to degrees; frame MISSION carries plain numbers."""
    return int(value) if frame == Frame.MISSION else int(value) / 1e7


def _coordinate_in(value: float, frame: int) -> int:
    if math.isnan(value):
        return 0
    return round(value) if frame == Frame.MISSION else round(value * 1e7)


# ---------------------------------------------------------------- .waypoints (QGC WPL 110)


def write_waypoints(mission: Mission, path: str | Path) -> None:
    Path(path).write_text(waypoints_text(mission))


def waypoints_text(mission: Mission) -> str:
    """`QGC WPL 110` text: line 0 is home (ArduPilot's item 0, PX4's `home`)."""
    rows = list(mission.items)
    if mission.autopilot == Autopilot.PX4:
        if mission.home is None:
            raise ValueError("a PX4 mission needs a home for line 0 of a .waypoints file")
        rows.insert(0, _home_item(mission.home))
    lines = [WAYPOINTS_HEADER] + [_waypoint_line(k, item) for k, item in enumerate(rows)]
    return "\n".join(lines) + "\n"


def _waypoint_line(index: int, item: MissionItem) -> str:
    """One TAB-separated line; `current` is 1 on home, as QGC and Mission Planner write it."""
    x, y = _coordinate_out(item.x, item.frame), _coordinate_out(item.y, item.frame)
    fields = [
        str(index),
        "1" if index == 0 else "0",
        str(int(item.frame)),
        str(int(item.command)),
        *(_text_float(p) for p in item.params),
        f"{x:.7f}" if isinstance(x, float) else str(x),
        f"{y:.7f}" if isinstance(y, float) else str(y),
        _text_float(item.z),
        "1" if item.autocontinue else "0",
    ]
    return "\t".join(fields)


def _text_float(value: float) -> str:
    """Shortest text that reads back to the same float; NaN as `nan` (strtod, float())."""
    _json_float(value)  # refuses infinities
    return "nan" if math.isnan(value) else repr(float(value))


def read_waypoints(path: str | Path, autopilot: Autopilot = Autopilot.ARDUPILOT) -> Mission:
    return parse_waypoints(Path(path).read_text(), autopilot, source=str(path))


def parse_waypoints(
    text: str, autopilot: Autopilot = Autopilot.ARDUPILOT, *, source: str = "<text>"
) -> Mission:
    """A mission from `QGC WPL 110` text: for ArduPilot line 0 is item 0, for PX4 it is home."""
    lines = text.splitlines()
    if not lines or lines[0].strip() != WAYPOINTS_HEADER:
        found = lines[0].strip() if lines else "an empty file"
        raise MissionFileError(
            f"expected {WAYPOINTS_HEADER!r}, found {found!r}", source=source, line=1
        )
    rows: list[MissionItem] = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        try:
            rows.append(_parse_waypoint_line(line, expected_index=len(rows)))
        except ValueError as error:
            raise MissionFileError(str(error), source=source, line=number) from None
    home = (rows[0].lat, rows[0].lon, float(rows[0].z)) if rows else None
    if autopilot == Autopilot.PX4:
        return Mission(tuple(rows[1:]), autopilot, home)
    return Mission(tuple(rows), autopilot, home)


def _parse_waypoint_line(line: str, expected_index: int) -> MissionItem:
    fields = line.split()  # TABs as written; any whitespace, as pymavlink reads it
    if len(fields) != len(WAYPOINTS_FIELDS):
        raise ValueError(f"expected 12 TAB-separated fields, found {len(fields)}")
    value = dict(zip(WAYPOINTS_FIELDS, fields, strict=True))
    index = _int_field(value, "INDEX")
    if index != expected_index:
        raise ValueError(f"INDEX {index} is out of sequence, expected {expected_index}")
    autocontinue = _int_field(value, "AUTOCONTINUE")
    if autocontinue not in (0, 1):
        raise ValueError(f"AUTOCONTINUE must be 0 or 1, got {autocontinue}")
    frame = _int_field(value, "FRAME")
    p1, p2, p3, p4, lat, lon, alt = (
        _float_field(value, name) for name in ("P1", "P2", "P3", "P4", "LAT", "LON", "ALT")
    )
    return MissionItem(
        command=_int_field(value, "COMMAND"),
        frame=frame,
        params=(p1, p2, p3, p4),
        x=_coordinate_in(lat, frame),
        y=_coordinate_in(lon, frame),
        z=alt,
        autocontinue=bool(autocontinue),
    )


def _int_field(value: dict[str, str], name: str) -> int:
    try:
        return int(value[name])
    except ValueError:
        raise ValueError(f"{name} {value[name]!r} is not an integer") from None


def _float_field(value: dict[str, str], name: str) -> float:
    try:
        number = float(value[name])
    except ValueError:
        raise ValueError(f"{name} {value[name]!r} is not a number") from None
    if math.isinf(number):
        raise ValueError(f"{name} is infinite")
    return number
