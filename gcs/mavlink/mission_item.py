"""One MAVLink mission item as the ground station holds it, independent of the wire.

Items carry no sequence number and no `current` flag: those belong to the transfer
(`mission_protocol`) and the file formats, which number items by position. Latitude
and longitude are integers in degE7, as MISSION_ITEM_INT carries them, so that a
round trip through the vehicle compares exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2


class Frame(IntEnum):
    """The MAV_FRAMEs the ground station writes or reads back (pymavlink's numbers)."""

    GLOBAL = mavlink2.MAV_FRAME_GLOBAL  # ArduPilot's home item (seq 0); DO items read back
    MISSION = mavlink2.MAV_FRAME_MISSION  # for DO_ commands, which have no position
    GLOBAL_RELATIVE_ALT = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT
    GLOBAL_RELATIVE_ALT_INT = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


class Command(IntEnum):
    """The MAV_CMDs a mission of ours holds."""

    NAV_WAYPOINT = mavlink2.MAV_CMD_NAV_WAYPOINT
    NAV_LOITER_TIME = mavlink2.MAV_CMD_NAV_LOITER_TIME
    NAV_RETURN_TO_LAUNCH = mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH
    NAV_LAND = mavlink2.MAV_CMD_NAV_LAND
    NAV_TAKEOFF = mavlink2.MAV_CMD_NAV_TAKEOFF
    DO_CHANGE_SPEED = mavlink2.MAV_CMD_DO_CHANGE_SPEED


class Autopilot(IntEnum):
    """The HEARTBEAT's autopilot field; it decides whether item 0 is home."""

    ARDUPILOT = mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA
    PX4 = mavlink2.MAV_AUTOPILOT_PX4

    @classmethod
    def of(cls, value: int) -> Autopilot:
        """The flavour a HEARTBEAT names; ArduPilot's conventions for anything else."""
        return cls(value) if value in cls._value2member_map_ else cls.ARDUPILOT


@dataclass(frozen=True, slots=True)
class MissionItem:
    command: int
    frame: int = Frame.GLOBAL_RELATIVE_ALT_INT
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    x: int = 0  # latitude, degE7
    y: int = 0  # longitude, degE7
    z: float = 0.0  # altitude, metres (relative to home in frame 6)
    autocontinue: bool = True

    @property
    def lat(self) -> float:
        return self.x / 1e7

    @property
    def lon(self) -> float:
        return self.y / 1e7

    def same_as(self, other: MissionItem) -> bool:
        """Equal as a vehicle stores it: params and z travel as float32, NaN equals NaN."""
        return (
            int(self.command) == int(other.command)
            and int(self.frame) == int(other.frame)
            and (self.x, self.y) == (other.x, other.y)
            and bool(self.autocontinue) == bool(other.autocontinue)
            and all(_same_f32(a, b) for a, b in zip(self.params, other.params, strict=True))
            and _same_f32(self.z, other.z)
        )


def _same_f32(a: float, b: float) -> bool:
    fa, fb = np.float32(a), np.float32(b)
    return bool((math.isnan(fa) and math.isnan(fb)) or fa == fb)


@dataclass(frozen=True, slots=True)
class Mission:
    """The items of one vehicle in upload order (item 0 is home for ArduPilot)."""

    items: tuple[MissionItem, ...]
    autopilot: Autopilot = Autopilot.ARDUPILOT
    home: tuple[float, float, float] | None = field(default=None)  # lat, lon, AMSL m

    def __len__(self) -> int:
        return len(self.items)

    def first_differing(self, other: Mission | tuple[MissionItem, ...]) -> int | None:
        """The first seq at which `other` differs from this mission, None when it matches.

        ArduPilot replaces item 0 with its current home on download, so for that flavour
        seq 0 is not compared.
        """
        theirs = other.items if isinstance(other, Mission) else other
        if len(theirs) != len(self.items):
            return min(len(theirs), len(self.items))
        start = 1 if self.autopilot == Autopilot.ARDUPILOT else 0
        for seq in range(start, len(self.items)):
            if not self.items[seq].same_as(theirs[seq]):
                return seq
        return None
