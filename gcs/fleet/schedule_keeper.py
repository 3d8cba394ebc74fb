"""Keeping vehicles on one clock: who waits for whom when someone falls behind.

The plan is safe only if every vehicle is where the plan says at the same moment.
A vehicle that falls behind its schedule by more than `pause_margin_s` relative to
another one within `meet_distance_m` of it (None: anywhere) makes that other one wait
(DO_PAUSE_CONTINUE) until it is within `resume_margin_s` of every vehicle near it that
is behind. Pairs, not one fleet-wide laggard: with many vehicles the one furthest
behind is often far away, while two others about to cross drift apart in time (flown
on ArduCopter SITL, ten vehicles: 3.9 s apart at their crossing, 6.06 m for a 7.07 m
plan). A vehicle holding at a waypoint is left alone, it is waiting already (and an
autopilot may restart the hold on resume). Besides, a vehicle the conflict guard
(`conflict_guard`) says must give way waits, whatever its lag, until the guard lets it go,
and one the guard says stands in the way of the vehicle furthest behind goes on.

The keeper only ever resumes what it paused itself: a vehicle the operator holds stays
held (it may well be the laggard the others wait for) until the operator continues it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from gcs.fleet.conflict_guard import GuardPolicy, Outlook
from gcs.fleet.holds import Holds
from gcs.fleet.route_tracker import VehicleProgress
from gcs.mission.geodesy import distance_m


@dataclass(frozen=True)
class KeepingPolicy:
    pause_margin_s: float = 1.5
    resume_margin_s: float = 0.3
    meet_distance_m: float | None = 30.0
    guard: GuardPolicy = field(default_factory=GuardPolicy)


@dataclass(frozen=True)
class KeepingDecision:
    pause: frozenset[str] = field(default_factory=frozenset)
    resume: frozenset[str] = field(default_factory=frozenset)
    laggard: str | None = None  # the one furthest behind of those the paused wait for
    laggard_lag_s: float = 0.0


def decide(
    progress: list[VehicleProgress],
    holds: Holds,
    policy: KeepingPolicy,
    outlook: Outlook | None = None,
) -> KeepingDecision:
    """Which vehicles the keeper pauses and which of its own pauses it lifts, now, given
    what the conflict guard foresees (who must wait for whom, which pairs will meet)."""
    mine = holds.keeper - holds.operator
    flying = in_the_plan(progress)
    if not flying:
        return KeepingDecision(resume=frozenset(mine))
    outlook = outlook or Outlook()
    gives_way = outlook.gives_way
    by_id = {p.uav_id: p for p in progress}
    pause, resume, waited_for = set(), set(), []
    for p in flying:
        near = [
            q
            for q in flying
            if q is not p
            and q.uav_id not in gives_way  # waiting itself: none waits for it, no cycles
            and _near(p, q, policy.meet_distance_m, outlook)
        ]
        behind = max(near, key=lambda q: q.lag_s, default=p)
        ahead_by = behind.lag_s - p.lag_s
        yields_to = by_id.get(gives_way.get(p.uav_id, ""))
        in_the_way = p.uav_id in outlook.must_go
        late = ahead_by > policy.pause_margin_s and not in_the_way
        caught_up = ahead_by <= policy.resume_margin_s or in_the_way
        if p.uav_id not in holds.stopped and (late or yields_to) and not p.holding:
            pause.add(p.uav_id)
            waited_for.append(behind if late or yields_to is None else yields_to)
        elif p.uav_id in mine and caught_up and yields_to is None:
            resume.add(p.uav_id)
    flying_ids = {p.uav_id for p in flying}
    resume |= {uav for uav in mine if uav not in flying_ids}  # finished or lost: let go
    laggard = max(waited_for or flying, key=lambda p: p.lag_s)
    return KeepingDecision(frozenset(pause), frozenset(resume), laggard.uav_id, laggard.lag_s)


def in_the_plan(progress: list[VehicleProgress]) -> list[VehicleProgress]:
    """The vehicles flying their plan now: up, linked, neither done, landing nor sent away."""
    return [p for p in progress if not (p.finished or p.landing or p.withdrawn) and p.link_up]


def coming_down(progress: list[VehicleProgress]) -> list[VehicleProgress]:
    """The vehicles at the end of their plan, landing there (or landed, not yet disarmed)."""
    return [p for p in progress if p.landing and not (p.finished or p.withdrawn) and p.link_up]


def _near(a: VehicleProgress, b: VehicleProgress, limit_m: float | None, outlook: Outlook) -> bool:
    """Within `limit_m` now, or soon as they fly on."""
    if limit_m is None or outlook.meets(a.uav_id, b.uav_id, limit_m):
        return True
    if a.lat is None or a.lon is None or b.lat is None or b.lon is None:
        return True
    return distance_m(a.lat, a.lon, b.lat, b.lon) <= limit_m
