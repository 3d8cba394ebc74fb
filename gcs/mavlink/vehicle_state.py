"""The live picture of one vehicle, kept up to date from the messages it sends.

Everything here is a plain value that a display or the service can copy at any
moment; the link updates it, nothing else writes it.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.modes import mode_name

MAV_STATE_BOOT: int = mavlink2.MAV_STATE_BOOT
MAV_MODE_FLAG_SAFETY_ARMED = mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
ARM_NEWS_S = 1.0
"""A HEARTBEAT heard sooner than this after an ARM was sent may have left the vehicle
before the ARM arrived (latency, a retry's first copy lost): it does not say "disarmed"."""


class LandedState(IntEnum):
    """MAV_LANDED_STATE of EXTENDED_SYS_STATE."""

    UNDEFINED = mavlink2.MAV_LANDED_STATE_UNDEFINED
    ON_GROUND = mavlink2.MAV_LANDED_STATE_ON_GROUND
    IN_AIR = mavlink2.MAV_LANDED_STATE_IN_AIR
    TAKEOFF = mavlink2.MAV_LANDED_STATE_TAKEOFF
    LANDING = mavlink2.MAV_LANDED_STATE_LANDING


class MissionState(IntEnum):
    """MISSION_CURRENT.mission_state."""

    UNKNOWN = mavlink2.MISSION_STATE_UNKNOWN
    NO_MISSION = mavlink2.MISSION_STATE_NO_MISSION
    NOT_STARTED = mavlink2.MISSION_STATE_NOT_STARTED
    ACTIVE = mavlink2.MISSION_STATE_ACTIVE
    PAUSED = mavlink2.MISSION_STATE_PAUSED
    COMPLETE = mavlink2.MISSION_STATE_COMPLETE


@dataclass
class Position:
    lat: float  # degrees
    lon: float
    relative_alt_m: float
    alt_amsl_m: float
    time_boot_ms: int = 0  # the vehicle's own clock when it was there


@dataclass
class VehicleState:
    sysid: int
    autopilot: int
    vehicle_type: int = 0
    position: Position | None = None
    heading_deg: float = 0.0
    groundspeed_m_s: float = 0.0
    velocity_n_e_m_s: tuple[float, float] = (0.0, 0.0)
    custom_mode: int = 0
    mode: str = ""
    armed: bool = False
    system_status: int = 0
    landed_state: int = LandedState.UNDEFINED
    gps_fix_type: int = 0
    home: Position | None = None
    mission_seq: int = 0
    mission_total: int = 0
    mission_state: int = MissionState.UNKNOWN
    reached: set[int] = field(default_factory=set)
    last_reached: int | None = None
    time_boot_ms: int = 0
    position_heard: float | None = None  # loop time of the last GLOBAL_POSITION_INT
    last_heard: float = 0.0  # loop time of the last message
    heartbeat_heard: float | None = None  # loop time of the last HEARTBEAT
    arm_sent: float | None = None  # loop time this ground station last sent it an ARM
    link_up: bool = False
    reboots: int = 0
    statustexts: deque[tuple[float, int, str]] = field(default_factory=lambda: deque(maxlen=20))

    @property
    def airborne(self) -> bool:
        if self.landed_state != LandedState.UNDEFINED:
            return self.landed_state in (
                LandedState.IN_AIR,
                LandedState.TAKEOFF,
                LandedState.LANDING,
            )
        alt = self.position.relative_alt_m if self.position else 0.0
        return self.armed and alt > 0.5

    @property
    def booting(self) -> bool:
        """The autopilot says it is still starting up (HEARTBEAT system_status BOOT)."""
        return self.system_status == MAV_STATE_BOOT

    @property
    def arm_unconfirmed(self) -> bool:
        """An ARM was sent and no HEARTBEAT since says what came of it: the vehicle may
        be armed, even taking off, while its last HEARTBEAT still says disarmed (fuzzed
        flight 7773: a hold during the start took a climbing vehicle for on the ground)."""
        if self.arm_sent is None:
            return False
        return self.heartbeat_heard is None or self.heartbeat_heard < self.arm_sent + ARM_NEWS_S

    @property
    def down(self) -> bool:
        """Disarmed on the ground, as far as the vehicle last said (and it said lately,
        since any ARM sent to it)."""
        return self.link_up and not self.armed and not self.airborne and not self.arm_unconfirmed

    def recent_text(self, since: float) -> str:
        """The STATUSTEXTs heard since loop time `since`, joined (for error messages)."""
        return "; ".join(text for t, _, text in self.statustexts if t >= since)

    def apply(self, msg: Any, now: float) -> None:
        """Fold one message from the vehicle's autopilot into the state."""
        self.last_heard = now
        boot = getattr(msg, "time_boot_ms", None)
        if boot is not None:
            self.time_boot_ms = boot
        update = _UPDATES.get(msg.get_type())
        if update is not None:
            update(self, msg, now)


def _heartbeat(s: VehicleState, m: Any, now: float) -> None:
    s.heartbeat_heard = now
    s.vehicle_type = m.type
    s.custom_mode = m.custom_mode
    s.mode = mode_name(s.autopilot, m.custom_mode)
    s.armed = bool(m.base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
    s.system_status = m.system_status


def _global_position(s: VehicleState, m: Any, now: float) -> None:
    s.position_heard = now
    if m.lat == 0 and m.lon == 0:
        return  # no position origin yet (ArduPilot before its EKF has one)
    s.position = Position(
        m.lat / 1e7, m.lon / 1e7, m.relative_alt / 1000.0, m.alt / 1000.0, m.time_boot_ms
    )
    s.velocity_n_e_m_s = (m.vx / 100.0, m.vy / 100.0)
    s.groundspeed_m_s = (m.vx**2 + m.vy**2) ** 0.5 / 100.0
    if m.hdg != 65535:
        s.heading_deg = m.hdg / 100.0


def _home(s: VehicleState, m: Any, now: float) -> None:
    s.home = Position(m.latitude / 1e7, m.longitude / 1e7, 0.0, m.altitude / 1000.0)


def _mission_current(s: VehicleState, m: Any, now: float) -> None:
    s.mission_seq = m.seq
    s.mission_total = getattr(m, "total", 0)
    s.mission_state = getattr(m, "mission_state", MissionState.UNKNOWN)


def _item_reached(s: VehicleState, m: Any, now: float) -> None:
    s.reached.add(m.seq)  # a set: PX4 repeats MISSION_ITEM_REACHED
    s.last_reached = m.seq


def _extended_sys_state(s: VehicleState, m: Any, now: float) -> None:
    s.landed_state = m.landed_state


def _gps(s: VehicleState, m: Any, now: float) -> None:
    s.gps_fix_type = m.fix_type


def _vfr_hud(s: VehicleState, m: Any, now: float) -> None:
    s.groundspeed_m_s = m.groundspeed
    s.heading_deg = float(m.heading)


def _statustext(s: VehicleState, m: Any, now: float) -> None:
    text = m.text if isinstance(m.text, str) else bytes(m.text).decode(errors="replace")
    s.statustexts.append((now, m.severity, text.rstrip("\x00")))


_UPDATES = {
    "HEARTBEAT": _heartbeat,
    "GLOBAL_POSITION_INT": _global_position,
    "HOME_POSITION": _home,
    "MISSION_CURRENT": _mission_current,
    "MISSION_ITEM_REACHED": _item_reached,
    "EXTENDED_SYS_STATE": _extended_sys_state,
    "GPS_RAW_INT": _gps,
    "VFR_HUD": _vfr_hud,
    "STATUSTEXT": _statustext,
}
