"""Flight events waiting for storage, and the file they wait in once memory is full.

When storage falls so far behind that the event writer's in-memory backlog reaches its
limit, every further event is appended to a JSON-lines file (a buffered append to the
page cache, not a storage round trip: microseconds in the flight's tick) until the
writer has read the file back and stored it, in order; then the file is emptied. A
service that stops with events unstored leaves them in the file, and the next start
stores them first.
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import IO, Any

from gcs.service.storage.tables import EventRow

log = logging.getLogger("mvo_gcs.events")


@dataclass(frozen=True)
class PendingEvent:
    """One event as the fleet reported it, not yet stored; `t` is the loop time it was
    recorded (what the backlog's age is measured from)."""

    t: float
    flight_id: str
    kind: str
    uav_id: str | None
    data: dict[str, Any]
    created_at: datetime

    def row(self) -> EventRow:
        """A fresh row each time: a failed transaction must not leave it half-attached."""
        return EventRow(
            flight_id=self.flight_id,
            kind=self.kind,
            uav_id=self.uav_id,
            data=self.data,
            created_at=self.created_at,
        )

    def line(self) -> str:
        fields = {**self.__dict__, "created_at": self.created_at.isoformat()}
        return json.dumps(fields, separators=(",", ":")) + "\n"

    @classmethod
    def parse(cls, line: str, t: float | None = None) -> PendingEvent:
        fields = json.loads(line)
        fields["created_at"] = datetime.fromisoformat(fields["created_at"])
        if t is not None:  # from an earlier run: its loop clock means nothing now
            fields["t"] = t
        return cls(**fields)


class EventSpill:
    """The events appended and not yet read back (`unread`), oldest first."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.unread = 0
        self.unreadable = 0  # lines read back that were not an event (cut short by a crash)
        self._out: IO[str] | None = None
        self._in: IO[str] | None = None
        self._next: PendingEvent | None = None  # the next unread event, read ahead
        self._left_over = 0  # unread lines from a previous run
        self._opened_at = 0.0  # the loop time they are taken to have been recorded at

    def open(self, now: float) -> int:
        """Take up what a previous run left (its events are stored first); how many."""
        if not self.path.exists() or not self.path.stat().st_size:
            return 0
        with self.path.open("rb+") as raw:  # a line cut short by a crash stays one line
            raw.seek(-1, os.SEEK_END)
            if raw.read(1) != b"\n":
                raw.write(b"\n")
        with self.path.open(encoding="utf-8") as lines:
            self.unread = sum(1 for _ in lines)
        self._left_over, self._opened_at = self.unread, now
        self._in = self.path.open(encoding="utf-8")
        self._read_ahead()
        return self.unread

    @property
    def head_t(self) -> float | None:
        """When the oldest unread event was recorded."""
        return self._next.t if self._next is not None else None

    def append(self, event: PendingEvent) -> None:
        if self._out is None:
            self._out = self.path.open("a", encoding="utf-8")
        self._out.write(event.line())
        self.unread += 1
        if self._next is None and self.unread == 1:
            self._next = event

    def read(self, most: int) -> list[PendingEvent]:
        """Up to `most` of the oldest unread events; the file is emptied once all are read."""
        if self._out is not None:
            self._out.flush()
        if self._in is None and self.unread:
            self._in = self.path.open(encoding="utf-8")
            self._next = None
            self._read_ahead()
        events: list[PendingEvent] = []
        while self.unread and len(events) < most:
            if self._next is not None:
                events.append(self._next)
            self.unread -= 1
            self._next = None
            self._read_ahead()
        if not self.unread:
            self._empty()
        return events

    def keep(self, earlier: list[PendingEvent]) -> None:
        """At shutdown: `earlier` (older than anything here) and the unread rest, in one
        file for the next start."""
        rest: list[str] = []
        if self.unread:
            if self._out is not None:
                self._out.flush()
            if self._in is None:
                self._in = self.path.open(encoding="utf-8")
                self._read_ahead()
            if self._next is not None:
                rest.append(self._next.line())
            rest += self._in.readlines()
        self._close_files()
        if not earlier and not rest:
            return
        partial = self.path.with_suffix(".partial")
        with partial.open("w", encoding="utf-8") as out:
            out.writelines(event.line() for event in earlier)
            out.writelines(rest)
        partial.replace(self.path)

    def _read_ahead(self) -> None:
        """The next unread line into `_next`; a line that cannot be read (cut short by a
        crash) is logged and counted as read."""
        assert self._in is not None
        while self.unread:
            line = self._in.readline()
            earlier = self._left_over > 0
            self._left_over = max(self._left_over - 1, 0)
            try:
                self._next = PendingEvent.parse(line, self._opened_at if earlier else None)
                return
            except (ValueError, TypeError, KeyError) as exc:
                log.error("%s: an unreadable event is left out (%s): %r", self.path, exc, line)
                self.unread -= 1
                self.unreadable += 1
        self._next = None

    def _empty(self) -> None:
        self._close_files()
        self.path.unlink(missing_ok=True)

    def _close_files(self) -> None:
        for handle in (self._out, self._in):
            if handle is not None:
                handle.close()
        self._out = self._in = None
        self._next = None
