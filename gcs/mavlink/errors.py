"""What can go wrong between the ground station and a vehicle, as typed exceptions.

Every error says which vehicle, what was asked and what the vehicle answered, so that
a caller (the fleet, the service, the terminal) can show it without further context.
"""

from __future__ import annotations

from enum import IntEnum


class MissionResult(IntEnum):
    """MAV_MISSION_RESULT, the `type` of MISSION_ACK."""

    ACCEPTED = 0
    ERROR = 1
    UNSUPPORTED_FRAME = 2
    UNSUPPORTED = 3
    NO_SPACE = 4
    INVALID = 5
    INVALID_PARAM1 = 6
    INVALID_PARAM2 = 7
    INVALID_PARAM3 = 8
    INVALID_PARAM4 = 9
    INVALID_PARAM5_X = 10
    INVALID_PARAM6_Y = 11
    INVALID_PARAM7 = 12
    INVALID_SEQUENCE = 13
    DENIED = 14
    OPERATION_CANCELLED = 15


class CommandResult(IntEnum):
    """MAV_RESULT, the `result` of COMMAND_ACK (the ones a GCS acts on)."""

    ACCEPTED = 0
    TEMPORARILY_REJECTED = 1
    DENIED = 2
    UNSUPPORTED = 3
    FAILED = 4
    IN_PROGRESS = 5
    CANCELLED = 6


class GcsError(Exception):
    """Base of every error the ground station raises about a vehicle."""


# --- the link --------------------------------------------------------------------------


class LinkError(GcsError):
    """The connection itself failed (bad connection string, refused, closed)."""


class ConnectTimeoutError(LinkError):
    """No autopilot HEARTBEAT arrived within the bound."""


class LinkLostError(LinkError):
    """The vehicle went silent for longer than the link timeout."""


class VehicleRebootedError(LinkError):
    """The vehicle rebooted: whatever was in flight between us is gone."""


class WaitTimeoutError(GcsError, TimeoutError):
    """An awaited message did not arrive within its bound."""


# --- the mission protocol --------------------------------------------------------------


class MissionTransferError(GcsError):
    """An upload, download, clear or set-current did not complete."""


class MissionTimeoutError(MissionTransferError, TimeoutError):
    """The vehicle stopped answering and every retry of the step was spent."""


class MissionMismatchError(MissionTransferError):
    """The mission read back after an upload differs from what was sent."""

    def __init__(self, sysid: int, seq: int, detail: str) -> None:
        super().__init__(f"vehicle {sysid}: mission read back differs at seq {seq}: {detail}")
        self.sysid = sysid
        self.seq = seq


class MissionRejectedError(MissionTransferError):
    """The vehicle ended a transfer with a MISSION_ACK other than ACCEPTED."""

    reason = "the vehicle refused the mission"
    definitive = True  # retrying the same request cannot help

    def __init__(self, sysid: int, result: int, operation: str, seq: int | None = None) -> None:
        where = f" at item seq {seq}" if seq is not None else ""
        name = _result_name(result)
        super().__init__(f"vehicle {sysid} refused the {operation}{where}: {name}: {self.reason}")
        self.sysid = sysid
        self.result = result
        self.operation = operation
        self.seq = seq


class MissionGenericError(MissionRejectedError):
    reason = "generic error, the vehicle gave no reason"
    definitive = False


class UnsupportedFrameError(MissionRejectedError):
    reason = "the coordinate frame is not supported"


class UnsupportedCommandError(MissionRejectedError):
    reason = "the command is not supported"


class NoSpaceError(MissionRejectedError):
    reason = "the mission has more items than the vehicle can store"


class InvalidMissionError(MissionRejectedError):
    reason = "one of the parameters has an invalid value"


class InvalidParamError(MissionRejectedError):
    """INVALID_PARAM1..7; `param` is the 1-based parameter the vehicle refused."""

    def __init__(self, sysid: int, result: int, operation: str, seq: int | None = None) -> None:
        self.param = result - MissionResult.INVALID_PARAM1 + 1
        label = {5: "param5 (x, latitude)", 6: "param6 (y, longitude)", 7: "param7 (altitude)"}
        self.reason = f"{label.get(self.param, f'param{self.param}')} has an invalid value"
        super().__init__(sysid, result, operation, seq)


