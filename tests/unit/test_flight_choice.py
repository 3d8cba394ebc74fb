"""Of several plans, the one the copters fly soonest: timed as flown, refusals passed over,
the most telling refusal raised when nothing can be flown."""

from __future__ import annotations

import dataclasses
from functools import cache

import pytest

from gcs.mavlink.mission_item import Autopilot
from gcs.mission.flight_choice import soonest, soonest_by_default
from gcs.mission.flight_plan import DEFAULT_CLEARANCE_M, FlightPlan, UnsafeSpeed, flight_plan
from gcs.mission.flight_timing import FlightStuck
from planner.experiments.scenario_generator import gap_swap_scenario
from planner.model.plan import Plan
from planner.model.scenario import Origin, Scenario
from planner.pipeline import PlannerSettings, plan

SEEDS = (1, 2, 3)
"""On this swap, seed 3's plan flies some twenty seconds sooner at 5 m/s than 1's or 2's."""


@cache
def _swap() -> Scenario:
    scenario = gap_swap_scenario(0, uavs=6)
    return scenario.model_copy(update={"origin": Origin(lat=-35.36, lon=149.16, alt_m=584.0)})


@cache
def _plans() -> tuple[Plan, ...]:
    """As `mvo-gcs fly --time-budget 0` plans them: the same on every machine."""
    widened = _swap().with_clearance(DEFAULT_CLEARANCE_M)
    settings = PlannerSettings(time_budget_s=None)
    return tuple(plan(widened, dataclasses.replace(settings, seed=s)) for s in SEEDS)


def _at_5(candidate: Plan) -> FlightPlan:
    autopilots = {u.id: Autopilot.ARDUPILOT for u in _swap().uavs}
    return flight_plan(candidate, _swap(), autopilots, max_speed_m_s=5.0)


def test_the_plan_flown_soonest_is_chosen_and_every_candidate_is_timed_as_flown() -> None:
    choice = soonest(_plans(), _at_5)
    durations = {p.seed: _at_5(p).duration_s for p in _plans()}
    assert [t.seed for t in choice.trials] == list(SEEDS)
    assert {t.seed: t.duration_s for t in choice.trials} == durations
    fastest = min(durations, key=durations.__getitem__)
    assert choice.plan.seed == fastest
    assert choice.flight.duration_s == durations[fastest]
    assert len(set(durations.values())) > 1, "the seeds should differ, or nothing is chosen"


def test_a_candidate_with_the_same_paths_is_not_timed_again() -> None:
    first = _plans()[0]
    again = first.model_copy(update={"seed": 9})
    timed: list[int] = []

    def at_5(candidate: Plan) -> FlightPlan:
        timed.append(candidate.seed)
        return _at_5(candidate)

    choice = soonest([first, again], at_5)
    assert timed == [first.seed]
    assert choice.trials[1].same_as == first.seed
    assert choice.plan.seed == first.seed


def test_a_refused_candidate_is_passed_over() -> None:
    refused_seed = min(_plans(), key=lambda p: _at_5(p).duration_s).seed

    def refusing(candidate: Plan) -> FlightPlan:
        if candidate.seed == refused_seed:
            raise FlightStuck("uav1 and uav3 wait for each other")
        return _at_5(candidate)

    choice = soonest(_plans(), refusing)
    assert choice.plan.seed != refused_seed
    refused = next(t for t in choice.trials if t.seed == refused_seed)
    assert refused.duration_s is None and "wait for each other" in (refused.refusal or "")


def test_when_nothing_can_be_flown_the_highest_safe_speed_of_any_candidate_is_named() -> None:
    highest = {1: 3.0, 2: 4.5, 3: None}

    def unsafe(candidate: Plan) -> FlightPlan:
        raise UnsafeSpeed(f"seed {candidate.seed}", highest[candidate.seed])

    with pytest.raises(UnsafeSpeed) as refused:
        soonest(_plans(), unsafe)
    assert refused.value.highest_safe_m_s == 4.5 and str(refused.value) == "seed 2"


def test_an_infeasible_candidate_is_skipped_and_none_feasible_is_an_error() -> None:
    infeasible = _plans()[0].model_copy(update={"feasible": False, "seed": 7})
    choice = soonest([infeasible, _plans()[1]], _at_5)
    assert choice.plan.seed == _plans()[1].seed
    assert choice.trials[0].refusal == "no safe plan"
    with pytest.raises(ValueError, match="no candidate plan is safe"):
        soonest([infeasible], _at_5)


def test_chosen_before_the_vehicles_are_known_every_trial_is_kept() -> None:
    """The service's choice (ArduCopter's defaults) gives each candidate's trial with the
    plan; when none can be flown at the speed it keeps the first, and says why each not."""
    kept, trials = soonest_by_default(_plans(), _swap(), 5.0)
    assert kept.seed == soonest(_plans(), _at_5).plan.seed
    assert [t.duration_s for t in trials] == [_at_5(p).duration_s for p in _plans()]
    first, trials = soonest_by_default(_plans(), _swap(), 20.0)  # faster than any keeps safe
    assert first.seed == _plans()[0].seed
    assert all(t.duration_s is None and "highest speed" in (t.refusal or "") for t in trials)
