"""How a copter moves along its path: its limits, how far it needs to stop, how fast it
takes a corner, and the speed it can have at every point of a path.

ArduCopter flies a mission's legs along jerk-limited S-curves (AC_WPNav, SCurve): its
speed rises and falls at WPNAV_ACCEL with the acceleration itself ramping at WPNAV_JERK,
it blends a corner into the next leg without stopping, the next leg setting off as this
one slows down once the blend stays within the waypoint radius (WP_RADIUS_M) and the
corner acceleration (WPNAV_ACCEL_C), and a paused mission slows along the track the same
jerk-limited way. The plan knows none of this: its legs change speed at once. This module
is the ground station's model of that motion, used to time a plan as it will be flown
(`flight_timing`) and to know where a vehicle can still stop (`gcs.fleet.gatekeeper`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import numpy.typing as npt

from gcs.mission.geodesy import Floats

DEFAULT_SPEED_M_S = 5.0
"""The flight speed unless the operator asks for another: a real cruise speed."""


BRAKE_REACH_S = 2.0
"""A brake reaches about this many seconds of the speed it starts from (SITL: 8.7 m from
5 m/s, 20.1 m from 10 m/s)."""
LAND_SETTLE_S = 0.9
"""Seconds a copter hovers over its landing point, stopped, before it descends (SITL)."""
LAND_DETECT_S = 2.1
"""Seconds from touching the ground to disarmed: ArduCopter's land detector waits for its
motors to sit at their lower limit for a second, then spools them down (SITL: 2.1 s)."""
SPEEDING_UP_M_S2 = 0.05
"""Above this a vehicle counts as speeding up (its S-curve may reach WPNAV_ACCEL)."""
SPARE = 1.1
"""What the stopping distances keep in hand beyond what ArduCopter SITL measured."""


@dataclass(frozen=True)
class CopterLimits:
    """Navigation limits in SI units, as ArduCopter's parameters give them."""

    speed_m_s: float = DEFAULT_SPEED_M_S  # WPNAV_SPEED, or the mission's DO_CHANGE_SPEED
    accel_m_s2: float = 2.5  # WPNAV_ACCEL
    jerk_m_s3: float = 1.0  # WPNAV_JERK: how the legs' S-curves change speed
    jerk_ramp_s: float = 0.3  # 2 x ATC_INPUT_TC: how long the S-curves' jerk takes to build
    stop_jerk_m_s3: float = 5.0  # PSC_JERK_NE: how a paused mission slows to a stop
    corner_accel_m_s2: float = 5.0  # WPNAV_ACCEL_C (ArduCopter: 2 x WPNAV_ACCEL when 0)
    radius_m: float = 0.5  # WP_RADIUS_M: how far a blended corner may pass from its point
    descent_m_s: float = 1.5  # WPNAV_SPEED_DN: how fast LAND comes down from high up
    land_m_s: float = 0.5  # LAND_SPEED: the last part of a landing
    land_slow_below_m: float = 10.0  # LAND_ALT_LOW: where that last part begins
    vertical_accel_m_s2: float = 1.0  # WPNAV_ACCEL_Z: how a landing's descent speeds up and slows

    def __post_init__(self) -> None:
        for name in (
            "speed_m_s", "accel_m_s2", "jerk_m_s3", "stop_jerk_m_s3", "corner_accel_m_s2",
            "radius_m",
        ):  # fmt: skip
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if not self.jerk_ramp_s >= 0:
            raise ValueError(f"jerk_ramp_s must not be negative, got {self.jerk_ramp_s}")

    @functools.cached_property
    def s_curve_jerk_m_s3(self) -> float:
        """The constant jerk at which a speed change at full acceleration takes as long as
        ArduCopter's, whose jerk itself builds up and dies away over `jerk_ramp_s` (SCurve
        limits snap to half of WPNAV_JERK·π / (2·ATC_INPUT_TC)): each ramp of the
        acceleration takes accel/jerk + jerk_ramp_s, not accel/jerk. With the defaults that
        is 0.89 of WPNAV_JERK: a 22 m leg from rest to rest peaks at 4.77 m/s (SITL
        4.65-4.73; the whole WPNAV_JERK, 4.95), a stop from 10 m/s takes 6.8 s (SITL 6.8)."""
        accel = self.accel_m_s2
        return accel / (accel / self.jerk_m_s3 + self.jerk_ramp_s)

    def change_time(self, delta_v: float, jerk: float | None = None) -> float:
        """Seconds a jerk-limited change of speed by `delta_v` takes, from and to no
        acceleration (a triangle of acceleration below accel²/jerk, a trapezium above)."""
        dv, accel, jerk = abs(delta_v), self.accel_m_s2, jerk or self.s_curve_jerk_m_s3
        if dv <= accel * accel / jerk:
            return 2.0 * math.sqrt(dv / jerk)
        return dv / accel + accel / jerk

    def change_distance(self, v_from: float, v_to: float, jerk: float | None = None) -> float:
        """Metres covered meanwhile: the profile is antisymmetric, so its mean speed is
        the mean of its ends."""
        return 0.5 * (v_from + v_to) * self.change_time(v_to - v_from, jerk)

    def stopping_distance(
        self,
        speed: float,
        accel: float = 0.0,
        paused: bool = False,
        track_m_s: float | None = None,
    ) -> float:
        """Metres a vehicle told to stop covers from `speed`, while speeding up at `accel`
        (which must first ramp down to nothing: the speed still grows meanwhile), on a
        track flown at `track_m_s` (the mission's speed there; default its cruise).

        A paused mission does not brake: it slows the clock of its S-curve (AC_WPNav), as
        if its track speed fell from `track_m_s` to nothing at WPNAV's acceleration ramped
        with the position controller's jerk, while the curve itself goes on speeding up
        (`track_distance`). Where ArduCopter will not pause, BRAKE stops it, its speed
        decaying with a time constant of about 1.5 s (ModeBrake). On SITL a pause stopped
        within 6.7 m from 5 m/s and 23.2 m from 10 m/s, a brake within 8.7 m and 20.1 m;
        a pause at 3.8 m/s, speeding up out of a corner on a 10 m/s track, 14.1 m (two
        vehicles of the 10-UAV crossing came 4.9 m apart where braking was counted on):
        the furthest of these, with a tenth to spare; `paused` only, for a vehicle creeping
        mid-leg (where a pause is never refused)."""
        track = max(speed, self.speed_m_s if track_m_s is None else track_m_s)
        braking = self.slowing_distance(speed, accel, 0.0, self.stop_jerk_m_s3)
        pause = max(braking, self.track_distance(speed, accel, track))
        peak = speed + max(0.0, accel) ** 2 / (2 * self.stop_jerk_m_s3)
        brake = 0.0 if paused else BRAKE_REACH_S * peak
        return SPARE * max(pause, brake)

    def unheard_run_m(self, silent_s: float) -> float:
        """Metres a vehicle sent on from rest at its cruise covers should it hear nothing
        more: `silent_s` of its S-curve speeding up (until its GCS failsafe acts), then
        the failsafe's brake. Unbounded where no failsafe is known (`silent_s` infinite).
        (Fuzzed flight 20276, 5 m/s, braked after 2 s: 4.4 m; this says 5.8 m.)"""
        if not math.isfinite(silent_s):
            return math.inf
        jerk, accel = self.s_curve_jerk_m_s3, self.accel_m_s2
        ramp = min(silent_s, accel / jerk)
        speed, run = jerk * ramp**2 / 2, jerk * ramp**3 / 6
        steady = silent_s - ramp
        run += speed * steady + jerk * ramp * steady**2 / 2
        speed = min(speed + jerk * ramp * steady, self.speed_m_s)
        return run + self.stopping_distance(speed, jerk * ramp, track_m_s=speed)

    def track_distance(self, speed: float, accel: float, track_m_s: float) -> float:
        """How far a paused mission goes on: its S-curve's clock slows as a speed of
        `track_m_s` would stop, so the curve runs on for that stop's distance over
        `track_m_s` seconds, from `speed`, and if speeding up (`accel` > 0) at up to
        WPNAV's acceleration until `track_m_s`. From cruise that is a plain stop; from a
        corner or a start it is much further than braking would be (SITL, paused speeding
        up on a 10 m/s track: 10.3 m from 2.05 m/s, 15.2 m from 4.05 m/s, 19.2 m from
        6.08 m/s; bench/results/pause_vs_sitl.md)."""
        if track_m_s <= 0:
            return 0.0
        runs_s = self.slowing_distance(track_m_s, 0.0, 0.0, self.stop_jerk_m_s3) / track_m_s
        rising = self.accel_m_s2 if accel > SPEEDING_UP_M_S2 else 0.0
        if rising <= 0 or speed + rising * runs_s <= track_m_s:
            return speed * runs_s + rising * runs_s**2 / 2
        up_s = (track_m_s - speed) / rising
        return speed * up_s + rising * up_s**2 / 2 + track_m_s * (runs_s - up_s)

    def slowing_distance(
        self, speed: float, accel: float, to: float, jerk: float | None = None
    ) -> float:
        """Metres from `speed` down to `to` while speeding up at `accel`, which must first
        ramp down to nothing (the speed still grows meanwhile)."""
        accel, jerk = max(0.0, accel), jerk or self.s_curve_jerk_m_s3
        ramp = accel / jerk
        before = speed * ramp + accel * ramp * ramp / 2 - jerk * ramp**3 / 6
        return before + self.change_distance(speed + accel * ramp / 2, to, jerk)

    def landing_time(self, altitude_m: float) -> float:
        """Seconds from stopping over the landing point to disarmed on the ground, as
        ArduCopter's LAND does: it settles, speeds up to its descent speed, slows on the
        way to LAND_ALT_LOW so as to pass it at the landing speed, comes down the rest at
        that, and disarms once its land detector is sure. The vehicle is in the way until
        then. (SITL 4.8.0-dev from 20 m, six landings: 30.1 to 31.3 s from stopping;
        this says 30.75 s, the descent and landing speeds alone 26.7 s.)"""
        low = min(altitude_m, self.land_slow_below_m)
        fast, land, accel = self.descent_m_s, self.land_m_s, self.vertical_accel_m_s2
        if altitude_m <= low:
            return LAND_SETTLE_S + land / (2 * accel) + low / land + LAND_DETECT_S
        slowing_m = min(max(fast * fast - land * land, 0.0) / (2 * accel), altitude_m - low)
        slowing_s = 2 * slowing_m / (fast + land)  # as long as a steady slow-down takes
        high_s = (altitude_m - low - slowing_m) / fast + fast / (2 * accel) + slowing_s
        return LAND_SETTLE_S + high_s + low / land + LAND_DETECT_S

    def corner_speed(self, turn_rad: float, leg_peak_m_s: float | None = None) -> float:
        """The lowest speed through a corner turning by `turn_rad` (0: straight on) between
        legs that peak at `leg_peak_m_s` (default: cruise).

        ArduCopter does not bend round a corner: it blends the two legs' S-curves (SCurve's
        fast-waypoint test). The next leg sets off from rest while this one comes to rest,
        from the moment the middle of the blend, where each leg is u seconds from its rest,
        D(u) metres from the corner at g(u) m/s, comes within `radius_m` of the corner
        (2 D sin(θ/2)) and within the corner acceleration, and while the next leg is still
        speeding up. The speed there is 2 g cos(θ/2). ArduCopter SITL with WP_RADIUS_M
        0.5 took 30, 60, 90 and 120° at 3.04, 1.64, 1.02 and 0.62 m/s from 5 m/s (2.92,
        1.57, 0.93, 0.57 from 10 m/s); this gives 3.12, 1.80, 1.17 and 0.72. A bend of
        radius `radius_m` at the corner acceleration, the model before, gave 8.4 m/s at 30°:
        the timing ran ahead of every flight by about half a second a corner."""
        half = 0.5 * min(abs(turn_rad), math.pi - 1e-6)
        if half < 1e-6:
            return math.inf
        jerk, peak, sin_half = self.s_curve_jerk_m_s3, self.stop_peak_m_s2(), math.sin(half)
        u = min(
            _tail_time(self.radius_m / (2 * sin_half), jerk, peak),
            0.5 * self.change_time(leg_peak_m_s or self.speed_m_s),  # the next leg half-way up
            self.corner_accel_m_s2 / (2 * sin_half * jerk)
            if 2 * peak * sin_half > self.corner_accel_m_s2
            else math.inf,
        )
        return 2 * _stop_tail(u, jerk, peak)[1] * math.cos(half)

    def rest_to_rest_peak(self, distance: float) -> float:
        """The top speed of the quickest S-curve from rest to rest over `distance` metres
        (no faster than cruise): half the way up, half down."""
        a, j, half = self.accel_m_s2, self.s_curve_jerk_m_s3, max(distance, 0.0) / 2
        if half * j * j <= a**3:  # no acceleration plateau: half = v·sqrt(v / j)
            peak = float((half * math.sqrt(j)) ** (2 / 3))
        else:  # half = v·(v / a + a / j) / 2
            peak = 0.5 * a * (-a / j + math.sqrt((a / j) ** 2 + 8 * half / a))
        return min(self.speed_m_s, peak)

    def stop_peak_m_s2(self, speed: float | None = None) -> float:
        """The deceleration an S-curve stop from `speed` (default cruise) peaks at."""
        speed = self.speed_m_s if speed is None else speed
        return min(self.accel_m_s2, math.sqrt(self.s_curve_jerk_m_s3 * speed))

    def speed_before_rest(self, distance: float, from_speed: float) -> float:
        """The speed an S-curve stop from `from_speed` has `distance` metres before its
        rest. The stop is antisymmetric about its middle: the speed it has lost t seconds
        in is the speed it has left t seconds before its end, so its first half is its
        tail (`_stop_tail`) turned round."""
        jerk, peak = self.s_curve_jerk_m_s3, self.stop_peak_m_s2(from_speed)
        total = self.change_time(from_speed)
        if distance >= 0.5 * from_speed * total:
            return from_speed

        def left(u: float) -> tuple[float, float]:  # metres to go and speed, u s before rest
            if u <= 0.5 * total:
                gone, speed, _ = _stop_tail(u, jerk, peak)
                return gone, speed
            gone, speed, _ = _stop_tail(total - u, jerk, peak)
            return 0.5 * from_speed * total - from_speed * (total - u) + gone, from_speed - speed

        low, high = 0.0, total
        while high - low > 1e-4:
            middle = 0.5 * (low + high)
            low, high = (middle, high) if left(middle)[0] <= distance else (low, middle)
        return left(low)[1]


