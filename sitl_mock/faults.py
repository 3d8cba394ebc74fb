"""Link and vehicle faults on demand: loss, delay, duplication, reordering, silence, mission
rejection, and refusals late in a start (arming, take-off, any command kind) so that a
ground station's fallback after a partial start can be tested. Link delays are in
SIMULATED seconds (they scale with the speed-up and stay deterministic for a seed); every
random choice comes from the vehicle's numpy Generator."""

from __future__ import annotations

import functools
import heapq
import itertools
from dataclasses import dataclass, fields
from typing import Generic, TypeVar

import numpy as np

from .codec import mavlink

P = TypeVar("P")

REORDER_HOLD_S = 0.1
"""A packet held back for reordering is released after this long if nothing overtakes it."""
REJECT_POINTS = ("count", "last_item")
VEHICLE_FAULTS = frozenset(
    {
        "reject_missions",
        "reject_at",
        "fail_arming",
        "refuse_takeoff",
        "refuse_commands",
        "refuse_result",
    }
)
"""Faults of the vehicle, not of the link."""


@dataclass(frozen=True)
class Faults:
    """Per-vehicle faults. Fractions are per MAVLink packet; times are simulated seconds."""

    loss_in: float = 0.0
    """Fraction of packets from the ground station dropped."""
    loss_out: float = 0.0
    """Fraction of packets to the ground station dropped."""
    latency_s: float = 0.0
    """Fixed one-way delay, each direction."""
    jitter_s: float = 0.0
    """Extra one-way delay drawn uniformly from [0, jitter_s), each direction (reorders)."""
    duplicate: float = 0.0
    """Fraction of packets delivered twice, each direction."""
    reorder: float = 0.0
    """Fraction of packets held back and delivered after the next one, each direction."""
    reject_missions: bool = False
    """Answer mission uploads with MAV_MISSION_ERROR (at `reject_at`)."""
    reject_at: str = "last_item"
    """"count" (the MISSION_COUNT is refused) or "last_item" (the final item is refused)."""
    fail_arming: bool = False
    """Every arming attempt fails (COMMAND_ACK FAILED, "Arm: ..." text), ready or not."""
    refuse_takeoff: bool = False
    """NAV_TAKEOFF and MISSION_START commands fail once armed: the start breaks after arming."""
    refuse_commands: frozenset[int] = frozenset()
    """MAV_CMD ids answered with `refuse_result` and not carried out."""
    refuse_result: int = mavlink.MAV_RESULT_FAILED

    def __post_init__(self) -> None:
        for name in ("loss_in", "loss_out", "duplicate", "reorder"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} must be a fraction in [0, 1], got {value}")
        for name in ("latency_s", "jitter_s"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must not be negative")
        if self.reject_at not in REJECT_POINTS:
            raise ValueError(f"reject_at must be one of {REJECT_POINTS}, got {self.reject_at!r}")
        object.__setattr__(self, "refuse_commands", frozenset(self.refuse_commands))

    @functools.cached_property
    def link_is_clean(self) -> bool:
        """No loss, delay, duplication or reordering (asked on every step: worked out once)."""
        return all(getattr(self, f.name) == 0 for f in fields(self) if f.name not in VEHICLE_FAULTS)


class _Channel(Generic[P]):
    """One direction of a faulty link."""

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self._queue: list[tuple[float, int, P]] = []
        self._counter = itertools.count()
        self._held: tuple[float, P] | None = None

    def push(self, packet: P, now: float, loss: float, faults: Faults) -> list[P]:
        """Packets deliverable now (possibly none, possibly this one twice, plus a held one)."""
        if loss > 0 and self._rng.random() < loss:
            return []
        copies = 2 if faults.duplicate > 0 and self._rng.random() < faults.duplicate else 1
        ready: list[P] = []
        for _ in range(copies):
            if self._held is None and faults.reorder > 0 and self._rng.random() < faults.reorder:
                self._held = (now + REORDER_HOLD_S, packet)
                continue
            ready += self._delay(packet, now, faults)
            if self._held is not None:
                ready += self._delay(self._held[1], now, faults)
                self._held = None
        return ready

    def _delay(self, packet: P, now: float, faults: Faults) -> list[P]:
        delay = faults.latency_s
        if faults.jitter_s > 0:
            delay += self._rng.uniform(0.0, faults.jitter_s)
        if delay <= 0:
            return [packet]
        heapq.heappush(self._queue, (now + delay, next(self._counter), packet))
        return []

    def release(self, now: float) -> list[P]:
        ready: list[P] = []
        while self._queue and self._queue[0][0] <= now:
            ready.append(heapq.heappop(self._queue)[2])
        if self._held is not None and self._held[0] <= now:
            ready.append(self._held[1])
            self._held = None
        return ready

    def clear(self) -> None:
        self._queue.clear()
        self._held = None


class FaultyLink(Generic[P]):
    """Applies a vehicle's `Faults` to packets in both directions; `silence` drops all."""

    def __init__(self, faults: Faults, rng: np.random.Generator) -> None:
        self.faults = faults
        self._in: _Channel[P] = _Channel(rng)
        self._out: _Channel[P] = _Channel(rng)
        self._silent_until = -1.0

    def set_faults(self, faults: Faults) -> None:
        self.faults = faults

    def silence(self, until: float) -> None:
        self._silent_until = max(self._silent_until, until)
        self._in.clear()
        self._out.clear()

    def silent(self, now: float) -> bool:
        return now < self._silent_until

    def inbound(self, packet: P, now: float) -> list[P]:
        return self._pass(self._in, packet, now, self.faults.loss_in)

    def outbound(self, packet: P, now: float) -> list[P]:
        return self._pass(self._out, packet, now, self.faults.loss_out)

    def release(self, now: float) -> tuple[list[P], list[P]]:
        """Delayed or held packets now due: (inbound, outbound)."""
        if self.faults.link_is_clean and not self._in._queue and not self._out._queue:
            return [], []
        return self._in.release(now), self._out.release(now)

    def _pass(self, channel: _Channel[P], packet: P, now: float, loss: float) -> list[P]:
        if self.silent(now):
            return []
        if self.faults.link_is_clean:
            return [packet]
        return channel.push(packet, now, loss, self.faults)
