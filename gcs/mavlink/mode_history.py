"""The modes the ground station asked one vehicle for lately, so that the last one stands.

A mode switch (DO_SET_MODE) carries no sequence number, and its ACK names only the
command. An attempt of an earlier switch that was re-sent and held up on the way can
reach the vehicle after a later switch was accepted, and undo it: an operator's RTL
arriving after the abort's LAND (fuzzed flight 3621), a brake after the order's go. The
vehicle then answers nothing the ground station waits for. So, for a short while after a
switch, a HEARTBEAT that shows a mode asked for just before it means such a late copy,
and the switch is made again (`gcs.mavlink.actions`; a switch to the mode a vehicle is in
changes nothing on ArduCopter, so a HEARTBEAT sent before the switch costs one command).
"""

from __future__ import annotations

from dataclasses import dataclass, field

LATE_COPY_S = 1.5
"""How long after a switch a late copy of an earlier one is looked for: well beyond a
held-up datagram on a loopback or radio link (tenths of a second), short enough that a
mode the autopilot enters by itself later (a failsafe) is not fought."""


@dataclass
class ModeHistory:
    """When each mode was last asked for, and which switch is the latest."""

    asked_at: dict[str, float] = field(default_factory=dict)
    """Mode name -> loop time its last switch ended (its attempts may still be under way)."""
    asks: int = 0
    speed_m_s: float | None = None
    """The last speed asked for (DO_CHANGE_SPEED): AUTO made again forgets it, so it is
    given again after."""

    paused_at: dict[bool, float] = field(default_factory=dict)
    """When a pause (True) and a continue (False) of the mission were last asked for."""

    def pause_ended(self, pause: bool, now: float) -> bool:
        """A pause (or continue, DO_PAUSE_CONTINUE) ended now: True if the opposite one
        was asked for within LATE_COPY_S before, whose late copy could still undo it."""
        opposite = self.paused_at.get(not pause)
        self.paused_at[pause] = now
        return opposite is not None and now - opposite < LATE_COPY_S

    def begin(self) -> int:
        """A switch begins; its number, which `is_latest` checks."""
        self.asks += 1
        return self.asks

    def is_latest(self, ask: int) -> bool:
        return ask == self.asks

    def end(self, mode: str, now: float) -> frozenset[str]:
        """A switch to `mode` ended now; the other modes asked for within LATE_COPY_S
        before it, whose late copies could still undo it."""
        earlier = frozenset(
            m for m, at in self.asked_at.items() if m != mode and now - at < LATE_COPY_S
        )
        self.asked_at[mode] = now
        return earlier
