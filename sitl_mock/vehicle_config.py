"""How to start one simulated vehicle: identity, place, autopilot, sockets, readiness, key."""

from __future__ import annotations

import secrets
from dataclasses import dataclass, field

from .faults import Faults
from .flavour import FLAVOURS, Flavour
from .mission_store import DEFAULT_CAPACITY
from .readiness import Timeline
from .transport import parse_output

DEFAULT_HOME = (47.3977, 8.5456, 488.0)
PX4_ESTIMATE_S = 5.0
TRANSPORTS = ("udp", "tcp", "memory")
KEY_BYTES = 32
BOARD_ID_BYTES = 8


@dataclass
class VehicleConfig:
    """How to start one vehicle. `port=0` lets the OS pick a free port."""

    sysid: int
    port: int = 0
    home: tuple[float, float, float] = DEFAULT_HOME
    """lat, lon (degrees), alt (metres AMSL)."""
    autopilot: str = "ardupilot"
    transport: str = "udp"
    """The vehicle's own server: "udp" (answers whoever speaks first), "tcp" (as SITL) or
    "memory" (no socket: clients connect through `Simulator.memory_port`, on one loop)."""
    faults: Faults = field(default_factory=Faults)
    mission_capacity: int = DEFAULT_CAPACITY
    estimate_delay_s: float | None = None
    """Simulated seconds after boot until arming in GUIDED/AUTO works (default: ArduCopter's
    41.5 s, PX4's 5 s)."""
    position_delay_s: float | None = None
    """Simulated seconds after boot until the EKF origin and home are set (default 20 s,
    never after `estimate_delay_s`)."""
    signing_key: bytes | None = None
    """A 32-byte MAVLink 2 signing key: sign everything sent, accept only signed packets."""
    outputs: tuple[str, ...] = ()
    """`udp:HOST:PORT` ground stations to send to, as MAVProxy's --out (shared by vehicles)."""
    board_id: bytes = field(default_factory=lambda: secrets.token_bytes(BOARD_ID_BYTES))
    """The flight controller's unique id, reported in AUTOPILOT_VERSION (ArduPilot's `uid2`,
    PX4's `uid`): each vehicle its own, so that one reached two ways is known as one."""

    def __post_init__(self) -> None:
        if not 1 <= self.sysid <= 255:
            raise ValueError(f"sysid must be in 1..255, got {self.sysid}")
        if self.autopilot not in FLAVOURS:
            raise ValueError(f"autopilot must be one of {sorted(FLAVOURS)}, got {self.autopilot!r}")
        if self.transport not in TRANSPORTS:
            raise ValueError(f"transport must be one of {TRANSPORTS}, got {self.transport!r}")
        if self.signing_key is not None and len(self.signing_key) != KEY_BYTES:
            raise ValueError(f"signing_key must be {KEY_BYTES} bytes, got {len(self.signing_key)}")
        for output in self.outputs:
            parse_output(output)
        if len(self.board_id) != BOARD_ID_BYTES or not any(self.board_id):
            raise ValueError(f"board_id must be {BOARD_ID_BYTES} bytes, not all zero")

    @property
    def flavour(self) -> Flavour:
        return FLAVOURS[self.autopilot]

    def timeline(self) -> Timeline:
        """When this vehicle gets each thing ready after a boot."""
        if self.flavour.home_is_item_zero:
            return Timeline.arducopter(self.position_delay_s, self.estimate_delay_s)
        estimate = PX4_ESTIMATE_S if self.estimate_delay_s is None else self.estimate_delay_s
        return Timeline.immediate(estimate)
