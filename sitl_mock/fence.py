"""The geofence as ArduCopter keeps and enforces it (AC_Fence, AC_PolyFence_loader,
ArduCopter/fence.cpp), for the fence types the mock flies.

Storage (the FENCE mission type): ArduPilot takes fence items in a global frame only
(0, 3, 5, 6, 10, 11; else UNSUPPORTED_FRAME), keeps a vertex's latitude and longitude
and a circle's radius, and gives them back in frame 0 with z 0
(`MissionItemProtocol_Fence::get_item_as_mission_item`); a list whose polygons do not
add up (a vertex count that changes within a polygon, or fewer than 3 vertices) is
refused whole with MAV_MISSION_ERROR when the last item arrives, the previous fence
kept. Rally points (the RALLY mission type) are taken in global frames (absolute, relative or
terrain), kept with a whole-metre altitude and its frame, and given back in frame 0, 3
or 10 (`MissionItemProtocol_Rally`).

Enforcement (`FenceMonitor`, checked every step; ArduCopter checks at 25 Hz), with
`FENCE_ENABLE` 1 and the `FENCE_TYPE` bits: 1 the maximum altitude (`FENCE_ALT_MAX`
above home), 2 a circle round home (`FENCE_RADIUS`), 4 the uploaded polygons and
circles (outside any inclusion zone or inside any exclusion zone is a breach). A fence
is breached once when crossed ("Polygon fence breached", severity NOTICE, not said on
the ground) and cleared when the vehicle is back inside ("Fence breach cleared"); the
breach counts (FENCE_STATUS breach_count) and, if the vehicle is armed, sets off
`FENCE_ACTION`: 0 report only; on the ground, disarm; more than 100 m outside, LAND;
1 RTL (else LAND), 2 LAND, 3 SmartRTL (not simulated) else RTL else LAND, 4 BRAKE
(else LAND), 5 SmartRTL else LAND. The minimum altitude fence (8) is not simulated.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .codec import mavlink
from .mission_item import MissionItem

INCLUSION = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
EXCLUSION = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
CIRCLE_INCLUSION = mavlink.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
CIRCLE_EXCLUSION = mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
RETURN_POINT = mavlink.MAV_CMD_NAV_FENCE_RETURN_POINT
FENCE_FRAMES = frozenset(
    {
        mavlink.MAV_FRAME_GLOBAL,
        mavlink.MAV_FRAME_GLOBAL_INT,
        mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
        mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
    }
)
RALLY_FRAMES = {
    mavlink.MAV_FRAME_GLOBAL: mavlink.MAV_FRAME_GLOBAL,
    mavlink.MAV_FRAME_GLOBAL_INT: mavlink.MAV_FRAME_GLOBAL,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT: mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT: mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
    mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
}
"""A rally point's frame as taken and as given back (its altitude frame is kept)."""

ALT_MAX, CIRCLE, POLYGON = 1, 2, 4
"""AC_FENCE_TYPE bits."""
NAMES = {ALT_MAX: "Max Alt", CIRCLE: "Circle", POLYGON: "Polygon"}
MANUAL_RECOVERY_S = 10.0
"""AC_FENCE_MANUAL_RECOVERY_TIME_MIN: after a mode change during a breach, new breaches
are recorded but not acted on for this long ("Manual recovery started")."""
GIVE_UP_DISTANCE_M = 100.0
"""AC_FENCE_GIVE_UP_DISTANCE: further outside than this, the action is LAND."""
ALT_MAX_BACKUP_M = 20.0
CIRCLE_BACKUP_M = 20.0


# ---------------------------------------------------------------- storage


def fence_item_refusal(item: MissionItem) -> int | None:
    if item.frame not in FENCE_FRAMES:
        return int(mavlink.MAV_MISSION_UNSUPPORTED_FRAME)
    if item.command not in (INCLUSION, EXCLUSION, CIRCLE_INCLUSION, CIRCLE_EXCLUSION, RETURN_POINT):
        return int(mavlink.MAV_MISSION_UNSUPPORTED)
    return None


def rally_item_refusal(item: MissionItem) -> int | None:
    if item.command != mavlink.MAV_CMD_NAV_RALLY_POINT:
        return int(mavlink.MAV_MISSION_UNSUPPORTED)
    if item.frame not in RALLY_FRAMES:
        return int(mavlink.MAV_MISSION_UNSUPPORTED_FRAME)
    if not -900_000_000 <= item.x <= 900_000_000:
        return int(mavlink.MAV_MISSION_INVALID_PARAM5_X)
    if not -1_800_000_000 <= item.y <= 1_800_000_000:
        return int(mavlink.MAV_MISSION_INVALID_PARAM6_Y)
    if not -32768 <= item.z <= 32767:
        return int(mavlink.MAV_MISSION_INVALID_PARAM7)
    return None


