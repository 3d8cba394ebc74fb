"""What can go wrong between the ground station and a vehicle, as typed exceptions.

Every error says which vehicle, what was asked and what the vehicle answered, so that
a caller (the fleet, the service, the terminal) can show it without further context.
"""

from __future__ import annotations

from enum import IntEnum

from pymavlink.dialects.v20 import ardupilotmega as mavlink2


class MissionResult(IntEnum):
    """MAV_MISSION_RESULT, the `type` of MISSION_ACK (pymavlink's numbers)."""

    ACCEPTED = mavlink2.MAV_MISSION_ACCEPTED
    ERROR = mavlink2.MAV_MISSION_ERROR
    UNSUPPORTED_FRAME = mavlink2.MAV_MISSION_UNSUPPORTED_FRAME
    UNSUPPORTED = mavlink2.MAV_MISSION_UNSUPPORTED
    NO_SPACE = mavlink2.MAV_MISSION_NO_SPACE
    INVALID = mavlink2.MAV_MISSION_INVALID
    INVALID_PARAM1 = mavlink2.MAV_MISSION_INVALID_PARAM1
    INVALID_PARAM2 = mavlink2.MAV_MISSION_INVALID_PARAM2
    INVALID_PARAM3 = mavlink2.MAV_MISSION_INVALID_PARAM3
    INVALID_PARAM4 = mavlink2.MAV_MISSION_INVALID_PARAM4
    INVALID_PARAM5_X = mavlink2.MAV_MISSION_INVALID_PARAM5_X
    INVALID_PARAM6_Y = mavlink2.MAV_MISSION_INVALID_PARAM6_Y
    INVALID_PARAM7 = mavlink2.MAV_MISSION_INVALID_PARAM7
    INVALID_SEQUENCE = mavlink2.MAV_MISSION_INVALID_SEQUENCE
    DENIED = mavlink2.MAV_MISSION_DENIED
    OPERATION_CANCELLED = mavlink2.MAV_MISSION_OPERATION_CANCELLED


class CommandResult(IntEnum):
    """MAV_RESULT, the `result` of COMMAND_ACK (the ones a GCS acts on)."""

    ACCEPTED = mavlink2.MAV_RESULT_ACCEPTED
    TEMPORARILY_REJECTED = mavlink2.MAV_RESULT_TEMPORARILY_REJECTED
    DENIED = mavlink2.MAV_RESULT_DENIED
    UNSUPPORTED = mavlink2.MAV_RESULT_UNSUPPORTED
    FAILED = mavlink2.MAV_RESULT_FAILED
    IN_PROGRESS = mavlink2.MAV_RESULT_IN_PROGRESS
    # MAV_RESULT_CANCELLED (6) is newer than pymavlink 2.4.50's ardupilotmega dialect.
    CANCELLED = getattr(mavlink2, "MAV_RESULT_CANCELLED", 6)


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
    **{
        r: InvalidParamError
        for r in range(MissionResult.INVALID_PARAM1, MissionResult.INVALID_PARAM7 + 1)
    },
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
        outcome = detail or _result_text(result)
        why = f": {statustext}" if statustext else ""
        super().__init__(f"vehicle {sysid}: {name} {outcome}{why}")
        self.sysid = sysid
        self.command = command
        self.result = result
        self.statustext = statustext
        self.attempts = 1  # how many times it was sent: after the first, an ACK was lost


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


def _result_text(result: int | None) -> str:
    return CommandResult(result).name if result is not None and result in _RESULTS else f"{result}"


def command_error(sysid: int, command: int, result: int, statustext: str = "") -> CommandError:
    """The typed error for a COMMAND_ACK result other than ACCEPTED or IN_PROGRESS."""
    return _COMMAND_ERRORS.get(result, CommandError)(sysid, command, result, statustext)


def _command_name(command: int) -> str:
    entry = mavlink2.enums["MAV_CMD"].get(command)
    return entry.name.removeprefix("MAV_CMD_") if entry is not None else f"command {command}"


# --- flying ----------------------------------------------------------------------------


class FlightError(GcsError):
    """A vehicle could not be brought to, or kept in, the state the flight needs."""