def _stop_tail(u: float, jerk: float, peak: float) -> tuple[float, float, float]:
    """Metres still to go, speed and deceleration `u` seconds before a jerk-limited stop at
    up to `peak` deceleration comes to rest (up to half-way through the stop)."""
    ramp = peak / jerk  # its last phase: the deceleration ramps down to nothing
    if u <= ramp:
        return jerk * u**3 / 6, jerk * u**2 / 2, jerk * u
    x, gone, speed = u - ramp, jerk * ramp**3 / 6, jerk * ramp**2 / 2
    return gone + speed * x + peak * x**2 / 2, speed + peak * x, peak


def _tail_time(distance: float, jerk: float, peak: float) -> float:
    """`_stop_tail` the other way round: how long before its rest the stop is `distance`
    metres from it."""
    ramp = peak / jerk
    gone, speed = jerk * ramp**3 / 6, jerk * ramp**2 / 2
    if distance <= gone:
        return float((6 * max(distance, 0.0) / jerk) ** (1 / 3))
    return ramp + (math.sqrt(speed**2 + 2 * peak * (distance - gone)) - speed) / peak


STRAY_AT_REST_M = 0.1
STRAY_PER_M_S = 0.055
"""How far a copter may be off its path: its position error at rest, growing with speed.
ArduCopter SITL (bench/results/kinematics_vs_sitl.txt), waypoint radius 0.5 m: at most
0.34 m off the polyline through corners at 5 m/s, 0.66 m at 10 m/s (it trails its
target through a sharp turn); 0.04 m on straight legs."""