def fence_list_valid(items: Sequence[MissionItem]) -> bool:
    """AC_PolyFence_loader::validate_fence: each polygon's vertices all carry its count,
    at least 3, and come together; circles have a positive radius."""
    i = 0
    while i < len(items):
        item = items[i]
        if item.command in (INCLUSION, EXCLUSION):
            count = int(item.param1)
            group = items[i : i + count]
            if count < 3 or len(group) < count:
                return False
            if any(g.command != item.command or int(g.param1) != count for g in group):
                return False
            i += count
            continue
        if item.command in (CIRCLE_INCLUSION, CIRCLE_EXCLUSION) and not item.param1 > 0:
            return False
        i += 1
    return True


def stored_fence_item(item: MissionItem) -> MissionItem:
    """What a download gives back: command, param1 (float32), position; frame 0, z 0."""
    return MissionItem(
        seq=item.seq,
        frame=mavlink.MAV_FRAME_GLOBAL,
        command=item.command,
        param1=float(np.float32(item.param1)),
        x=item.x,
        y=item.y,
        mission_type=mavlink.MAV_MISSION_TYPE_FENCE,
    )


def stored_rally_item(item: MissionItem) -> MissionItem:
    """Position and a whole-metre altitude (int16, cut towards zero), in the frame of
    its altitude (3 for 3 and 6)."""
    return MissionItem(
        seq=item.seq,
        frame=RALLY_FRAMES[item.frame],
        command=mavlink.MAV_CMD_NAV_RALLY_POINT,
        x=item.x,
        y=item.y,
        z=float(math.trunc(item.z)),
        mission_type=mavlink.MAV_MISSION_TYPE_RALLY,
    )


# ---------------------------------------------------------------- the zones

Local = Callable[[float, float], tuple[float, float]]
"""(lat, lon) -> (east, north) metres in the simulation's plane."""


@dataclass(frozen=True)
class Zones:
    """The stored fence in the simulation's plane (metres east and north)."""

    inclusions: tuple[np.ndarray, ...] = ()
    exclusions: tuple[np.ndarray, ...] = ()
    inclusion_circles: tuple[tuple[float, float, float], ...] = ()
    exclusion_circles: tuple[tuple[float, float, float], ...] = ()

    @property
    def empty(self) -> bool:
        return not (
            self.inclusions or self.exclusions or self.inclusion_circles or self.exclusion_circles
        )

    @classmethod
    def of(cls, items: Sequence[MissionItem], to_local: Local) -> Zones:
        polygons: dict[int, list[np.ndarray]] = {INCLUSION: [], EXCLUSION: []}
        circles: dict[int, list[tuple[float, float, float]]] = {
            CIRCLE_INCLUSION: [],
            CIRCLE_EXCLUSION: [],
        }
        i = 0
        while i < len(items):
            item = items[i]
            if item.command in polygons:
                count = max(1, int(item.param1))
                vertices = [to_local(v.lat, v.lon) for v in items[i : i + count]]
                polygons[item.command].append(np.asarray(vertices, dtype=float))
                i += count
                continue
            if item.command in circles:
                east, north = to_local(item.lat, item.lon)
                circles[item.command].append((east, north, float(item.param1)))
            i += 1
        return cls(
            tuple(polygons[INCLUSION]),
            tuple(polygons[EXCLUSION]),
            tuple(circles[CIRCLE_INCLUSION]),
            tuple(circles[CIRCLE_EXCLUSION]),
        )

    def breach_distance(self, east: float, north: float) -> float | None:
        """How far the point is outside the allowed area (metres), None when inside:
        outside any inclusion zone or inside any exclusion zone is a breach."""
        worst: float | None = None

        def out(distance: float) -> None:
            nonlocal worst
            worst = distance if worst is None else max(worst, distance)

        for polygon in self.inclusions:
            if not _inside(polygon, east, north):
                out(_edge_distance(polygon, east, north))
        for polygon in self.exclusions:
            if _inside(polygon, east, north):
                out(_edge_distance(polygon, east, north))
        for ce, cn, radius in self.inclusion_circles:
            d = math.hypot(east - ce, north - cn)
            if d >= radius:
                out(d - radius)
        for ce, cn, radius in self.exclusion_circles:
            d = math.hypot(east - ce, north - cn)
            if d <= radius:
                out(radius - d)
        return worst


