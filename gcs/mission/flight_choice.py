"""Of several plans for one scenario, the one the copters fly soonest.

The planner ranks plans on its own clock, where a UAV changes speed at once. Copters
accelerate, brake, and stop wherever the passing order makes one let another pass first,
so plans the planner finds alike can fly far apart: over thirty seeds, the six-UAV swap
through a gap flies in 60 to 85 s at 5 m/s. Candidates differ in their seed and, each
`WIDER_M` more than the one before, in their clearance: a wider berth often means fewer
encounters to stop at (the 10-UAV crossing at 5 m/s: 93.0 s at 1.3 m, 83.8 s at 3 m),
and no candidate keeps less than was asked for. Each is timed as it would be flown
(`FlightPlan.duration_s`, the vehicles' own limits) and the soonest kept. A candidate the
ground station cannot keep safe at the speed, or whose order the vehicles cannot keep, is
passed over; only when every one is, is the flight refused.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

from gcs.mavlink.mission_item import Autopilot
from gcs.mission.flight_plan import FlightPlan, UnsafeSpeed, flight_plan
from gcs.mission.flight_timing import FlightStuck
from planner.model.plan import Plan
from planner.model.scenario import Scenario

Refusal = UnsafeSpeed | FlightStuck
MAX_CANDIDATES = 8
"""What the service plans for one request at most: each candidate is a plan and a timed
flight."""
WIDER_M = 0.5
"""How much more clearance each candidate keeps than the one before."""


def candidate(scenario: Scenario, clearance_m: float, k: int) -> Scenario:
    """The scenario the k-th candidate (from 0) is planned on: `clearance_m` and k steps of
    `WIDER_M` beyond 2R (`Scenario.with_clearance`)."""
    return scenario.with_clearance(clearance_m + k * WIDER_M)


@dataclass(frozen=True)
class Trial:
    """What one candidate plan came to: its timed flight, or why it cannot be flown."""

    seed: int
    duration_s: float | None = None
    refusal: str | None = None
    same_as: int | None = None  # the seed of an earlier candidate with the same paths

    def outcome(self) -> str:
        if self.same_as is not None:
            return f"the same paths as seed {self.same_as}"
        if self.refusal is not None:
            return self.refusal
        return f"{self.duration_s:.1f} s"


@dataclass(frozen=True)
class Choice:
    flight: FlightPlan
    plan: Plan  # the candidate as planned (the flight's is stretched to its speed)
    trials: list[Trial]


def soonest(plans: Iterable[Plan], fly_as: Callable[[Plan], FlightPlan]) -> Choice:
    """The feasible plan whose flight (`fly_as`) reaches its last goal soonest; the lowest
    seed among equals. Raises the most telling refusal when no candidate can be flown."""
    trials, best, refusals = _timed(plans, fly_as)
    if best is None:
        raise _most_telling(refusals)
    return Choice(best[0], best[1], trials)


def _timed(
    plans: Iterable[Plan], fly_as: Callable[[Plan], FlightPlan]
) -> tuple[list[Trial], tuple[FlightPlan, Plan] | None, list[Refusal]]:
    """Every candidate's trial, the soonest flight and its plan (None if none can be
    flown), and why the others cannot."""
    trials: list[Trial] = []
    refusals: list[Refusal] = []
    seen: dict[tuple[tuple[str, str], ...], int] = {}
    best: tuple[FlightPlan, Plan] | None = None
    for plan in plans:
        if not plan.feasible:
            trials.append(Trial(plan.seed, refusal="no safe plan"))
            continue
        paths = tuple((u.id, repr(u.trajectory)) for u in plan.uavs)
        if paths in seen:
            trials.append(Trial(plan.seed, same_as=seen[paths]))
            continue
        seen[paths] = plan.seed
        try:
            flight = fly_as(plan)
            duration = flight.duration_s
        except (UnsafeSpeed, FlightStuck) as exc:
            refusals.append(exc)
            trials.append(Trial(plan.seed, refusal=str(exc)))
            continue
        trials.append(Trial(plan.seed, duration_s=duration))
        if best is None or duration < best[0].duration_s:
            best = flight, plan
    return trials, best, refusals


def _most_telling(refusals: list[Refusal]) -> Exception:
    """The refusal naming the highest safe speed of any candidate, else the first; a
    ValueError when no candidate was even feasible."""
    unsafe = [r for r in refusals if isinstance(r, UnsafeSpeed)]
    if unsafe:
        return max(unsafe, key=lambda r: r.highest_safe_m_s or 0.0)
    if refusals:
        return refusals[0]
    return ValueError("no candidate plan is safe")


def soonest_by_default(
    plans: Sequence[Plan], scenario: Scenario, speed_m_s: float
) -> tuple[Plan, list[Trial]]:
    """The plan flown soonest at `speed_m_s` by ArduCopters with their default limits and
    the default mission options (as `GET /plans/{id}/timing` times it), for choosing before
    the vehicles are known, and every candidate's trial; the first feasible plan when none
    can be flown at that speed (the flight will say why), the first plan when none is
    feasible."""
    autopilots = dict.fromkeys((u.id for u in scenario.uavs), Autopilot.ARDUPILOT)

    def fly_as(plan: Plan) -> FlightPlan:
        return flight_plan(plan, scenario, autopilots, max_speed_m_s=speed_m_s)

    try:
        trials, best, _ = _timed(plans, fly_as)
    except ValueError:  # a scenario that cannot be flown at all (the flight will say why)
        trials, best = [], None
    if best is not None:
        return best[1], trials
    return next((p for p in plans if p.feasible), plans[0]), trials