def stray_m(speed_m_s: float) -> float:
    """How far off its path a copter flying at `speed_m_s` may be."""
    return STRAY_AT_REST_M + STRAY_PER_M_S * speed_m_s


def highest_speed_for_stray(allowed_m: float) -> float | None:
    """The highest speed at which a copter strays no more than `allowed_m`; None if none."""
    if allowed_m < STRAY_AT_REST_M:
        return None
    return (allowed_m - STRAY_AT_REST_M) / STRAY_PER_M_S


def turn_angles(xy: Floats) -> Floats:
    """The turn at each interior vertex of a polyline, radians in [0, pi]."""
    legs = np.diff(xy, axis=0)
    heading = np.arctan2(legs[:, 1], legs[:, 0])
    turn = np.abs(np.diff(heading))
    return np.minimum(turn, 2 * np.pi - turn)


def speed_profile(
    s_vertices: Floats,
    leg_speeds: Floats,
    turns: Floats,
    limits: CopterLimits,
    stops: Floats | None = None,
) -> tuple[Floats, Floats, Floats]:
    """The highest speed at each vertex (entry) that the copter can have there and still
    make every later corner and stop at the end: (s, v) knots, v = 0 at both ends and
    where `stops` (a mask over the vertices) says the autopilot comes to rest; and each
    leg's speed as flown (`leg_peaks`).

    The waypoints are the vertices where the path turns or the speed changes (a mission
    leaves the others out). A waypoint's speed is bounded by its corner, by the legs on
    either side, by the waypoint after next (ArduCopter plans its S-curve one waypoint
    ahead only, so it must be able to stop there: waypoints 1 m apart held it to
    1.7 m/s), and, in a backward pass, by what slowing down to the next waypoint's bound
    allows in between (jerk-limited). A vertex between two waypoints is bounded by its
    legs and by slowing down to the next waypoint and stopping at the one after."""
    n = len(s_vertices)
    bound = np.zeros(n)
    if n < 2:
        return s_vertices.copy(), bound, leg_speeds
    waypoint = _waypoints(leg_speeds, turns, stops)
    index = np.flatnonzero(waypoint)
    leg_speeds = leg_peaks(s_vertices, leg_speeds, waypoint, limits)
    nxt = index[np.minimum(np.searchsorted(index, np.arange(n), side="right"), len(index) - 1)]
    after = index[np.minimum(np.searchsorted(index, nxt, side="right"), len(index) - 1)]
    corners = np.array(
        [
            limits.corner_speed(a, min(v_in, v_out))
            for a, v_in, v_out in zip(turns, leg_speeds[:-1], leg_speeds[1:], strict=True)
        ]
    )
    bound[1:-1] = np.minimum(np.minimum(corners, leg_speeds[:-1]), leg_speeds[1:])
    if stops is not None:
        bound[stops] = 0.0
    for k in index[-2:0:-1]:  # the waypoints, backwards
        stop_at = entry_speed_for(s_vertices[nxt[k]] - s_vertices[k], 0.0, limits)
        slow_to = entry_speed_for(s_vertices[nxt[k]] - s_vertices[k], bound[nxt[k]], limits)
        bound[k] = min(bound[k], stop_at, slow_to)
    for k in np.flatnonzero(~waypoint):
        stop_at = entry_speed_for(s_vertices[after[k]] - s_vertices[k], 0.0, limits)
        slow_to = entry_speed_for(s_vertices[nxt[k]] - s_vertices[k], bound[nxt[k]], limits)
        bound[k] = min(bound[k], stop_at, slow_to)
    return s_vertices.copy(), bound, leg_speeds


