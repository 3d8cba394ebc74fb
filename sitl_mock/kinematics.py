"""Kinematics for the whole fleet, stepped together with numpy.

Horizontally each vehicle flies legs the way ArduCopter's S-curves do (scurve.py): a
straight line to its target with jerk-limited speed changes, ending at rest. Given the
target after this one, it starts that leg while this one slows down (ArduPilot's "fast
waypoint"), where the blended corner stays inside the waypoint radius and the corner
acceleration limit (2 WP_ACC), and counts the target reached half-way through the blend:
the corner is rounded and costs no time. ArduCopter pauses a mission by slowing the
clock its S-curves run on (`pause_track`), not by braking: the curve goes on, speeding up
out of a corner if it was, while its clock runs down. Anything else that changes the
target in flight (a new goto, a mode change, PX4's pause) brakes along the current
velocity first, unless the vehicle is already heading for the new target. Vertically
each vehicle chases its target altitude at its climb or descent rate with its own
acceleration bound. Altitude is metres above the vehicle's home and never goes below the
ground (0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scurve import (
    DECEL_PHASE,
    PHASES,
    Profile,
    advance,
    brake_profile,
    leg_profile,
    stopping_distance,
)

VERTICAL_TOLERANCE = 0.3
"""m: close enough to a target altitude."""
LEGS = 2
"""Legs a vehicle flies at once: the one finishing and the one starting (at a corner)."""
AT_TARGET_M = 1e-6
ENDS_AT_TARGET_M = 1e-3
"""A leg ending this close to the target is the leg to it (float rounding of the sums)."""
CORNER_ACCEL_FACTOR = 2.0
"""ArduCopter's corner acceleration (WP_ACC_C) defaults to twice WP_ACC."""


@dataclass(frozen=True)
class NavLimits:
    """Navigation limits in SI units (read from an autopilot's parameters)."""

    cruise_speed: float = 10.0
    accel: float = 2.5
    climb_rate: float = 2.5
    descent_rate: float = 1.5
    vertical_accel: float = 1.0
    land_speed: float = 0.5
    accept_radius: float = 2.0
    jerk: float = 1.0
    stop_jerk: float = 5.0
    """How fast the acceleration ramps when a pause or a brake stops the vehicle (ArduCopter
    shapes a paused mission's speed, and BRAKE's, with its position controller's
    PSC_JERK_NE, not the legs' S-curve jerk)."""
    brake_decel: float = 7.5
    """The deceleration a brake (ArduCopter's BRAKE mode, BRAKE_MODE_DECEL_RATE_MSS) may
    ask for; its speed decays with the time constant brake_decel / stop_jerk
    (`scurve.brake_profile`). A pause stops at `accel`."""


@dataclass(frozen=True)
class _NextLeg:
    """The leg after the current target, flown from it once the current leg slows down."""

    to: tuple[float, float]
    direction: np.ndarray
    profile: Profile


