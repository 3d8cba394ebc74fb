"""Jerk-limited speed profiles along a straight line (S-curves), as multicopters fly legs.

ArduCopter and PX4 do not change speed at their acceleration limit at once: acceleration
itself ramps at a jerk limit, so a stop from cruise takes longer and reaches further than
a point mass would (at 1 m/s and 1 m/s³, 2 s and 1 m instead of 0.4 s and 0.2 m). A leg is
flown as one profile of seven constant-jerk phases: speed change from the entry speed to a
peak (three phases), cruise at the peak, slow-down to rest at the end (three phases).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

PHASES = 7
"""Ramp up, hold, ramp down the acceleration; cruise; the same three to slow down."""
DECEL_PHASE = 4
"""Index of the first slow-down phase: a leg in it is finishing."""


def change_time(delta_v: float, accel: float, jerk: float) -> float:
    """Seconds a jerk-limited change of speed by `delta_v` takes, starting and ending
    without acceleration."""
    dv = abs(delta_v)
    if dv <= accel * accel / jerk:
        return 2.0 * math.sqrt(dv / jerk)
    return dv / accel + accel / jerk


def change_distance(v_from: float, v_to: float, accel: float, jerk: float) -> float:
    """Metres covered by that change: the profile is antisymmetric, so the mean speed is
    the mean of its ends."""
    return 0.5 * (v_from + v_to) * change_time(v_to - v_from, accel, jerk)


def stopping_distance(speed: float, accel: float, jerk: float) -> float:
    return change_distance(speed, 0.0, accel, jerk)


@dataclass(frozen=True)
class Profile:
    """Seven phases: their jerks, start times, and the (distance, speed, acceleration)
    at the start of each phase and at the end (row 7)."""

    jerks: np.ndarray  # (7,)
    knots: np.ndarray  # (8,) start time of each phase, then the end
    states: np.ndarray  # (8, 3)

    @property
    def length(self) -> float:
        return float(self.states[-1, 0])

    @property
    def duration(self) -> float:
        return float(self.knots[-1])

    @property
    def accel_end(self) -> float:
        """When the speed-up ends (cruise or slow-down begins)."""
        return float(self.knots[3])

    @property
    def decel_start(self) -> float:
        return float(self.knots[DECEL_PHASE])

    def at(self, t: float) -> np.ndarray:
        """(distance, speed, acceleration) `t` seconds in (clamped to the profile)."""
        t = min(max(t, 0.0), self.duration)
        k = min(int(np.searchsorted(self.knots, t, side="right")) - 1, PHASES - 1)
        return advance(self.states[k], self.jerks[k], t - self.knots[k])


def leg_profile(
    distance: float,
    entry_speed: float,
    max_speed: float,
    accel: float,
    jerk: float,
    up_jerk: float | None = None,
) -> Profile:
    """The quickest profile from `entry_speed` to rest at `distance` no faster than
    `max_speed` (or than the entry speed, when already faster), the speed changing first
    at `up_jerk` (default `jerk`). Where even a straight slow-down needs more room than
    `distance`, the profile is that slow-down: the vehicle overshoots and comes back."""
    v0 = max(entry_speed, 0.0)
    first = jerk if up_jerk is None else up_jerk
    stop = stopping_distance(v0, accel, jerk)
    if distance <= stop:
        return _profile(v0, v0, 0.0, accel, jerk)
    peak = max(max_speed, 1e-6)

    def needed(v: float) -> float:
        return change_distance(v0, v, accel, first) + stopping_distance(v, accel, jerk)

    if needed(peak) > distance:
        if v0 > peak:  # no room to slow to the new speed first: hold the speed, then stop
            return _profile(v0, v0, (distance - stop) / v0, accel, jerk)
        # the highest peak that fits lies between the entry speed (it fits, since
        # distance > stop) and `peak`; `needed` grows with the peak there
        low, high = v0, peak
        for _ in range(60):
            mid = 0.5 * (low + high)
            low, high = (mid, high) if needed(mid) <= distance else (low, mid)
        peak = low
    cruise_s = (distance - needed(peak)) / peak
    return _profile(v0, peak, max(cruise_s, 0.0), accel, jerk, first)


def _profile(
    v0: float, peak: float, cruise_s: float, accel: float, jerk: float, up_jerk: float | None = None
) -> Profile:
    durations, jerks = np.zeros(PHASES), np.zeros(PHASES)
    changes = ((0, v0, peak, up_jerk or jerk), (DECEL_PHASE, peak, 0.0, jerk))
    for first, v_from, v_to, j in changes:
        dv = v_to - v_from
        ramp = min(math.sqrt(abs(dv) / j), accel / j)
        plateau = max(abs(dv) / accel - accel / j, 0.0) if ramp == accel / j else 0.0
        sign = math.copysign(1.0, dv)
        durations[first : first + 3] = (ramp, plateau, ramp)
        jerks[first : first + 3] = (sign * j, 0.0, -sign * j)
    durations[3] = cruise_s
    knots = np.concatenate(([0.0], np.cumsum(durations)))
    states = np.zeros((PHASES + 1, 3))
    states[0] = (0.0, v0, 0.0)
    for k in range(PHASES):
        states[k + 1] = advance(states[k], jerks[k], durations[k])
    states[-1, 2] = 0.0  # the ramps cancel; drop their rounding
    states[-1, 1] = 0.0
    return Profile(jerks, knots, states)


DECAY_PIECE = 0.5
"""A brake's decay is flown in pieces this many time constants long."""