class InvalidSequenceError(MissionRejectedError):
    reason = "an item arrived out of sequence"
    definitive = False


class MissionDeniedError(MissionRejectedError):
    reason = "not accepting missions now (another ground station may be mid-transfer)"


class MissionCancelledError(MissionRejectedError):
    reason = "the vehicle cancelled the transfer (it timed out waiting for us)"
    definitive = False


_MISSION_ERRORS: dict[int, type[MissionRejectedError]] = {
    MissionResult.ERROR: MissionGenericError,
    MissionResult.UNSUPPORTED_FRAME: UnsupportedFrameError,
    MissionResult.UNSUPPORTED: UnsupportedCommandError,
    MissionResult.NO_SPACE: NoSpaceError,
    MissionResult.INVALID: InvalidMissionError,
    **{r: InvalidParamError for r in range(MissionResult.INVALID_PARAM1, 13)},
    MissionResult.INVALID_SEQUENCE: InvalidSequenceError,
    MissionResult.DENIED: MissionDeniedError,
    MissionResult.OPERATION_CANCELLED: MissionCancelledError,
}


def mission_error(
    sysid: int, result: int, operation: str, seq: int | None = None
) -> MissionRejectedError:
    """The typed error for a MISSION_ACK result other than ACCEPTED."""
    cls = _MISSION_ERRORS.get(result, MissionRejectedError)
    return cls(sysid, result, operation, seq)


def _result_name(result: int) -> str:
    try:
        return MissionResult(result).name
    except ValueError:
        return f"result {result}"


# --- commands --------------------------------------------------------------------------


class CommandError(GcsError):
    """A COMMAND_LONG/INT the vehicle did not carry out."""

    def __init__(
        self, sysid: int, command: int, result: int | None, statustext: str = "", detail: str = ""
    ) -> None:
        name = _command_name(command)
        outcome = detail or (CommandResult(result).name if result in _RESULTS else f"{result}")
        why = f": {statustext}" if statustext else ""
        super().__init__(f"vehicle {sysid}: {name} {outcome}{why}")
        self.sysid = sysid
        self.command = command
        self.result = result
        self.statustext = statustext


class CommandTemporarilyRejectedError(CommandError):
    """The vehicle may accept the command later (e.g. not ready yet)."""


class CommandDeniedError(CommandError):
    """The vehicle refuses the command in its current state."""


class CommandUnsupportedError(CommandError):
    """The vehicle does not know the command."""


class CommandFailedError(CommandError):
    """The vehicle tried and failed (arming checks: "PreArm: ..." in `statustext`)."""


class CommandTimeoutError(CommandError, TimeoutError):
    """No COMMAND_ACK after every retry."""


_RESULTS = {r.value for r in CommandResult}
_COMMAND_ERRORS: dict[int, type[CommandError]] = {
    CommandResult.TEMPORARILY_REJECTED: CommandTemporarilyRejectedError,
    CommandResult.DENIED: CommandDeniedError,
    CommandResult.UNSUPPORTED: CommandUnsupportedError,
    CommandResult.FAILED: CommandFailedError,
    CommandResult.CANCELLED: CommandFailedError,
}


def command_error(sysid: int, command: int, result: int, statustext: str = "") -> CommandError:
    """The typed error for a COMMAND_ACK result other than ACCEPTED or IN_PROGRESS."""
    return _COMMAND_ERRORS.get(result, CommandError)(sysid, command, result, statustext)


_COMMAND_NAMES = {
    16: "NAV_WAYPOINT",
    20: "NAV_RETURN_TO_LAUNCH",
    21: "NAV_LAND",
    22: "NAV_TAKEOFF",
    176: "DO_SET_MODE",
    193: "DO_PAUSE_CONTINUE",
    224: "DO_SET_MISSION_CURRENT",
    246: "PREFLIGHT_REBOOT_SHUTDOWN",
    300: "MISSION_START",
    400: "COMPONENT_ARM_DISARM",
    511: "SET_MESSAGE_INTERVAL",
    512: "REQUEST_MESSAGE",
}


def _command_name(command: int) -> str:
    return _COMMAND_NAMES.get(command, f"command {command}")


# --- flying ----------------------------------------------------------------------------


class FlightError(GcsError):
    """A vehicle could not be brought to, or kept in, the state the flight needs."""