class PointMassFleet:
    """Positions (east, north, alt), velocities and targets of n vehicles in one local frame."""

    def __init__(self, homes_en: np.ndarray) -> None:
        n = len(homes_en)
        self.time = 0.0
        self.pos = np.zeros((n, 3))
        self.pos[:, :2] = homes_en
        self.vel = np.zeros((n, 3))
        self.target = self.pos.copy()
        self.radius = np.full(n, 2.0)
        self.cruise = np.full(n, 10.0)
        self.accel = np.full(n, 2.5)
        self.jerk = np.full(n, 1.0)
        self.stop_jerk = np.full(n, 5.0)
        self.brake_decel = np.full(n, 7.5)
        self.clock = np.ones(n)
        """How fast each vehicle's legs run: 1 normally, down to 0 in a paused mission."""
        self.clock_rate = np.zeros(n)
        self.clock_to = np.ones(n)
        self.quick_start = np.zeros(n, dtype=bool)
        """The next leg from rest speeds up at the stopping jerk (a resumed pause picks up
        its track speed that way, not along a new S-curve)."""
        self.climb = np.full(n, 2.5)
        self.descent = np.full(n, 1.5)
        self.vertical_accel = np.full(n, 1.0)
        self.active = np.zeros(n, dtype=bool)
        """Motors driving the vehicle; inactive vehicles stand still."""
        self.reached = np.zeros(n, dtype=bool)
        """Latched once a vehicle meets its current target; cleared by a new target."""
        self.legs = _Legs(n)
        self.base = self.pos[:, :2].copy()
        """Where the finished legs left each vehicle; the legs flying add to it."""
        self.next_leg: list[_NextLeg | None] = [None] * n
        self.has_next = np.zeros(n, dtype=bool)
        self.blending = np.zeros(n, dtype=bool)
        """Flying the next leg already, while the one to the target finishes."""

    def __len__(self) -> int:
        return len(self.pos)

    def step(self, dt: float) -> None:
        self.time += dt
        if not self.active.any() and not self.legs.on.any():
            # Motors off everywhere and no leg to drop (on the ground before take-off and
            # after landing): what the full step below comes to, without its work.
            self.vel[:] = 0.0
            self.pos[self.pos[:, 2] <= 0.0, 2] = 0.0
            return
        warped = (self.clock < 1.0) | (self.clock_to < 1.0)
        if warped.any():
            self._run_clocks(dt, warped)
        self._step_horizontal()
        if warped.any():
            self.vel[:, :2] *= self.clock[:, None]
        self._step_vertical(dt)
        self.vel[~self.active] = 0.0
        self.pos[:, 2] += self.vel[:, 2] * dt
        on_ground = self.pos[:, 2] <= 0.0
        self.pos[on_ground, 2] = 0.0
        self.vel[on_ground & (self.vel[:, 2] < 0), 2] = 0.0
        self.reached |= self._arrived()

    def _step_horizontal(self) -> None:
        legs = self.legs
        stopped = ~self.active & legs.on.any(axis=1)
        if stopped.any():  # (masked writes skipped when nothing is masked: every step)
            self.base[stopped] = self.pos[stopped, :2]  # motors off: it stands where it is
            legs.on[stopped] = False
        if legs.on.any():
            offset, speed, finished, slowing = legs.evaluate(self.time)
            self.base += (legs.direction * (finished * legs.length)[..., None]).sum(axis=1)
            legs.on &= ~finished
            off = ~legs.on
            offset[off] = 0.0
            speed[off] = 0.0
            self.pos[:, :2] = self.base + (legs.direction * offset[..., None]).sum(axis=1)
            self.vel[:, :2] = (legs.direction * speed[..., None]).sum(axis=1)
            single = legs.on.sum(axis=1) == 1
            ready = self.has_next & ~self.blending & single & (slowing & legs.on).any(axis=1)
            if ready.any():
                for vehicle in np.flatnonzero(ready):
                    self._maybe_blend(int(vehicle))
        else:
            self.vel[:, :2] = 0.0
        idle = self.active & ~legs.on.any(axis=1)
        if idle.any():
            away = _distance(self.target[:, :2] - self.pos[:, :2]) > AT_TARGET_M
            for i in np.flatnonzero(idle & away):
                self.fly_leg(int(i), self.pos[i, :2], 0.0)  # overshot or braked: go there now

    def _run_clocks(self, dt: float, which: np.ndarray) -> None:
        """Shape the legs' clocks toward their targets and hold the legs back by what they
        lost. AC_WPNav shapes an offset speed from the track speed W down to 0 (a pause)
        or back up, at WP_ACC with PSC_JERK_NE; the clock is that speed over W. The speed
        changes here as a plain jerk-limited stop would, which is what SITL measured (a
        pause from 5 m/s: 6.65 m in 2.32 s; from 10 m/s: 23.19 m in 4.24 s)."""
        track = np.maximum(self.cruise[which], 0.1)
        accel, jerk = self.accel[which], self.stop_jerk[which]
        speed = self.clock[which] * track + self.clock_rate[which] * track * dt
        error = self.clock_to[which] * track - speed
        wanted = np.sign(error) * np.minimum(np.sqrt(2 * jerk * np.abs(error)), accel)
        wanted = np.clip(wanted, -np.abs(error) / dt, np.abs(error) / dt)
        rate = self.clock_rate[which] * track
        rate += np.clip(wanted - rate, -jerk * dt, jerk * dt)
        clock = np.clip(speed / track, 0.0, 1.0)
        rate[(clock <= 0.0) & (rate < 0)] = 0.0
        rate[(clock >= 1.0) & (rate > 0)] = 0.0
        self.clock[which], self.clock_rate[which] = clock, rate / track
        self.legs.start[which] += ((1.0 - clock) * dt)[:, None]

    def reset_clock(self, i: int) -> None:
        """Legs on the plain clock again (a mode change, a jump: AC_WPNav starts afresh)."""
        self.clock[i], self.clock_rate[i], self.clock_to[i] = 1.0, 0.0, 1.0

    def _maybe_blend(self, i: int) -> None:
        """Start the next leg now if ArduCopter would (SCurve's fast-waypoint test): this
        leg is slowing down, ends before the next one has sped up, and the middle of the
        blended turn is within the waypoint radius, slower than both legs and within the
        corner acceleration. Only the leg to the target blends; a brake does not."""
        legs, following = self.legs, self.next_leg[i]
        if following is None or legs.on[i].sum() != 1:
            return
        k = int(np.argmax(legs.on[i]))
        end = self.base[i] + legs.direction[i, k] * legs.length[i, k]
        if _distance(end - self.target[i, :2]) > ENDS_AT_TARGET_M:
            return  # braking somewhere else first
        elapsed = self.time - legs.start[i, k]
        remaining = legs.knots[i, k, -1] - elapsed
        if remaining > following.profile.accel_end:  # (it is slowing down: see the caller)
            return
        this = legs.profile(i, k)
        s, v, a = this.at(elapsed + remaining / 2)
        s_next, v_next, a_next = following.profile.at(remaining / 2)
        here = legs.direction[i, k]
        position = here * (s - this.length) + following.direction * s_next
        velocity = here * v + following.direction * v_next
        accel = here * a + following.direction * a_next
        slowest = min(this.states[:, 1].max(), following.profile.states[:, 1].max())
        if (
            _distance(position) < self.radius[i]
            and _distance(velocity) < slowest
            and _distance(accel) < CORNER_ACCEL_FACTOR * self.accel[i]
        ):
            legs.add(i, self.time, following.direction, following.profile)
            self.blending[i] = True

    def _arrived(self) -> np.ndarray:
        at_rest = ~self.legs.on.any(axis=1)
        at_rest &= _distance(self.target[:, :2] - self.pos[:, :2]) <= self.radius
        if self.blending.any():
            for i in np.flatnonzero(self.blending):
                at_rest[i] = self._half_way_round(int(i))
        vertical = np.abs(self.target[:, 2] - self.pos[:, 2]) < VERTICAL_TOLERANCE
        return self.active & at_rest & vertical

    def _half_way_round(self, i: int) -> bool:
        """Whether a blended corner has passed its middle (ArduPilot's `s_finished`): the
        next leg has flown as long as the last one has left to fly."""
        legs = self.legs
        if legs.on[i].sum() < 2:
            return True
        first, second = np.argsort(legs.start[i])
        left = legs.knots[i, first, -1] - (self.time - legs.start[i, first])
        return bool(self.time - legs.start[i, second] >= left)

    def _step_vertical(self, dt: float) -> None:
        error = self.target[:, 2] - self.pos[:, 2]
        rate = np.where(error > 0, self.climb, self.descent)
        speed = np.minimum(rate, np.sqrt(2 * self.vertical_accel * np.abs(error)))
        speed = np.minimum(speed, np.abs(error) / dt)
        change = np.sign(error) * speed - self.vel[:, 2]
        limit = self.vertical_accel * dt
        self.vel[:, 2] += np.clip(change, -limit, limit)

    def set_next_leg(self, i: int, leg: _NextLeg | None) -> None:
        self.next_leg[i] = leg
        self.has_next[i] = leg is not None

    def leg_to(
        self, i: int, start: np.ndarray, end: np.ndarray, entry_speed: float = 0.0
    ) -> tuple[np.ndarray, Profile] | None:
        """Direction and profile of a leg from `start` to `end` at vehicle i's limits (None
        if there is nowhere to go)."""
        vector = np.asarray(end, dtype=float) - start
        distance = float(_distance(vector))
        if distance <= AT_TARGET_M:
            return None
        up = self.stop_jerk[i] if self.quick_start[i] else None
        self.quick_start[i] = False
        profile = leg_profile(
            distance, entry_speed, self.cruise[i], self.accel[i], self.jerk[i], up
        )
        return vector / distance, profile

    def fly_leg(self, i: int, start: np.ndarray, entry_speed: float) -> None:
        """A leg from `start` (where the legs flying end) to the target."""
        leg = self.leg_to(i, start, self.target[i, :2], entry_speed)
        if leg is not None:
            self.legs.add(i, self.time, *leg)

    def brake_to_rest(self, i: int, accel: float | None = None, jerk: float | None = None) -> float:
        """Replace the legs flying with one slow-down along the velocity (at the legs'
        acceleration and jerk unless told otherwise); how far it goes."""
        speed = float(_distance(self.vel[i, :2]))
        accel = self.accel[i] if accel is None else accel
        jerk = self.jerk[i] if jerk is None else jerk
        return self._slow_down(
            i, leg_profile(stopping_distance(speed, accel, jerk), speed, speed, accel, jerk)
        )

    def brake_mode(self, i: int) -> float:
        """ArduCopter's BRAKE: the speed decays (`scurve.brake_profile`); how far it goes."""
        speed = float(_distance(self.vel[i, :2]))
        return self._slow_down(i, brake_profile(speed, self.brake_decel[i], self.stop_jerk[i]))

    def _slow_down(self, i: int, profile: Profile) -> float:
        self.reset_clock(i)
        self.base[i] = self.pos[i, :2]
        self.legs.on[i] = False
        self.blending[i] = False
        velocity = self.vel[i, :2].copy()
        speed = float(_distance(velocity))
        if speed <= AT_TARGET_M:
            return 0.0
        self.legs.add(i, self.time, velocity / speed, profile)
        return profile.length

    def body(self, index: int) -> Body:
        return Body(self, index)