def brake_profile(speed: float, decel: float, jerk: float) -> Profile:
    """ArduCopter's BRAKE from `speed` to rest. Its velocity shaper asks for a deceleration
    of speed x jerk / decel (the linear part of its square-root controller; `decel` is
    BRAKE_MODE_DECEL_RATE_MSS, 7.5, and caps it), reached at `jerk` (PSC_JERK_NE): once
    there, the speed decays exponentially with the time constant tau = decel / jerk (1.5 s),
    slower at the end than any jerk-limited stop. Seven constant-jerk phases follow that:
    the ramp to the decay, a hold at `decel` (only from above decel x tau), four pieces of
    the decay each ending on it (deceleration = speed / tau), and a last one to rest with
    no deceleration left, 2 tau long. SITL from 4.97 and 10.01 m/s: standstill after
    8.68 m in 5.36 s and 20.06 m in 6.64 s."""
    tau = decel / jerk
    v0 = max(speed, 0.0)
    durations, jerks = np.zeros(PHASES), np.zeros(PHASES)
    ramp = min(math.sqrt(tau * tau + 2.0 * v0 / jerk) - tau, decel / jerk)
    hold = max(v0 - jerk * ramp * ramp / 2.0 - decel * tau, 0.0) / decel
    durations[:2], jerks[:2] = (ramp, hold), (-jerk, 0.0)
    states = np.zeros((PHASES + 1, 3))
    states[0] = (0.0, v0, 0.0)
    for k in range(PHASES):
        if k >= 2:
            _, v, a = states[k]
            if k < PHASES - 1:  # a piece of the decay, ending on it
                dt = DECAY_PIECE * tau
                jerks[k] = (-(v + a * dt) / tau - a) / (dt + dt * dt / (2.0 * tau))
            else:  # to rest: from deceleration v / tau that takes 2 tau
                dt = 2.0 * tau
                jerks[k] = -a / dt
            durations[k] = dt
        states[k + 1] = advance(states[k], jerks[k], durations[k])
    states[-1, 1:] = 0.0  # rest; drop the rounding
    return Profile(jerks, np.concatenate(([0.0], np.cumsum(durations))), states)


def advance(state: np.ndarray, jerk: np.ndarray | float, dt: np.ndarray | float) -> np.ndarray:
    """(distance, speed, acceleration) after `dt` at constant `jerk`; broadcasts over a
    leading axis (the fleet's vehicles)."""
    s, v, a = state[..., 0], state[..., 1], state[..., 2]
    return np.stack(
        (
            s + v * dt + a * dt**2 / 2 + jerk * dt**3 / 6,
            v + a * dt + jerk * dt**2 / 2,
            a + jerk * dt,
        ),
        axis=-1,
    )