def _inside(polygon: np.ndarray, x: float, y: float) -> bool:
    """Even-odd rule, as AP's Polygon_outside."""
    xs, ys = polygon[:, 0], polygon[:, 1]
    xs2, ys2 = np.roll(xs, -1), np.roll(ys, -1)
    crosses = (ys > y) != (ys2 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        at = xs + (y - ys) * (xs2 - xs) / (ys2 - ys)
    return bool(np.count_nonzero(crosses & (x < at)) % 2)


def _edge_distance(polygon: np.ndarray, x: float, y: float) -> float:
    a, b = polygon, np.roll(polygon, -1, axis=0)
    ab = b - a
    length2 = np.maximum((ab**2).sum(axis=1), 1e-12)
    t = np.clip(((np.array([x, y]) - a) * ab).sum(axis=1) / length2, 0.0, 1.0)
    nearest = a + t[:, None] * ab
    return float(np.hypot(nearest[:, 0] - x, nearest[:, 1] - y).min())


# ---------------------------------------------------------------- the monitor


@dataclass
class Breach:
    """What a check found: the fence bits newly breached and how far outside."""

    new: int
    distance_m: float


@dataclass
class FenceMonitor:
    """AC_Fence's breach state: which fences are breached, how often, since when."""

    breaches: int = 0
    breach_count: int = 0
    breach_time_ms: int = 0
    _distances: dict[int, float] = field(default_factory=dict)
    _alt_backup: float = 0.0
    _circle_backup: float = 0.0

    def reset(self) -> None:
        self.breaches, self.breach_count, self.breach_time_ms = 0, 0, 0
        self._distances.clear()
        self._alt_backup = self._circle_backup = 0.0

    def check(
        self,
        enabled_types: int,
        zones: Zones,
        position: tuple[float, float, float],
        home: tuple[float, float],
        limits: tuple[float, float],
        uptime_ms: int,
        recovering: bool = False,
    ) -> Breach | None:
        """Check the enabled fences at `position` (east, north, up above home); `limits`
        are FENCE_ALT_MAX and FENCE_RADIUS. Returns the new breaches, if any (none while
        `recovering`: they are recorded, not returned); breaches no longer true are
        cleared."""
        east, north, up = position
        new = 0
        alt_max, radius = limits
        if enabled_types & ALT_MAX:
            if up >= alt_max:
                self._distances[ALT_MAX] = up - alt_max
                if not self.breaches & ALT_MAX or (self._alt_backup and up >= self._alt_backup):
                    new |= ALT_MAX
                    self._alt_backup = up + ALT_MAX_BACKUP_M
            else:
                self._clear(ALT_MAX)
                self._alt_backup = 0.0
        else:
            self._clear(ALT_MAX)
        if enabled_types & CIRCLE:
            from_home = math.hypot(east - home[0], north - home[1])
            if from_home >= radius:
                self._distances[CIRCLE] = from_home - radius
                backup = self._circle_backup
                if not self.breaches & CIRCLE or (backup and from_home >= backup):
                    new |= CIRCLE
                    self._circle_backup = from_home + CIRCLE_BACKUP_M
            else:
                self._clear(CIRCLE)
                self._circle_backup = 0.0
        else:
            self._clear(CIRCLE)
        outside = zones.breach_distance(east, north) if enabled_types & POLYGON else None
        if outside is not None:
            self._distances[POLYGON] = outside
            if not self.breaches & POLYGON:
                new |= POLYGON
        else:
            self._clear(POLYGON)
        if not new:
            return None
        self.breaches |= new
        self.breach_count = min(self.breach_count + 1, 0xFFFF)
        self.breach_time_ms = uptime_ms
        distance = max(self._distances.get(bit, 0.0) for bit in NAMES if new & bit)
        return None if recovering else Breach(new, distance)

    def _clear(self, bit: int) -> None:
        self.breaches &= ~bit
        self._distances.pop(bit, None)

    @property
    def breach_type(self) -> int:
        """FENCE_STATUS breach_type: BOUNDARY for the circle or polygons, else MAXALT."""
        if self.breaches & (CIRCLE | POLYGON):
            return int(mavlink.FENCE_BREACH_BOUNDARY)
        if self.breaches & ALT_MAX:
            return int(mavlink.FENCE_BREACH_MAXALT)
        return int(mavlink.FENCE_BREACH_NONE)


def fence_names(bits: int) -> str:
    """AC_Fence::get_fence_names: "Polygon fence", "Max Alt and Polygon fences"."""
    names = [name for bit, name in sorted(NAMES.items()) if bits & bit]
    if len(names) <= 1:
        text = names[0] if names else ""
    else:
        text = ", ".join(names[:-1]) + " and " + names[-1]
    return text + (" fences" if len(names) > 1 else " fence")
