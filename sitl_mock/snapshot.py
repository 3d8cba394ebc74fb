"""One vehicle at one instant: what telemetry reports and what tests inspect."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple


class Sensors(NamedTuple):
    """SYS_STATUS onboard_control_sensors_present / _enabled / _health."""

    present: int
    enabled: int
    health: int


NO_SENSORS = Sensors(0, 0, 0)


@dataclass(frozen=True)
class VehicleState:
    sysid: int
    t: float
    """Simulated seconds."""
    uptime: float
    """Simulated seconds since the vehicle (re)booted: what time_boot_ms counts."""
    lat: float
    lon: float
    alt: float
    """Metres above home."""
    alt_amsl: float
    velocity_ned: tuple[float, float, float]
    """m/s north, east, down."""
    heading_deg: float
    armed: bool
    mode: str
    custom_mode: int
    base_mode: int
    system_status: int
    landed_state: int
    mission_seq: int
    mission_total: int
    mission_state: int
    home: tuple[float, float, float]
    """lat, lon, alt AMSL."""
    estimate_ready: bool
    """The position estimate allows arming and flying in GUIDED/AUTO."""
    position_known: bool = True
    """The GPS has a fix: GLOBAL_POSITION_INT carries latitude and longitude."""
    home_set: bool = True
    """The EKF origin and home exist: HOME_POSITION is sent."""
    sensors: Sensors = NO_SENSORS
    """SYS_STATUS present, enabled, health."""
    rejected_packets: int = 0
    """Incoming packets dropped for a missing or wrong MAVLink 2 signature."""
    holding: bool = False
    """Told to stop where it is (paused, BRAKE): what a test checks a hold by."""

    @property
    def ground_speed(self) -> float:
        north, east, _ = self.velocity_ned
        return float((north**2 + east**2) ** 0.5)
