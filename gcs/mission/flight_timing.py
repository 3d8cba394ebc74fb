"""A plan as copters fly it: every UAV along its path with its vehicle's limits, waiting
where the passing order says, on one clock from the common start.

The plan's own times assume instant speed changes. Flown, each vehicle speeds up and
slows down along jerk-limited curves, slows for its corners and stops at its end
(`motion`), and where the passing order makes it wait for another (`passing_order`) it
is stopped by the same rule the flight uses (`StoppingRule`). Stepping all of them
together gives the trajectories the fleet will fly when nothing goes wrong: their
duration is the flight's (the benchmark's yardstick), their arrival at each waypoint the
schedule the console shows, and the exact safety check judges them.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from gcs.mission.geodesy import Floats
from gcs.mission.motion import (
    CopterLimits,
    Gate,
    StoppingRule,
    speed_profile,
    turn_angles,
)
from gcs.mission.passing_order import PassingOrder, PlannedPath
from planner.model.trajectory import Trajectory

APPROACH_LAG_S = 0.5
"""An approach from a stop flies its item afresh from rest (`FlightActions.approach`),
which ArduCopter starts about half a second later than a plain jerk-limited S-curve
would (it limits snap too: SITL reached half of 5 m/s 2.72 s into a leg from rest, the
S-curve 2.24 s; bench/results/kinematics_vs_sitl.txt)."""
STEP_S = 0.05
SAMPLE_S = 0.25
"""Seconds between the points of a timed trajectory: a straight line between two of
them is off the curve by at most accel·SAMPLE_S²/8, under 2 cm at 2.5 m/s²."""
NO_STOPS = np.zeros(0)
STOP_MATCH_M = 0.5  # a stop this close to a vertex is at that vertex
STOPPED_M_S = 0.05
ARRIVED_M = 0.5
"""Stopped this close short of a vertex it slowed down for, a vehicle is there: chasing
speeds stops a little short where ArduCopter's S-curve, planned to the point, does not."""


def _limit(
    order: PassingOrder | None, uav: str, progress: Mapping[str, float]
) -> tuple[float, str | None]:
    if order is None:
        return np.inf, None
    limit = order.limit(uav, progress)
    return limit.at_m, limit.leader


class FlightStuck(RuntimeError):
    """The simulated flight stopped moving before every vehicle arrived (a bug: the
    passing order cannot wait in a circle)."""


@dataclass(frozen=True)
class TimedPath:
    """Where one vehicle is along its path, second by second, flown as a copter flies,
    until it is down at its end."""

    path: PlannedPath
    t: Floats  # seconds from the common start
    s: Floats  # metres along the path
    arrival_s: float  # over its end; it is down at t[-1]

    def time_at(self, s: float) -> float:
        """When the vehicle first gets `s` metres along its path."""
        k = int(np.searchsorted(self.s, s - 1e-9, side="left"))
        return float(self.t[min(k, len(self.t) - 1)])

    def trajectory(self, cell_m: float) -> Trajectory:
        """In the plan's terms: `[t, x, y]` in cells."""
        along = self.path.s
        x = np.interp(self.s, along, self.path.xy[:, 0]) / cell_m
        y = np.interp(self.s, along, self.path.xy[:, 1]) / cell_m
        return Trajectory(np.column_stack([self.t, x, y]))


