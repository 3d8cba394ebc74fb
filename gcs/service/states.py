"""The states of a flight and of a planning job: one enum each, one table of transitions.

Storage keeps the enum's value, the service moves between states only through
`FlightState.check` / `JobState.check` (a refused move is a `StateConflict`, which the
API answers 409 with its message), and the API schema declares the same enum.

A flight is *open* from its upload until every one of its vehicles is disarmed on the
ground: while open it owns its vehicles (no other flight may upload to them or start
them) and nothing it uses may be deleted. The operator's commands (abort, hold, land,
return to launch) work in every open state.
"""

from __future__ import annotations

from enum import StrEnum


class StateConflict(Exception):
    """A request the flight's or job's state does not allow; answered 409."""


class FlightState(StrEnum):
    CREATED = "created"  # a plan bound to vehicles; nothing sent yet
    UPLOADING = "uploading"
    UPLOADED = "uploaded"  # every mission verified on its vehicle, waiting for start
    UPLOAD_FAILED = "upload_failed"  # some vehicle refused or did not answer; none armed
    STARTING = "starting"  # arming, taking off, lining up over the starts
    FLYING = "flying"
    PAUSED = "paused"  # held by the operator
    ABORTING = "aborting"  # told to return or land; open until all are down
    INTERRUPTED = "interrupted"  # the flight cannot go on by itself (start failed, time
    # bound, service restart); vehicles may be up: the operator decides (resume: flying)
    LANDED = "landed"  # every vehicle flew its mission and is down
    ABORTED = "aborted"  # aborted, and every vehicle is down
    ENDED = "ended"  # ended otherwise (a vehicle withdrawn, interrupted), all down
    CANCELLED = "cancelled"  # the operator released an unflown flight

    @property
    def is_open(self) -> bool:
        return self in OPEN

    @property
    def is_final(self) -> bool:
        return not FLIGHT_TRANSITIONS[self]

    def check(self, new: FlightState, flight_id: str) -> None:
        """Refuse a move the table does not allow, saying what would be allowed."""
        if new not in FLIGHT_TRANSITIONS[self]:
            raise StateConflict(
                f"flight {flight_id} is {self.value}: it cannot become {new.value} "
                f"({_allowed(FLIGHT_TRANSITIONS[self])})"
            )


F = FlightState
FLIGHT_TRANSITIONS: dict[FlightState, frozenset[FlightState]] = {
    F.CREATED: frozenset({F.UPLOADING, F.CANCELLED}),
    F.UPLOADING: frozenset({F.UPLOADED, F.UPLOAD_FAILED, F.ABORTING, F.INTERRUPTED}),
    F.UPLOADED: frozenset({F.UPLOADING, F.STARTING, F.ABORTING, F.INTERRUPTED, F.CANCELLED}),
    F.UPLOAD_FAILED: frozenset({F.UPLOADING, F.CANCELLED}),
    F.STARTING: frozenset({F.FLYING, F.UPLOADED, F.ABORTING, F.INTERRUPTED}),
    F.FLYING: frozenset({F.PAUSED, F.ABORTING, F.INTERRUPTED, F.LANDED, F.ENDED}),
    F.PAUSED: frozenset({F.FLYING, F.ABORTING, F.INTERRUPTED, F.LANDED, F.ENDED}),
    F.ABORTING: frozenset({F.ABORTED, F.INTERRUPTED}),
    F.INTERRUPTED: frozenset({F.FLYING, F.ABORTING, F.ENDED}),
    F.LANDED: frozenset(),
    F.ABORTED: frozenset(),
    F.ENDED: frozenset(),
    F.CANCELLED: frozenset(),
}
OPEN = frozenset(
    {F.UPLOADING, F.UPLOADED, F.STARTING, F.FLYING, F.PAUSED, F.ABORTING, F.INTERRUPTED}
)
AIRBORNE = frozenset({F.STARTING, F.FLYING, F.PAUSED, F.ABORTING, F.INTERRUPTED})
"""States in which a vehicle of the flight may be in the air."""


class JobState(StrEnum):
    QUEUED = "queued"
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"
    CANCELLED = "cancelled"
    INTERRUPTED = "interrupted"  # the service stopped while it ran

    @property
    def is_final(self) -> bool:
        return not JOB_TRANSITIONS[self]

    def check(self, new: JobState, job_id: str) -> None:
        if new not in JOB_TRANSITIONS[self]:
            raise StateConflict(
                f"job {job_id} is {self.value}: it cannot become {new.value} "
                f"({_allowed(JOB_TRANSITIONS[self])})"
            )


J = JobState
_JOB_ENDS = frozenset({J.DONE, J.FAILED, J.CANCELLED, J.INTERRUPTED})
JOB_TRANSITIONS: dict[JobState, frozenset[JobState]] = {
    J.QUEUED: frozenset({J.RUNNING}) | _JOB_ENDS,
    J.RUNNING: frozenset({J.RUNNING}) | _JOB_ENDS,  # progress reports keep it running
    J.DONE: frozenset(),
    J.FAILED: frozenset(),
    J.CANCELLED: frozenset(),
    J.INTERRUPTED: frozenset(),
}


def _allowed(targets: frozenset[StrEnum]) -> str:
    if not targets:
        return "it has ended"
    return "it may become " + ", ".join(sorted(t.value for t in targets))