def leg_peaks(
    s_vertices: Floats, leg_speeds: Floats, waypoint: npt.NDArray[np.bool_], limits: CopterLimits
) -> Floats:
    """Each leg's speed, no faster than the S-curve from rest to rest over the stretch
    between the two waypoints it lies on gets: ArduCopter plans every leg so, and at a
    corner blends the one slowing down with the next speeding up (`corner_speed`); it does
    not carry its speed from leg to leg. A 22 m leg at 10 m/s peaked at 4.67 m/s on SITL
    (4.76 by `rest_to_rest_peak`, as the mock flies it); timed at cruise through its
    corners, a mission of such legs took SITL 1.38 times as long as its timing said."""
    index = np.flatnonzero(waypoint)
    stretch = np.diff(s_vertices[index])
    peaks = np.array([limits.rest_to_rest_peak(float(d)) for d in stretch])
    on = np.searchsorted(index, np.arange(len(leg_speeds)), side="right") - 1
    capped: Floats = np.minimum(leg_speeds, peaks[np.clip(on, 0, len(peaks) - 1)])
    return capped


def _waypoints(leg_speeds: Floats, turns: Floats, stops: Floats | None) -> npt.NDArray[np.bool_]:
    """Which vertices a mission keeps: the ends, turns, speed changes and stops."""
    waypoint = np.ones(len(leg_speeds) + 1, dtype=bool)
    straight = np.abs(turns) < 1e-6
    same_speed = np.isclose(leg_speeds[:-1], leg_speeds[1:], rtol=1e-4, atol=0.0)
    waypoint[1:-1] = ~(straight & same_speed)
    if stops is not None:
        waypoint |= stops
    return waypoint