@dataclass
class _Vehicle:
    """One vehicle of the simulated fleet."""

    path: PlannedPath
    limits: CopterLimits
    vertex_s: list[float]  # plain floats: stepped 20 times a simulated second, one by one
    vertex_speed: list[float]  # the highest speed at each vertex (corners, the end)
    leg_speed: list[float]  # m/s of each leg, as flown
    commanded: list[float]  # m/s of each leg, as its mission sets it
    s: float = 0.0
    v: float = 0.0
    a: float = 0.0
    gate: Gate = Gate.GO
    done: bool = False
    slowing_for: set[int] = field(default_factory=set)  # the vertices it slows for
    approach_m_s: float = 0.0  # how fast it approaches its limit (CREEP)
    starting_s: float = 0.0  # still to wait before an approach from a stop moves it
    ceiling: float = math.inf  # the speed of the S-curve into the stop it slows for
    stopping_from: dict[int, float] = field(default_factory=dict)  # stop vertex: speed then
    clock: float = 1.0  # how fast its S-curve runs: 1 flying, down to 0 paused
    clock_rate: float = 0.0  # the clock's change per second
    desired_m_s: float | None = None  # the speed last commanded (None: its legs')

    @classmethod
    def of(
        cls, path: PlannedPath, leg_speed: Floats, limits: CopterLimits, stops: Floats = NO_STOPS
    ) -> _Vehicle:
        """`stops`: metres along the path where the autopilot comes to rest."""
        s = path.s
        turns = turn_angles(path.xy) if len(s) > 2 else np.zeros(0)
        at_rest = np.abs(s[:, None] - np.asarray(stops)[None, :]).min(axis=1, initial=np.inf)
        knots, bound, legs = speed_profile(s, leg_speed, turns, limits, at_rest < STOP_MATCH_M)
        return cls(path, limits, knots.tolist(), bound.tolist(), legs.tolist(), leg_speed.tolist())

    def cap(self, rule: StoppingRule) -> float:
        """The speed the vehicle aims for here: its leg's (or its gate's), until it must
        slow down for one of the next two vertices, as an S-curve does: from the moment
        what is left is what slowing down from its speed and acceleration takes, it aims
        for the vertex's speed (and lets go again if it stops short of it); into a stop,
        no faster than the end of an S-curve from the speed it had there (`ceiling`). The
        vertex after next counts too: a vertex's speed assumes the vehicle gets there no
        longer speeding up, which one that sets off just before it is not."""
        k = self._next_vertex()
        if self.slowing_for and self.v < STOPPED_M_S:  # stopped for it
            if k in self.slowing_for and self.vertex_s[k] - self.s <= ARRIVED_M:
                self.s = float(self.vertex_s[k])  # there: on to the next one
                k = self._next_vertex()
            self.slowing_for.clear()  # (or stopped short of it: on again)
        self.slowing_for.intersection_update(range(k, len(self.vertex_s)))
        self.stopping_from = {j: v for j, v in self.stopping_from.items() if j in self.slowing_for}
        leg = self.leg_speed[max(0, k - 1)] if len(self.leg_speed) else 0.0
        if self.desired_m_s is not None:
            leg = min(leg, self.desired_m_s)
        peak = self.v + max(self.a, 0.0) ** 2 / (2 * self.limits.s_curve_jerk_m_s3)  # once `a` is 0
        for j in range(k, min(k + 2, len(self.vertex_s))):
            ahead = self.vertex_speed[j]
            if peak > ahead and self.vertex_s[j] - self.s <= self.limits.slowing_distance(
                self.v, self.a, ahead
            ):
                self.slowing_for.add(j)
                if ahead == 0.0:
                    self.stopping_from.setdefault(j, peak)
        corners = [self.vertex_speed[j] for j in self.slowing_for if self.vertex_speed[j] > 0]
        self.ceiling = min(
            (
                self.limits.speed_before_rest(self.vertex_s[j] - self.s, self.stopping_from[j])
                for j in self.slowing_for
                if self.vertex_speed[j] == 0.0
            ),
            default=math.inf,
        )
        return min([leg, self.ceiling, *corners])

    def _next_vertex(self) -> int:
        return min(bisect.bisect_right(self.vertex_s, self.s), len(self.vertex_s) - 1)

    @property
    def speed(self) -> float:
        """The speed it flies at (and reports): its S-curve's, slowed by the clock."""
        return self.v * self.clock

    @property
    def accel(self) -> float:
        """The acceleration it flies with (and reports)."""
        return self.a * self.clock**2 + self.v * self.clock_rate

    def command(self, gate: Gate, approach_m_s: float | None = None) -> None:
        """The ground station's commands for `gate`, as the flight sends them
        (`GateCommander`; the same gate again changes nothing): a pause for STOP; an
        approach from a stop flies its item afresh from rest, at the approach's speed;
        otherwise the speed is set (the mission's for GO) and a paused clock resumed."""
        if gate == Gate.CREEP and self.gate == Gate.STOP:
            self.v = self.a = self.clock_rate = 0.0
            self.clock = 1.0
            self.starting_s = APPROACH_LAG_S
        if gate != Gate.STOP:
            self.desired_m_s = approach_m_s if gate == Gate.CREEP else None
        self.gate = gate

    def step(self, target: float, dt: float) -> None:
        """Chase `target` speed along the S-curve: acceleration from a square-root
        shaper, ramped at the jerk limit, as ArduPilot's shape_vel_accel does, on the
        curve's own clock."""
        limits = self.limits
        if self.starting_s > 0:
            self.starting_s -= dt
            target = 0.0
        self._run_clock(dt)
        dt_curve = self.clock * dt
        jerk = limits.s_curve_jerk_m_s3
        self.a += _shaped(target - self.v, self.a, jerk, limits.accel_m_s2, dt_curve)
        self.v = max(0.0, self.v + self.a * dt_curve)
        if self.v > self.ceiling and dt_curve > 0:  # into a stop: along the S-curve's end
            self.a -= (self.v - self.ceiling) / dt_curve
            self.v = self.ceiling
        if self.v == 0.0 and self.a < 0:
            self.a = 0.0
        self.s = min(self.path.length, self.s + self.v * dt_curve)
        if self.path.length - self.s < 1e-3 and self.v < 0.05:
            self.s, self.v, self.a, self.done = self.path.length, 0.0, 0.0, True

    def _run_clock(self, dt: float) -> None:
        """A paused mission is not braked: AC_WPNav shapes an offset speed from the
        track's speed down to nothing (a pause) or back up (a resume) at WPNAV's
        acceleration and the position controller's jerk, and runs its S-curve on that
        over the track's speed (SITL paused speeding up at 3.4 m/s on a 10 m/s track went
        on 7 m in 4 s, and resumed took 4 s to its speed again; stopped at once, the
        timing ran seconds ahead of every wait)."""
        goal = 0.0 if self.gate == Gate.STOP else 1.0
        if self.clock == goal and self.clock_rate == 0.0:
            return
        leg = self.commanded[max(0, self._next_vertex() - 1)] if self.commanded else 1.0
        track = max(self.desired_m_s or leg, 1e-3)
        limits, rate = self.limits, self.clock_rate * track
        error = (goal - self.clock) * track
        rate += _shaped(error, rate, limits.stop_jerk_m_s3, limits.accel_m_s2, dt)
        clock = min(max(self.clock + rate * dt / track, 0.0), 1.0)
        if clock in (0.0, 1.0) and (clock - self.clock) * rate <= 0:
            rate = 0.0
        self.clock, self.clock_rate = clock, rate / track


