"""COMMAND_LONG / COMMAND_INT / SET_MODE handling: one method per command, each returning
the MAV_RESULT a real autopilot gives, plus messages to send after the COMMAND_ACK.

Refusal faults (`Faults.fail_arming`, `refuse_takeoff`, `refuse_commands`) are applied
here, before a command reaches the flight controller. A command re-sent with a higher
`confirmation` is carried out again, as ArduPilot does (it never reads the field): a
take-off re-sent once the vehicle lifts off is refused, as flying already.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

from .codec import Message, Sender, mavlink
from .faults import Faults
from .flight import ACCEPTED, FAILED, FlightController
from .mission_store import MissionStore
from .modes import FlightMode
from .telemetry import TelemetrySchedule

UNSUPPORTED: int = mavlink.MAV_RESULT_UNSUPPORTED
FORCE_MAGIC = 21196
FAULT_ARMING_TEXT = "Arm: Hardware safety switch"
"""A real ArduPilot refusal that can come at any time (the safety switch), for `fail_arming`."""
FAULT_TAKEOFF_TEXT = "Takeoff refused"
FORCE_REBOOT_MAGIC = 20190226
"""param6 that lets ArduPilot reboot while armed (`handle_preflight_reboot`)."""
REBOOT_AUTOPILOT = frozenset({1, 3})
TAKEOFF_COMMANDS = frozenset({mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_CMD_MISSION_START})
AUTOPILOT_VERSION = mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION
HOME_POSITION = mavlink.MAVLINK_MSG_ID_HOME_POSITION


@dataclass(frozen=True)
class Command:
    id: int
    params: tuple[float, ...]
    """param1..param7; COMMAND_INT's x, y arrive as degE7 integers in params[4:6]."""
    sender: Sender

    @classmethod
    def from_message(cls, msg: Message, sender: Sender) -> Command:
        if msg.get_type() == "COMMAND_INT":
            params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z)
            return cls(msg.command, params, sender)
        params = (
            msg.param1,
            msg.param2,
            msg.param3,
            msg.param4,
            msg.param5,
            msg.param6,
            msg.param7,
        )
        return cls(msg.command, params, sender)


@dataclass
class Outcome:
    result: int
    then: list[int] = field(default_factory=list)
    """Message ids to send after the ACK (REQUEST_MESSAGE)."""
    reboot: bool = False
    """Reboot once the ACK is out (PREFLIGHT_REBOOT_SHUTDOWN)."""


def _whole(param: float) -> int:
    """A param as an integer; NaN (how MAVSDK leaves a PX4 command's unused params) is 0."""
    return round(param) if math.isfinite(param) else 0


_Handler = Callable[["CommandHandler", tuple[float, ...], float], Outcome]


