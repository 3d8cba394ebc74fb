"""One vehicle at one instant: what telemetry reports and what tests inspect."""

from __future__ import annotations

from dataclasses import dataclass


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

    @property
    def ground_speed(self) -> float:
        north, east, _ = self.velocity_ned
        return (north**2 + east**2) ** 0.5
