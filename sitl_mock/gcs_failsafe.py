"""ArduCopter's GCS failsafe: what a vehicle does once its ground station falls silent.

As `Copter::failsafe_gcs_check` and `failsafe_gcs_on_event` (ArduCopter 4.8): only the
HEARTBEATs of the system `MAV_GCS_SYSID` count; nothing happens before the first one, or
while `FS_GCS_ENABLE` is 0. Silent for longer than `FS_GCS_TIMEOUT` seconds (of the
vehicle's clock), the vehicle takes the action `FS_GCS_ENABLE` names, once: disarmed, it
only says so; on the ground, it disarms; landing with `FS_OPTIONS` bit 3, in AUTO with
bit 1, or in a pilot's mode with bit 4 (the default), it goes on. Heard again, the
failsafe clears, and the vehicle stays in the mode it took: only a ground station brings
it back.
"""

from __future__ import annotations

from collections.abc import Callable

from .codec import mavlink
from .flight import ACCEPTED, FlightController
from .mission_runner import MissionState
from .modes import FlightMode
from .params import ParameterSet

CONTINUE_IF_AUTO = 1 << 1
CONTINUE_IF_LANDING = 1 << 3
CONTINUE_IF_PILOT_CONTROL = 1 << 4
PILOT_CONTROLLED = frozenset({FlightMode.STABILIZE, FlightMode.LOITER})
"""The simulated modes that are not `is_autopilot()` in ArduCopter."""
DEFAULT_TIMEOUT_S = 5.0
"""Before FS_GCS_TIMEOUT (ArduCopter 4.2 and older) the timeout was fixed at 5 s."""
RTL_OR_LAND = (FlightMode.RTL, FlightMode.LAND)
ACTIONS: dict[int, tuple[FlightMode, ...]] = {
    5: (FlightMode.LAND,),
    7: (FlightMode.BRAKE, FlightMode.LAND),
}
"""FS_GCS_ENABLE -> the modes tried in turn; any other value RTL_OR_LAND (1 and 2 RTL, 3, 4
and 6 RTL too: SmartRTL and DO_LAND_START are not simulated; unknown values RTL)."""


class GcsFailsafe:
    def __init__(
        self, flight: FlightController, params: ParameterSet, say: Callable[[int, str], None]
    ) -> None:
        self._flight = flight
        self._params = params
        self._say = say
        self._heard_at: float | None = None
        self.active = False

    def reset(self) -> None:
        """A reboot: no ground station heard yet."""
        self._heard_at, self.active = None, False

    def heard(self, sysid: int, now: float) -> None:
        """A HEARTBEAT from `sysid`."""
        if "MAV_GCS_SYSID" in self._params and sysid == self._params.get("MAV_GCS_SYSID"):
            self._heard_at = now

    def check(self, now: float) -> None:
        if self._heard_at is None or not self._enabled():
            return
        silent = now - self._heard_at > self._timeout_s()
        if silent and not self.active:
            self.active = True
            self._on_event(now)
        elif not silent and self.active:
            self.active = False
            self._say(mavlink.MAV_SEVERITY_WARNING, "GCS Failsafe Cleared")

    def _enabled(self) -> bool:
        return "FS_GCS_ENABLE" in self._params and self._params.get("FS_GCS_ENABLE") != 0

    def _timeout_s(self) -> float:
        if "FS_GCS_TIMEOUT" in self._params:
            return self._params.get("FS_GCS_TIMEOUT")
        return DEFAULT_TIMEOUT_S

    def _option(self, bit: int) -> bool:
        return "FS_OPTIONS" in self._params and int(self._params.get("FS_OPTIONS")) & bit != 0

    def _on_event(self, now: float) -> None:
        flight = self._flight
        if not flight.armed:
            self._announce()
            return
        if self._on_the_ground():
            flight.disarm(now, force=True)
            self._announce("Disarming")
            return
        if flight.landed_state == mavlink.MAV_LANDED_STATE_LANDING and self._option(
            CONTINUE_IF_LANDING
        ):
            self._announce("Continuing Landing")
            return
        if flight.mode == FlightMode.AUTO and self._option(CONTINUE_IF_AUTO):
            self._announce("Continuing Auto Mode")
            return
        if flight.mode in PILOT_CONTROLLED and self._option(CONTINUE_IF_PILOT_CONTROL):
            self._announce("Continuing Pilot Control")
            return
        self._announce()
        tries = ACTIONS.get(int(self._params.get("FS_GCS_ENABLE")), RTL_OR_LAND)
        for mode in tries:
            if flight.set_mode(mode, now) == ACCEPTED:
                return

    def _on_the_ground(self) -> bool:
        """Copter::should_disarm_on_failsafe: landed, and in AUTO its mission not begun."""
        flight = self._flight
        if flight.airborne:
            return False
        return flight.mode != FlightMode.AUTO or flight.runner.state != MissionState.ACTIVE

    def _announce(self, action: str | None = None) -> None:
        text = "GCS Failsafe" if action is None else f"GCS Failsafe - {action}"
        self._say(mavlink.MAV_SEVERITY_WARNING, text)