class CommandHandler:
    """Maps commands to the flight controller, mission store and telemetry schedule."""

    def __init__(
        self,
        flight: FlightController,
        store: MissionStore,
        schedule: TelemetrySchedule,
        current_changed: Callable[[], None],
        faults: Callable[[], Faults] = Faults,
        say: Callable[[int, str], None] = lambda severity, text: None,
    ) -> None:
        self._flight = flight
        self._store = store
        self._schedule = schedule
        self._current_changed = current_changed
        self._faults = faults
        self._say = say

    def handle(self, command: Command, now: float) -> Outcome:
        """Answer a command at simulated time `now`."""
        return self._refused(command) or self._carry_out(command, now)

    def _carry_out(self, command: Command, now: float) -> Outcome:
        handler = self._handlers.get(command.id)
        return Outcome(UNSUPPORTED) if handler is None else handler(self, command.params, now)

    def _refused(self, command: Command) -> Outcome | None:
        """The answer a refusal fault gives this command, if one applies."""
        faults, command_id = self._faults(), command.id
        if command_id in faults.refuse_commands:
            return Outcome(faults.refuse_result)
        arming = (
            command_id == mavlink.MAV_CMD_COMPONENT_ARM_DISARM and _whole(command.params[0]) == 1
        )
        if arming and faults.fail_arming and not self._flight.armed:
            self._say(mavlink.MAV_SEVERITY_CRITICAL, FAULT_ARMING_TEXT)
            return Outcome(FAILED)
        if command_id in TAKEOFF_COMMANDS and faults.refuse_takeoff and self._flight.armed:
            self._say(mavlink.MAV_SEVERITY_CRITICAL, FAULT_TAKEOFF_TEXT)
            return Outcome(FAILED)
        return None

    def set_mode(self, base_mode: int, custom_mode: int, now: float) -> int:
        """SET_MODE message (and DO_SET_MODE): only custom modes are understood."""
        if not base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return FAILED
        mode = self._flight.flavour.modes.mode(custom_mode)
        return FAILED if mode is None else self._flight.set_mode(mode, now)

    # -- one method per command ------------------------------------------------------------

    def _arm_disarm(self, p: tuple[float, ...], now: float) -> Outcome:
        force = _whole(p[1]) == FORCE_MAGIC
        if _whole(p[0]) == 1:
            return Outcome(self._flight.arm(now, force))
        return Outcome(self._flight.disarm(now, force))

    def _do_set_mode(self, p: tuple[float, ...], now: float) -> Outcome:
        custom = _whole(p[1])
        if self._flight.flavour.name == "px4":
            custom = (_whole(p[1]) << 16) | (_whole(p[2]) << 24)
        return Outcome(self.set_mode(_whole(p[0]), custom, now))

    def _takeoff(self, p: tuple[float, ...], now: float) -> Outcome:
        alt = p[6]
        if self._flight.flavour.name == "px4":  # PX4's param7 is AMSL; NaN means default
            alt = math.nan if math.isnan(alt) else alt - self._flight.home.alt_amsl
            if math.isnan(alt):
                alt = self._flight.params.get("MIS_TAKEOFF_ALT")
        return Outcome(self._flight.takeoff(alt, now))

    def _mission_start(self, p: tuple[float, ...], now: float) -> Outcome:
        return Outcome(self._flight.start_mission(now))

    def _change_speed(self, p: tuple[float, ...], now: float) -> Outcome:
        return Outcome(self._flight.change_speed(p[1]))

    def _pause_continue(self, p: tuple[float, ...], now: float) -> Outcome:
        if _whole(p[0]) == 0:
            return Outcome(self._flight.pause(now))
        return Outcome(self._flight.resume(now))

    def _return_to_launch(self, p: tuple[float, ...], now: float) -> Outcome:
        return Outcome(self._flight.set_mode(FlightMode.RTL, now))

    def _land(self, p: tuple[float, ...], now: float) -> Outcome:
        return Outcome(self._flight.set_mode(FlightMode.LAND, now))

    def _set_mission_current(self, p: tuple[float, ...], now: float) -> Outcome:
        if not self._store.set_current(_whole(p[0])):
            return Outcome(FAILED)
        self._current_changed()
        return Outcome(ACCEPTED)

    def _request_message(self, p: tuple[float, ...], now: float) -> Outcome:
        msg_id = _whole(p[0])
        if msg_id == HOME_POSITION and not self._flight.home_set(now):
            return Outcome(FAILED)  # no home until the position estimate has an origin
        if msg_id == AUTOPILOT_VERSION or self._schedule.can_stream(msg_id):
            return Outcome(ACCEPTED, [msg_id])
        return Outcome(FAILED)

    def _reboot(self, p: tuple[float, ...], now: float) -> Outcome:
        """PREFLIGHT_REBOOT_SHUTDOWN as ArduPilot answers it: armed needs the magic param6."""
        if self._flight.armed and _whole(p[5]) != FORCE_REBOOT_MAGIC:
            return Outcome(FAILED)
        if _whole(p[0]) not in REBOOT_AUTOPILOT:
            return Outcome(UNSUPPORTED)
        return Outcome(ACCEPTED, reboot=True)

    def _request_capabilities(self, p: tuple[float, ...], now: float) -> Outcome:
        return Outcome(ACCEPTED, [AUTOPILOT_VERSION])

    def _set_message_interval(self, p: tuple[float, ...], now: float) -> Outcome:
        ok = self._schedule.set_message_interval(_whole(p[0]), p[1], now)
        return Outcome(ACCEPTED if ok else FAILED)

    _handlers: ClassVar[dict[int, _Handler]] = {
        mavlink.MAV_CMD_COMPONENT_ARM_DISARM: _arm_disarm,
        mavlink.MAV_CMD_DO_SET_MODE: _do_set_mode,
        mavlink.MAV_CMD_NAV_TAKEOFF: _takeoff,
        mavlink.MAV_CMD_MISSION_START: _mission_start,
        mavlink.MAV_CMD_DO_CHANGE_SPEED: _change_speed,
        mavlink.MAV_CMD_DO_PAUSE_CONTINUE: _pause_continue,
        mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH: _return_to_launch,
        mavlink.MAV_CMD_NAV_LAND: _land,
        mavlink.MAV_CMD_DO_SET_MISSION_CURRENT: _set_mission_current,
        mavlink.MAV_CMD_REQUEST_MESSAGE: _request_message,
        mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: _request_capabilities,
        mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN: _reboot,
        mavlink.MAV_CMD_SET_MESSAGE_INTERVAL: _set_message_interval,
    }