def entry_speed_for(distance: float, exit_speed: float, limits: CopterLimits) -> float:
    """The highest speed from which the copter slows to `exit_speed` within `distance`.

    Solves change_distance(v, exit) = distance for v on the trapezium branch of the
    profile, which takes at least as long as the triangle: the answer errs low (safe)."""
    if distance <= 0:
        return exit_speed
    a, ramp = limits.accel_m_s2, limits.accel_m_s2**2 / limits.s_curve_jerk_m_s3
    # 2a·d = v² - e² + (v + e)·ramp, so v² + ramp·v - (e² - e·ramp + 2a·d) = 0
    c = exit_speed**2 - exit_speed * ramp + 2 * a * distance
    return max(exit_speed, 0.5 * (-ramp + math.sqrt(ramp * ramp + 4 * c)))


class Gate(StrEnum):
    """What a vehicle does about the point it may not pass yet."""

    GO = "go"  # flies on at its leg's speed
    STOP = "stop"  # paused: waits for the vehicle ahead to get out of the way
    CREEP = "creep"  # approaches the point slowly, from a stop, ready to stop short of it


@dataclass(frozen=True)
class StoppingRule:
    """When a vehicle flying toward a point it may not pass yet must be stopped, when it
    goes again, and when it edges closer: the same rule times a plan and flies it.

    It is stopped once the point is no further than its stopping distance at its speed,
    plus what it covers while the command reaches it (`reaction_s`: the position's age
    and the command's way), plus `buffer_m`. It goes again once it could reach its cruise
    speed and still stop short, so that it is not stopped again moments later (no
    command chatter on the radio link). Until then a stopped vehicle approaches the point
    at the fastest of `approach_speeds_m_s` from which it can still stop short (so that
    it is there sooner once the way is free; faster as the point moves on), and one that
    another vehicle waits for creeps up at `creep_m_s` however short the gap: stopping
    short must never make two vehicles wait for each other."""

    reaction_s: float = 0.6
    buffer_m: float = 1.0
    creep_m_s: float = 0.5
    creep_buffer_m: float = 0.2
    approach_speeds_m_s: tuple[float, ...] = (1.0, 2.0, 3.0, 4.0, 6.0, 8.0)
    approach_m: float = 2.0  # the least an approach must gain before it has to stop again
    approach_slack_m_s: float = 0.5
    """How much faster than its approach speed a vehicle may go and still be taken for on
    it. Faster, a DO_CHANGE_SPEED item of its mission has set the leg's speed again: a
    creep passing one sped up to 4.4 m/s on a 10 m/s track, judged as paused from 0.5 m/s,
    and stopped 5.5 m from another (fuzzed flight 9979). Not less: real ArduCopter's
    reported speed wavers about its approach, and at 0.1 m/s case VI at 10 m/s on SITL
    waited 13 times, not 7, and took 1.22x its timed flight."""

    def decide(
        self,
        gate: Gate,
        gap_m: float,
        speed: float,
        accel: float,
        limits: CopterLimits,
        waited_on: bool,
        approach_m_s: float | None = None,
    ) -> Gate:
        """The next gate state, `gap_m` short of the point, at `speed` and `accel`
        (`approach_m_s`: the speed an approach (CREEP) was sent at)."""
        if gap_m > self.go_room_m(limits):
            return Gate.GO
        if gate == Gate.GO:
            needed = self.needed_m(speed, self._setting_off(speed, accel, limits), limits)
            return Gate.STOP if gap_m <= needed else Gate.GO
        if gate == Gate.CREEP:
            sent = approach_m_s or speed
            # Faster than its approach, a speed item of its mission took over: the leg's
            # speed (None: cruise) is what a pause runs down from. On it, a creep is
            # judged as one (a pause stops it anywhere) however its reported speed wavers:
            # judged by that, real ArduCopter's creeps were stopped 2 m short and sent on
            # again, four times running (case VI at 10 m/s: 13 waits, 1.20x its timing).
            on_it = speed <= sent + self.approach_slack_m_s
            track = sent if on_it else None
            creeping = self._creeping(sent if on_it else speed)
            needed = self.needed_m(speed, accel, limits, creeping, track)
            return Gate.STOP if gap_m <= needed else gate
        approach = self.approach_speed(gap_m, limits, waited_on)
        return Gate.CREEP if speed <= self.creep_m_s and approach is not None else Gate.STOP

    def _setting_off(self, speed: float, accel: float, limits: CopterLimits) -> float:
        """The acceleration to judge a vehicle flying its mission by: one flying steady
        below its cruise speed (out of a corner, or hovering at a waypoint) may set off at
        any moment, its acceleration building at WP_JERK while a command is on its way
        (fuzzed flight 11574: let go out of a corner at a steady 2.66 m/s, it sped up on
        its next leg, and its pause ran past its limit to 5.65 m from another)."""
        if speed < limits.speed_m_s - self.approach_slack_m_s and accel > -SPEEDING_UP_M_S2:
            return max(accel, limits.s_curve_jerk_m_s3 * self.reaction_s)
        return accel

    def approach_speed(self, gap_m: float, limits: CopterLimits, waited_on: bool) -> float | None:
        """How fast a stopped vehicle approaches a point `gap_m` ahead: the fastest speed
        it can reach and still stop short (a creep only if another waits for it); None
        if it must stay where it is."""
        fitting = [
            v
            for v in self.approach_speeds_m_s
            if v < limits.speed_m_s and gap_m > self._approach_room_m(v, limits) + self.approach_m
        ]
        if not fitting and waited_on and gap_m > self._approach_room_m(self.creep_m_s, limits):
            fitting = [self.creep_m_s]
        return fitting[-1] if fitting else None

    def faster_approach(
        self, gap_m: float, limits: CopterLimits, waited_on: bool, approach_m_s: float | None
    ) -> float | None:
        """A faster approach than the one under way (`approach_m_s`; None: a creep) that
        fits `gap_m` now that the limit has moved on with its leader, or None. Kept at the
        speed it set off at, a vehicle following its leader through a gap crept at 1 m/s
        for 12 s behind a limit 17 m ahead (the gap swap at 5 m/s: 1.6 s sooner, up to
        7.9 s at 10 m/s). Judged from rest, as `approach_speed` is: from the speed it has,
        it needs less room."""
        faster = self.approach_speed(gap_m, limits, waited_on)
        current = self.creep_m_s if approach_m_s is None else approach_m_s
        return faster if faster is not None and faster > current + self.approach_slack_m_s else None

    def _approach_room_m(self, speed: float, limits: CopterLimits) -> float:
        creeping = self._creeping(speed)
        needed = self.needed_m(speed, 0.0, limits, creeping, track_m_s=speed)
        return needed + limits.change_distance(0.0, speed)

    def _creeping(self, speed: float) -> bool:
        """Slow enough that a paused mission stops it (ArduCopter pauses anywhere mid-leg)."""
        return speed <= self.creep_m_s + 0.05

    def go_room_m(self, limits: CopterLimits) -> float:
        """Room to speed up to cruise from a stop and still stop short."""
        return _go_room_m(self, limits)

    def needed_m(
        self,
        speed: float,
        accel: float,
        limits: CopterLimits,
        creeping: bool = False,
        track_m_s: float | None = None,
    ) -> float:
        """Room to stop short from `speed` and `accel` on a track flown at `track_m_s`
        (default the vehicle's cruise): the speed still grows while the command is on its
        way."""
        buffer = self.creep_buffer_m if creeping else self.buffer_m
        rising = min(max(accel, 0.0), limits.accel_m_s2)
        track = limits.speed_m_s if track_m_s is None else track_m_s
        reacted = min(speed + rising * self.reaction_s, max(speed, track))
        stopping = limits.stopping_distance(reacted, accel, creeping, track)
        return stopping + speed * self.reaction_s + buffer


@functools.lru_cache(maxsize=1024)
def _go_room_m(rule: StoppingRule, limits: CopterLimits) -> float:
    """StoppingRule.go_room_m, asked of every gate at every step of a flight and its
    timing, for a handful of (rule, limits) pairs."""
    cruise = limits.speed_m_s
    return limits.change_distance(0.0, cruise) + rule.needed_m(cruise, 0.0, limits)
