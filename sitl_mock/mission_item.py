"""One stored mission item, as the vehicle keeps it, and its two wire forms."""

from __future__ import annotations

import math
from dataclasses import astuple, dataclass, replace

from .codec import Message, mavlink

GLOBAL_FRAMES = frozenset(
    {
        mavlink.MAV_FRAME_GLOBAL,
        mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        mavlink.MAV_FRAME_GLOBAL_INT,
        mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    }
)
AMSL_FRAMES = frozenset({mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_INT})
SUPPORTED_FRAMES = GLOBAL_FRAMES | {mavlink.MAV_FRAME_MISSION}
NAV_COMMANDS = frozenset(
    {
        mavlink.MAV_CMD_NAV_WAYPOINT,
        mavlink.MAV_CMD_NAV_LOITER_UNLIM,
        mavlink.MAV_CMD_NAV_LOITER_TIME,
        mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
        mavlink.MAV_CMD_NAV_LAND,
        mavlink.MAV_CMD_NAV_TAKEOFF,
    }
)
"""The navigation commands the mock flies; each has a location (RTL: home)."""


@dataclass(frozen=True)
class MissionItem:
    """A MISSION_ITEM_INT's content: x/y are degE7 in global frames, z is metres."""

    seq: int
    frame: int
    command: int
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    autocontinue: int = 1
    current: int = 0
    mission_type: int = mavlink.MAV_MISSION_TYPE_MISSION

    @property
    def lat(self) -> float:
        return self.x / 1e7

    @property
    def lon(self) -> float:
        return self.y / 1e7

    @property
    def has_position(self) -> bool:
        return self.frame in GLOBAL_FRAMES and (self.x != 0 or self.y != 0)

    @classmethod
    def from_message(cls, msg: Message) -> MissionItem:
        """From MISSION_ITEM_INT, or legacy MISSION_ITEM (float degrees scaled to degE7)."""
        scale = 1e7 if msg.get_type() == "MISSION_ITEM" and msg.frame in GLOBAL_FRAMES else 1
        return cls(
            seq=msg.seq,
            frame=msg.frame,
            command=msg.command,
            param1=msg.param1,
            param2=msg.param2,
            param3=msg.param3,
            param4=msg.param4,
            x=round(msg.x * scale),
            y=round(msg.y * scale),
            z=msg.z,
            autocontinue=msg.autocontinue,
            current=msg.current,
            mission_type=getattr(msg, "mission_type", 0),
        )

    def with_seq(self, seq: int) -> MissionItem:
        return replace(self, seq=seq)

    def to_item_int(self, target_system: int, target_component: int) -> Message:
        return mavlink.MAVLink_mission_item_int_message(
            target_system,
            target_component,
            self.seq,
            self.frame,
            self.command,
            self.current,
            self.autocontinue,
            self.param1,
            self.param2,
            self.param3,
            self.param4,
            self.x,
            self.y,
            self.z,
            self.mission_type,
        )

    def to_item(self, target_system: int, target_component: int) -> Message:
        scale = 1e-7 if self.frame in GLOBAL_FRAMES else 1.0
        return mavlink.MAVLink_mission_item_message(
            target_system,
            target_component,
            self.seq,
            self.frame,
            self.command,
            self.current,
            self.autocontinue,
            self.param1,
            self.param2,
            self.param3,
            self.param4,
            self.x * scale,
            self.y * scale,
            self.z,
            self.mission_type,
        )


def same_item(a: MissionItem, b: MissionItem) -> bool:
    """Field-by-field equality in which NaN equals NaN (a re-sent item carries the same NaNs)."""
    return all(
        x == y
        or (isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y))
        for x, y in zip(astuple(a), astuple(b), strict=True)
    )