def _distance(vectors: np.ndarray) -> np.ndarray:
    distance: np.ndarray = np.hypot(vectors[..., 0], vectors[..., 1])
    return distance


class _Legs:
    """Up to LEGS straight legs per vehicle: direction, length, start time and profile.

    A leg's offset along its direction is `start_offset` plus its profile's distance; the
    vehicle is at its base plus the offsets of its legs flying."""

    def __init__(self, n: int) -> None:
        self.on = np.zeros((n, LEGS), dtype=bool)
        self.direction = np.zeros((n, LEGS, 2))
        self.start_offset = np.zeros((n, LEGS))
        self.length = np.zeros((n, LEGS))
        self.start = np.zeros((n, LEGS))
        self.knots = np.zeros((n, LEGS, PHASES + 1))
        self.states = np.zeros((n, LEGS, PHASES + 1, 3))
        self.jerks = np.zeros((n, LEGS, PHASES))

    def add(
        self,
        i: int,
        now: float,
        direction: np.ndarray,
        profile: Profile,
        slot: int | None = None,
        start_offset: float = 0.0,
    ) -> None:
        """Fly `profile` along `direction` from now (in `slot`, default a free one)."""
        k = int(np.argmin(self.on[i])) if slot is None else slot
        self.on[i, k] = True
        self.direction[i, k] = direction
        self.start_offset[i, k] = start_offset
        self.length[i, k] = start_offset + profile.length
        self.start[i, k] = now
        self.knots[i, k] = profile.knots
        self.states[i, k] = profile.states
        self.jerks[i, k] = profile.jerks

    def profile(self, i: int, k: int) -> Profile:
        return Profile(self.jerks[i, k], self.knots[i, k], self.states[i, k])

    def elapsed(self, now: float) -> np.ndarray:
        return np.minimum(now - self.start, self.knots[..., -1])

    def newest(self) -> np.ndarray:
        """Each vehicle's latest leg flying (any slot if none)."""
        newest: np.ndarray = np.argmax(np.where(self.on, self.start, -np.inf), axis=1)
        return newest

    def evaluate(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Offset and speed of every leg now, which legs have finished and which are
        slowing down to their end."""
        shape = self.on.shape
        knots = self.knots.reshape(-1, PHASES + 1)
        tau = np.minimum(now - self.start.reshape(-1), knots[:, -1])
        phase = (tau[:, None] >= knots[:, 1:PHASES]).sum(axis=1)
        rows = np.arange(len(tau))
        state = self.states.reshape(-1, PHASES + 1, 3)[rows, phase]
        jerk = self.jerks.reshape(-1, PHASES)[rows, phase]
        state = advance(state, jerk, tau - knots[rows, phase])
        offset = self.start_offset.reshape(-1) + state[:, 0]
        speed = state[:, 1]
        finished = self.on & (tau >= knots[:, -1]).reshape(shape)
        slowing = (tau >= knots[:, DECEL_PHASE]).reshape(shape)
        offset = np.where(finished, self.length, offset.reshape(shape))
        return offset, speed.reshape(shape), finished, slowing


class Body:
    """One vehicle's handle on the fleet arrays: where it is and where it should go."""

    def __init__(self, fleet: PointMassFleet, index: int) -> None:
        self._fleet = fleet
        self.index = index

    @property
    def position(self) -> np.ndarray:
        """(east, north, alt above home), a copy."""
        position: np.ndarray = self._fleet.pos[self.index].copy()
        return position

    @property
    def velocity(self) -> np.ndarray:
        velocity: np.ndarray = self._fleet.vel[self.index].copy()
        return velocity

    @property
    def alt(self) -> float:
        return float(self._fleet.pos[self.index, 2])

    @property
    def ground_speed(self) -> float:
        vx, vy = self._fleet.vel[self.index, :2]
        return float(np.hypot(vx, vy))

    @property
    def reached(self) -> bool:
        return bool(self._fleet.reached[self.index])

    @property
    def active(self) -> bool:
        return bool(self._fleet.active[self.index])

    def set_active(self, active: bool) -> None:
        self._fleet.active[self.index] = active

    def apply_limits(self, limits: NavLimits) -> None:
        f, i = self._fleet, self.index
        f.cruise[i], f.accel[i], f.jerk[i] = limits.cruise_speed, limits.accel, limits.jerk
        f.stop_jerk[i], f.brake_decel[i] = limits.stop_jerk, limits.brake_decel
        f.climb[i], f.descent[i] = limits.climb_rate, limits.descent_rate
        f.vertical_accel[i] = limits.vertical_accel

    @property
    def cruise(self) -> float:
        return float(self._fleet.cruise[self.index])

    def set_cruise(self, speed: float, plateau_only: bool = False) -> None:
        """A new speed for the leg being flown and the one planned after it. A leg slowing
        down to its end already finishes as it is; with `plateau_only` (ArduCopter), one
        speeding up slows no more than by ending its constant acceleration now
        (`Flavour.slows_a_speed_up_only_by_its_plateau`)."""
        f, i = self._fleet, self.index
        f.cruise[i] = speed
        legs, k = f.legs, int(f.legs.newest()[i])
        elapsed = float(legs.elapsed(f.time)[i, k])
        if legs.on[i, k] and elapsed < legs.knots[i, k, DECEL_PHASE]:
            profile = legs.profile(i, k)
            peak = float(profile.states[3, 1])
            speeding_up = 0.0 < elapsed < profile.knots[3] and peak > profile.states[0, 1]
            if plateau_only and speeding_up and speed < peak:
                self._cut_plateau(k, profile, elapsed, speed)
            else:
                offset, leg_speed, _, _ = legs.evaluate(f.time)
                remaining = legs.length[i, k] - offset[i, k]
                profile = leg_profile(remaining, leg_speed[i, k], speed, f.accel[i], f.jerk[i])
                legs.add(i, f.time, legs.direction[i, k].copy(), profile, k, offset[i, k])
        following = f.next_leg[i]
        if following is not None and not f.blending[i]:
            self._plan_next(following.to)

    def _cut_plateau(self, k: int, profile: Profile, elapsed: float, speed: float) -> None:
        """Leg k, speeding up, told to go no faster than `speed`: its constant acceleration
        (phase 1) ends no sooner than now and its jerk ramps run on, so it peaks at
        `speed` or at what those ramps give; with no constant acceleration left it keeps
        its peak."""
        f, i = self._fleet, self.index
        begins, ends = float(profile.knots[1]), float(profile.knots[2])
        if elapsed >= ends or ends <= begins:
            return
        lowest = profile.states[3, 1] - profile.states[1, 2] * (ends - max(elapsed, begins))
        replanned = leg_profile(
            profile.length,
            float(profile.states[0, 1]),
            max(speed, float(lowest)),
            f.accel[i],
            f.jerk[i],
            float(profile.jerks[0]),
        )
        legs = f.legs
        start, offset = float(legs.start[i, k]), float(legs.start_offset[i, k])
        legs.add(i, start, legs.direction[i, k].copy(), replanned, k, offset)

    def set_descent(self, rate: float) -> None:
        self._fleet.descent[self.index] = rate

    def go_to(
        self,
        east: float,
        north: float,
        alt: float,
        radius: float,
        then: tuple[float, float] | None = None,
    ) -> None:
        """Fly to a point and stop there, or, given the point after it (`then`), round the
        corner into that leg where the autopilot would."""
        f, i = self._fleet, self.index
        following = f.next_leg[i]
        f.set_next_leg(i, None)
        continuing = (
            f.blending[i] and following is not None and np.allclose(following.to, (east, north))
        )
        f.target[i] = (east, north, alt)
        f.radius[i] = max(radius, 0.1)
        f.reached[i] = False
        f.blending[i] = False
        if f.active[i] and not continuing:
            self._redirect()
        if then is not None:
            self._plan_next(then)

    def _plan_next(self, then: tuple[float, float]) -> None:
        f, i = self._fleet, self.index
        leg = f.leg_to(i, f.target[i, :2], np.asarray(then, dtype=float))
        to = (float(then[0]), float(then[1]))
        f.set_next_leg(i, None if leg is None else _NextLeg(to, *leg))

    def _redirect(self) -> None:
        """Keep going if already heading for the target; otherwise brake to rest first
        (the fleet then starts the leg to the target from where the vehicle stops)."""
        f, i = self._fleet, self.index
        velocity = f.vel[i, :2]
        speed = float(np.hypot(*velocity))
        to_target = f.target[i, :2] - f.pos[i, :2]
        distance = float(np.hypot(*to_target))
        if speed > AT_TARGET_M and float(velocity @ to_target) < 0.999 * speed * distance:
            f.brake_to_rest(i)
            return
        f.base[i] = f.pos[i, :2]
        f.legs.on[i] = False
        f.fly_leg(i, f.pos[i, :2], speed)

    def stopping_point(self) -> tuple[float, float]:
        """Where a jerk-limited stop from the current velocity would end."""
        f, i = self._fleet, self.index
        vel = f.vel[i, :2]
        speed = float(np.hypot(*vel))
        if speed <= AT_TARGET_M:
            return float(f.pos[i, 0]), float(f.pos[i, 1])
        stop = stopping_distance(speed, f.accel[i], f.jerk[i])
        east, north = f.pos[i, :2] + vel / speed * stop
        return float(east), float(north)

    def hold(self, alt: float | None = None) -> None:
        """Brake to a stop and stay there (at `alt`, default the current altitude)."""
        east, north = self.stopping_point()
        self._fleet.reset_clock(self.index)
        self.go_to(east, north, self.alt if alt is None else alt, radius=0.5)

    def stop(self, brake: bool = False, alt: float | None = None) -> None:
        """Stop along the velocity and hover there (at `alt`, default the current
        altitude): a paused mission, or LAND, slows at the legs' acceleration with the
        stopping jerk (ArduCopter: AC_WPNav's pause shapes the track speed with
        PSC_JERK_NE, LAND its velocity); a brake's speed decays (BRAKE mode,
        `brake_profile`)."""
        f, i = self._fleet, self.index
        speed = float(np.hypot(*f.vel[i, :2]))
        direction = f.vel[i, :2] / speed if speed > AT_TARGET_M else np.zeros(2)
        reach = f.brake_mode(i) if brake else f.brake_to_rest(i, f.accel[i], f.stop_jerk[i])
        f.set_next_leg(i, None)
        f.target[i] = (*(f.pos[i, :2] + direction * reach), self.alt if alt is None else alt)
        f.radius[i] = 0.5
        f.reached[i] = False

    def pause_track(self) -> None:
        """ArduCopter's paused mission: the legs flown go on while their clock runs down."""
        self._fleet.clock_to[self.index] = 0.0

    def resume_track(self) -> None:
        """The paused legs' clock runs up again: the track picks up the speed it had."""
        self._fleet.clock_to[self.index] = 1.0

    def pick_up(self) -> None:
        """The next leg picks its speed up as a resumed pause does (at the stopping jerk)."""
        self._fleet.quick_start[self.index] = True

    def place(self, east: float, north: float, alt: float = 0.0) -> None:
        """Teleport at rest (a reboot puts the vehicle back on its home)."""
        f, i = self._fleet, self.index
        f.reset_clock(i)
        f.pos[i] = (east, north, alt)
        f.vel[i] = 0.0
        f.base[i] = (east, north)
        f.legs.on[i] = False
        self.go_to(east, north, alt, radius=0.5)
