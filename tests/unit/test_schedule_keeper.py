"""The schedule keeper's decisions, and the rule that an operator's hold is authoritative."""

from __future__ import annotations

from dataclasses import replace

from hypothesis import given
from hypothesis import strategies as st

from gcs.fleet.holds import Holds
from gcs.fleet.route_tracker import VehicleProgress
from gcs.fleet.schedule_keeper import KeepingPolicy, decide

BASE = VehicleProgress(
    uav_id="a",
    sysid=1,
    mode="AUTO",
    armed=True,
    airborne=True,
    link_up=True,
    lat=0.0,
    lon=0.0,
    alt_m=10.0,
    current_seq=2,
    reached=1,
    items=5,
    distance_to_next_m=10.0,
    eta_s=1.0,
    scheduled_next_s=3.0,
    clock_s=5.0,
    plan_time_s=5.0,
    lag_s=0.0,
    paused=False,
    held=False,
    withdrawn=False,
    holding=False,
    landing=False,
    finished=False,
)


def progress(uav: str, lag: float, **changes: object) -> VehicleProgress:
    return replace(BASE, uav_id=uav, lag_s=lag, plan_time_s=5.0 - lag, **changes)  # type: ignore[arg-type]


def test_vehicles_ahead_of_a_laggard_wait_and_resume_once_it_caught_up() -> None:
    policy = KeepingPolicy(pause_margin_s=1.0, resume_margin_s=0.25)
    first = decide([progress("a", 2.0), progress("b", 0.5), progress("c", 1.5)], Holds(), policy)
    assert first.laggard == "a" and first.pause == {"b"} and not first.resume
    holds = Holds(keeper={"b"})
    later = decide([progress("a", 2.0), progress("b", 1.9), progress("c", 1.5)], holds, policy)
    assert later.resume == {"b"} and not later.pause


def test_two_vehicles_about_to_meet_keep_one_clock_whatever_the_fleets_laggard_does() -> None:
    """The bug this fixes: only vehicles near the one furthest behind ever waited, so two
    others crossing far from it drifted apart in time (3.9 s on ten ArduCopter SITL)."""
    far = 0.01  # degrees: over a kilometre from the others
    fleet = [
        progress("laggard", 40.0, lat=far, lon=far),
        progress("ahead", 34.9),
        progress("behind", 38.8),
    ]
    decision = decide(fleet, Holds(), KeepingPolicy(meet_distance_m=30.0))
    assert decision.pause == {"ahead"}
    assert decision.laggard == "behind" and decision.laggard_lag_s == 38.8


def test_a_finished_vehicle_neither_waits_nor_makes_others_wait() -> None:
    decision = decide(
        [progress("a", 9.0, finished=True), progress("b", 0.0)],
        Holds(keeper={"b"}),
        KeepingPolicy(),
    )
    assert decision.resume == {"b"} and not decision.pause


def test_every_vehicle_held_by_the_operator_stays_held() -> None:
    """The bug this rule fixes: all paused by the operator, all lags alike, all resumed."""
    everyone = {"a", "b", "c"}
    holds = Holds(operator=set(everyone), keeper=set(everyone))
    decision = decide([progress(u, 1.0) for u in sorted(everyone)], holds, KeepingPolicy())
    assert not decision.resume
    assert not holds.keeper_resumes(frozenset(everyone))


lags = st.floats(-5.0, 20.0, allow_nan=False)
uav_names = st.sampled_from(["a", "b", "c", "d", "e"])


@st.composite
def fleets(draw: st.DrawFn) -> tuple[list[VehicleProgress], Holds]:
    names = sorted(draw(st.sets(uav_names, min_size=1)))
    vehicles = [
        progress(
            name,
            draw(lags),
            finished=draw(st.booleans()),
            landing=draw(st.booleans()),
            holding=draw(st.booleans()),
            link_up=draw(st.booleans()),
            withdrawn=draw(st.booleans()),
        )
        for name in names
    ]
    subsets = st.sets(st.sampled_from(names))
    return vehicles, Holds(operator=draw(subsets), keeper=draw(subsets))


@given(fleets(), st.floats(0.1, 5.0), st.floats(0.0, 1.0))
def test_the_keeper_never_resumes_an_operator_hold(
    fleet: tuple[list[VehicleProgress], Holds], pause_margin: float, resume_margin: float
) -> None:
    vehicles, holds = fleet
    policy = KeepingPolicy(pause_margin_s=pause_margin, resume_margin_s=resume_margin)
    decision = decide(vehicles, holds, policy)
    assert not decision.resume & holds.operator
    assert decision.resume <= holds.keeper  # it lifts only its own pauses
    assert not decision.pause & holds.stopped  # nobody stopped twice
    moving = holds.keeper_resumes(decision.resume)
    assert not moving & holds.operator


@given(fleets())
def test_only_the_operators_continue_moves_a_held_vehicle(
    fleet: tuple[list[VehicleProgress], Holds],
) -> None:
    vehicles, holds = fleet
    held = set(holds.operator)
    for _ in range(3):  # several keeper ticks
        decision = decide(vehicles, holds, KeepingPolicy())
        holds.keeper_pauses(decision.pause)
        assert not holds.keeper_resumes(decision.resume) & held
    assert holds.operator == held
    moving = holds.release(held)
    assert moving == held - holds.keeper
