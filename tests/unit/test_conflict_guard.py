"""The conflict guard: drift the schedule keeper's margin allows must not cost a pair
more than the plan's closest approach less the tolerance, nor may anyone fly past a
vehicle coming down at its goal."""

from __future__ import annotations

from dataclasses import replace

from gcs.fleet.conflict_guard import ConflictGuard, GuardPolicy
from gcs.fleet.holds import Holds
from gcs.fleet.route_tracker import RouteTracker, VehicleProgress
from gcs.fleet.schedule_keeper import KeepingPolicy, decide
from gcs.mission.build import Visit

from .test_schedule_keeper import BASE

M = 1 / 111_320.0  # degrees per metre near the equator, close enough for these tests
GAP_S = 7.0 * 2**0.5  # B crosses A's line this much later: the plan keeps them 7 m apart


def tracker(uav: str, start: tuple[float, float], *visits: Visit) -> RouteTracker:
    return RouteTracker(uav, list(visits), (start[1] * M, start[0] * M))


def visit(seq: int, east: float, north: float, arrive: float, leave: float | None = None) -> Visit:
    return Visit(seq, arrive, arrive if leave is None else leave, north * M, east * M)


# A flies east along y = 0 at 1 m/s; B waits GAP_S, then flies north along x = 0.
TRACKERS = {
    "a": tracker("a", (-20.0, 0.0), visit(2, 20.0, 0.0, 40.0)),
    "b": tracker(
        "b", (0.0, -20.0), visit(2, 0.0, -20.0, 0.0, GAP_S), visit(3, 0.0, 20.0, GAP_S + 40.0)
    ),
}


def at(uav: str, plan_time: float, clock: float = 20.0, **changes: object) -> VehicleProgress:
    """Vehicle `uav` where its plan puts it at `plan_time`, on a plan clock of `clock`."""
    if uav == "a":
        east, north = -20.0 + plan_time, 0.0
    else:
        east, north = 0.0, -20.0 + max(0.0, plan_time - GAP_S)
    return replace(
        BASE,
        uav_id=uav,
        lat=north * M,
        lon=east * M,
        clock_s=clock,
        plan_time_s=plan_time,
        lag_s=clock - plan_time,
        **changes,  # type: ignore[arg-type]
    )


def test_the_plan_itself_keeps_the_pair_seven_metres_apart() -> None:
    assert abs(ConflictGuard(GuardPolicy()).plan_closest_m(TRACKERS) - 7.0) < 0.05


def test_a_pair_on_one_clock_flies_on() -> None:
    outlook = ConflictGuard(GuardPolicy()).gives_way([at("a", 15.0), at("b", 15.0)], [], TRACKERS)
    assert outlook.gives_way == {}


def test_the_one_ahead_waits_although_the_lag_margin_allows_the_drift() -> None:
    """B 1.2 s ahead of A: under the keeper's 1.5 s margin, and 6.15 m at the crossing
    against the plan's 7 m. Waiting, B stands well off A's line; A standing would be in
    B's way."""
    fleet = [at("a", 13.8), at("b", 15.0)]
    policy = KeepingPolicy()
    assert decide(fleet, Holds(), policy).pause == frozenset()  # the lag keeper alone
    outlook = ConflictGuard(policy.guard).gives_way(fleet, [], TRACKERS)
    assert outlook.gives_way == {"b": "a"}
    decision = decide(fleet, Holds(), policy, outlook)
    assert decision.pause == {"b"} and decision.laggard == "a"


def test_the_one_waiting_is_not_resumed_while_it_would_still_come_too_close() -> None:
    guard, policy = ConflictGuard(GuardPolicy()), KeepingPolicy()
    waiting = [at("a", 13.8, clock=20.0), at("b", 15.0, clock=20.0, paused=True)]
    outlook = guard.gives_way(waiting, [], TRACKERS)
    assert outlook.gives_way == {"b": "a"}
    assert not decide(waiting, Holds(keeper={"b"}), policy, outlook).resume
    caught_up = [at("a", 15.0, clock=21.2), at("b", 15.0, clock=21.2, paused=True)]
    outlook = guard.gives_way(caught_up, [], TRACKERS)
    assert outlook.gives_way == {}
    assert decide(caught_up, Holds(keeper={"b"}), policy, outlook).resume == {"b"}


def test_a_vehicle_waits_for_one_coming_down_in_its_way() -> None:
    """The plan counts a vehicle at its goal as gone; in the air it is an obstacle."""
    lander = replace(at("b", 0.0), lat=2.0 * M, lon=0.0, landing=True, airborne=True)
    guard = ConflictGuard(GuardPolicy())
    assert guard.gives_way([at("a", 15.0)], [lander], TRACKERS).gives_way == {"a": "b"}
    on_the_ground = replace(lander, airborne=False)
    assert guard.gives_way([at("a", 15.0)], [on_the_ground], TRACKERS).gives_way == {}


def test_the_keeper_keeps_two_far_apart_on_one_clock_when_their_plans_meet_soon() -> None:
    """30 m apart now, so the old keeper let them drift; their plans meet within the
    guard's horizon, so the one ahead waits for the other."""
    fleet = [at("a", 0.0, clock=3.0), at("b", 5.0, clock=5.0)]  # a 3 s behind, 28 m off
    assert decide(fleet, Holds(), KeepingPolicy(meet_distance_m=10.0)).pause == frozenset()
    policy = KeepingPolicy(meet_distance_m=10.0)
    outlook = ConflictGuard(policy.guard).gives_way(fleet, [], TRACKERS)
    assert decide(fleet, Holds(), policy, outlook).pause == {"b"}


def test_the_one_furthest_behind_never_waits_and_one_stopped_in_its_way_goes_on() -> None:
    """B stopped for A at (0, 5), on A's line 5 m off; A 18 s behind it. Had A waited
    for B as B waited for A, the flight would stand still (the mock's ten-UAV crossing
    did, in CI); B going on north keeps them 7 m apart, so B goes."""
    fleet = [at("a", 15.0, clock=33.0), at("b", GAP_S + 25.0, clock=33.0, paused=True)]
    policy = KeepingPolicy()
    outlook = ConflictGuard(policy.guard).gives_way(fleet, [], TRACKERS)
    assert outlook.gives_way == {} and outlook.must_go == {"b"}
    decision = decide(fleet, Holds(keeper={"b"}), policy, outlook)
    assert decision.resume == {"b"} and not decision.pause