def _shaped(error: float, accel: float, jerk: float, most: float, dt: float) -> float:
    """The change of `accel` over `dt` that closes a speed `error` as a square-root shaper
    does: no faster than `most`, ramped at `jerk`."""
    wanted = min(math.sqrt(2 * jerk * abs(error)), most)
    wanted = math.copysign(wanted, error) if error else 0.0
    change = jerk * dt
    return min(max(wanted - accel, -change), change)


def fly(
    paths: Mapping[str, PlannedPath],
    leg_speeds: Mapping[str, Floats],
    limits: Mapping[str, CopterLimits],
    order: PassingOrder | None = None,
    rule: StoppingRule | None = None,
    altitude_m: float = 20.0,
    max_s: float = 7200.0,
    stops: Mapping[str, Floats] | None = None,
) -> dict[str, TimedPath]:
    """Every vehicle from the common start to its end, waiting where `order` says and
    coming to rest at its `stops` (metres along its path). A vehicle at its end is in the
    others' way until it has landed there."""
    rule = rule or StoppingRule()
    stops = stops or {}
    fleet = {
        uav: _Vehicle.of(p, leg_speeds[uav], limits[uav], stops.get(uav, NO_STOPS))
        for uav, p in paths.items()
    }
    t, last_move = 0.0, 0.0
    every = max(1, round(SAMPLE_S / STEP_S))
    rows: dict[str, list[tuple[float, float]]] = {uav: [(0.0, 0.0)] for uav in fleet}
    steps = 0
    down_at = {uav: np.inf for uav in fleet}
    while not all(v.done for v in fleet.values()):
        progress = {uav: np.inf if t >= down_at[uav] else v.s for uav, v in fleet.items()}
        limits_now = {uav: _limit(order, uav, progress) for uav in fleet}
        waited_on = {leader for _, leader in limits_now.values() if leader is not None}
        for uav, vehicle in fleet.items():
            if vehicle.done:
                continue
            at, _ = limits_now[uav]
            gap, waited = at - vehicle.s, uav in waited_on
            accel = vehicle.limits.accel_m_s2 if t == 0.0 else vehicle.accel  # as `launch` starts
            gate = rule.decide(
                vehicle.gate, gap, vehicle.speed, accel, vehicle.limits, waited,
                vehicle.approach_m_s or None,
            )  # fmt: skip
            if gate == Gate.CREEP and vehicle.gate != Gate.CREEP:
                vehicle.approach_m_s = rule.approach_speed(gap, vehicle.limits, waited) or 0.0
            elif gate == Gate.CREEP:
                sent = vehicle.approach_m_s or None
                faster = rule.faster_approach(gap, vehicle.limits, waited, sent)
                vehicle.approach_m_s = faster or vehicle.approach_m_s
            vehicle.command(gate, vehicle.approach_m_s)
            before = vehicle.s
            vehicle.step(vehicle.cap(rule), STEP_S)
            if vehicle.s > before + 1e-9:
                last_move = t
            if vehicle.done:
                down_at[uav] = t + vehicle.limits.landing_time(altitude_m)
        t += STEP_S
        steps += 1
        for uav, vehicle in fleet.items():
            if rows[uav][-1][1] < vehicle.path.length and (steps % every == 0 or vehicle.done):
                rows[uav].append((t, vehicle.s))
        if t - last_move > 600.0 or t > max_s:
            waiting = sorted(uav for uav, v in fleet.items() if not v.done)
            raise FlightStuck(f"{waiting} stopped moving at {t:.0f} s of the simulated flight")
    timed = {}
    for uav, vehicle in fleet.items():  # over its end until it is down
        arrival = rows[uav][-1][0]
        rows[uav].append((down_at[uav], vehicle.path.length))
        t_s, s_m = np.array(rows[uav]).T
        timed[uav] = TimedPath(paths[uav], t_s, s_m, arrival)
    return timed
