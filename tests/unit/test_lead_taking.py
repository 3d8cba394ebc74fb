"""A vehicle stopped inside an encounter it was to wait short of leads it there, where its
leader can still stop short; every circle of waits that makes is broken, or nothing
changes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

from gcs.fleet.gatekeeper import Gatekeeper
from gcs.fleet.lead_taking import lead_ahead, take_the_lead
from gcs.mission.motion import CopterLimits, Gate
from gcs.mission.passing_order import PassingOrder, PlannedPath, Waits
from tests.unit.test_passing_order import PLANS, _crossing_pair, _path, fly_adversary, planned
from tests.unit.test_replan_gates import _flying

LIMITS = {"a": CopterLimits(speed_m_s=5.0), "b": CopterLimits(speed_m_s=5.0)}


def _crossing() -> tuple[dict[str, PlannedPath], Gatekeeper]:
    """a crosses (50, 0) first; b, 5 s later, waits short of it."""
    paths = _crossing_pair(offset_s=5.0)
    return paths, Gatekeeper(PassingOrder.derive(paths.values(), margin_m=0.5), LIMITS)


def test_a_vehicle_stopped_inside_its_encounter_goes_first_and_its_leader_waits() -> None:
    """b's stop came late: it stands 2 m past where it was to wait for a, which would
    fly by it closer than 2R (fuzzed flight 6698: 5.43 m, 2R 6 m). b goes on, and a,
    still 30 m off, waits short of the crossing until b is through."""
    paths, keeper = _crossing()
    limit = keeper.order.limit("b", {"a": 10.0, "b": 0.0}).at_m
    progress = _flying(paths, {"a": 10.0, "b": limit + 2.0})
    progress["b"].speed = 0.0

    keeper.decide(progress, ["a", "b"])

    [(uav, past, turned, unheard)] = keeper.leads_taken
    assert not unheard
    assert (uav, turned) == ("b", [("b", "a")])
    assert past == pytest.approx(2.0)
    assert keeper.gates["b"] == Gate.GO
    a_limit = keeper.order.limit("a", {"a": 10.0, "b": limit + 2.0})
    assert a_limit.leader == "b"
    assert a_limit.at_m <= 50.0 - 6.0  # short of the crossing by 2R
    progress["a"].s = a_limit.at_m - 1.0
    [change] = keeper.decide(progress, ["a", "b"])
    assert (change.uav_id, change.gate, change.waits_for) == ("a", Gate.STOP, "b")
    assert keeper.order.limit("a", {"a": 40.0, "b": 50.0 + 7.0}).at_m == math.inf  # b through


@pytest.mark.parametrize(
    ("a_at", "b_past", "b_speed"),
    [(42.0, 2.0, 0.0), (10.0, 0.3, 0.0), (10.0, 2.0, 1.0)],
    ids=["leader-too-close-to-stop", "only-just-past", "still-moving"],
)
def test_otherwise_the_order_stays(a_at: float, b_past: float, b_speed: float) -> None:
    """a 8 m from the crossing at 5 m/s cannot stop short of it any more; b only 0.3 m
    past its limit is still out of a's reach; b still moving is still being stopped."""
    paths, keeper = _crossing()
    order = keeper.order
    limit = order.limit("b", {"a": a_at, "b": 0.0}).at_m
    progress = _flying(paths, {"a": a_at, "b": limit + b_past})
    progress["b"].speed = b_speed

    keeper.decide(progress, ["a", "b"])

    assert keeper.order is order
    assert keeper.leads_taken == []


@pytest.mark.parametrize(("a_at", "taken"), [(43.8, True), (44.5, False)])
def test_a_leader_standing_inside_the_encounter_waits_there_if_passed_far_enough(
    a_at: float, taken: bool
) -> None:
    """Both stopped inside their encounter (fuzzed flight 8403: a waiting for a third,
    b 2 m past its limit): b goes first if its way passes a no closer than 2R (a 6.2 m
    from b's path), else nothing changes (5.5 m)."""
    paths, keeper = _crossing()
    limit = keeper.order.limit("b", {"a": a_at, "b": 0.0}).at_m
    progress = _flying(paths, {"a": a_at, "b": limit + 2.0})
    progress["a"].speed = progress["b"].speed = 0.0

    keeper.decide(progress, ["a", "b"])

    assert [uav for uav, *_ in keeper.leads_taken] == (["b"] if taken else [])


def test_only_the_encounter_it_stands_in_is_turned() -> None:
    """b crosses a's path twice, both times after a: turned where b stands, b still
    waits for a at the second crossing."""
    a = _path("a", [[0.0, 0.0], [200.0, 0.0]], 10.0)
    b = _path("b", [[50.0, -50.0], [50.0, 50.0], [150.0, 50.0], [150.0, -50.0]], 5.0)
    order = PassingOrder.derive([a, b], margin_m=0.5)
    first = order.limit("b", {"a": 0.0})
    assert first.leader == "a" and first.at_m < 50.0

    turned = order.swapped("b", "a", first.at_m)

    assert turned is not None
    assert turned.limit("a", {"b": 0.0}).at_m < 50.0 - 6.0  # a waits for b at the first
    assert turned.limit("a", {"b": 100.0}).at_m == math.inf  # and nowhere else
    second = turned.limit("b", {"a": 60.0})
    assert second.leader == "a" and 200.0 < second.at_m < 250.0 - 6.0
    assert order.limit("b", {"a": 0.0}) == first  # the order it came from is unchanged


def test_a_vehicle_unheard_while_it_flies_on_goes_first_and_its_leader_waits() -> None:
    """b's link is down 10 m short of where it was to wait for a: its mission flies it on
    through the crossing whatever the ground station says (fuzzed flight 1014 with link
    drops: 5 m into its encounter when heard again, stopped there, and passed 0.65 m
    away). a, still 30 m off, waits short of the crossing until b is heard past it; once
    an outage, and a vehicle heard again is judged afresh."""
    paths, keeper = _crossing()
    limit = keeper.order.limit("b", {"a": 20.0, "b": 0.0}).at_m
    progress = _flying(paths, {"a": 20.0, "b": limit - 10.0})

    keeper.decide(progress, ["a"], unheard=["b"])

    [(uav, past, turned, unheard)] = keeper.leads_taken
    assert (uav, turned, unheard) == ("b", [("b", "a")], True)
    assert past == pytest.approx(-10.0)
    a_limit = keeper.order.limit("a", {"a": 20.0, "b": limit - 10.0})
    assert a_limit.leader == "b" and a_limit.at_m <= 50.0 - 6.0
    progress["a"].s = a_limit.at_m - 1.0
    [change] = keeper.decide(progress, ["a"], unheard=["b"])
    assert (change.uav_id, change.gate, change.waits_for) == ("a", Gate.STOP, "b")
    assert len(keeper.leads_taken) == 1  # once an outage
    progress["b"].s = 50.0 + 7.0  # heard again, through
    [change] = keeper.decide(progress, ["a", "b"])
    assert (change.uav_id, change.gate) == ("a", Gate.GO)


def test_an_unheard_vehicle_does_not_lead_where_its_leader_cannot_stop_short() -> None:
    """a, 8 m from the crossing at 5 m/s, can no longer stop short of it: the order
    stays (b, unheard, cannot be stopped either: nothing the ground station can do)."""
    paths, keeper = _crossing()
    order = keeper.order
    limit = order.limit("b", {"a": 42.0, "b": 0.0}).at_m
    progress = _flying(paths, {"a": 42.0, "b": limit - 10.0})

    keeper.decide(progress, ["a"], unheard=["b"])

    assert keeper.order is order and keeper.leads_taken == []


def test_an_unheard_vehicle_leads_every_encounter_it_has_not_left_behind() -> None:
    """b crosses a's path twice, both times after a; unheard before the first, it leads
    both (a can stop short of each), and nobody waits for it any more."""
    a = _path("a", [[0.0, 0.0], [200.0, 0.0]], 10.0)
    b = _path("b", [[50.0, -50.0], [50.0, 50.0], [150.0, 50.0], [150.0, -50.0]], 5.0)
    order = PassingOrder.derive([a, b], margin_m=0.5)
    assert len(order.encounters("b")) == 2
    at, ends = {"a": 0.0, "b": 10.0}, {"a": a.length, "b": b.length}

    taken = lead_ahead(order, "b", at, ends, lambda *_: True)

    assert taken is not None and taken.turned == [("b", "a"), ("b", "a")]
    assert taken.order.encounters("b") == []
    assert [e.leader for e in taken.order.encounters("a")] == ["b", "b"]
    assert lead_ahead(order, "b", {"a": 0.0, "b": b.length}, ends, lambda *_: True) is None
    passed_first = lead_ahead(order, "b", {"a": 100.0, "b": 10.0}, ends, lambda *_: True)
    assert passed_first is not None and passed_first.turned == [("b", "a")]  # a is past one


def _waits(leader: str, at: float | np.ndarray, after: float) -> Waits:
    at = np.atleast_1d(at)
    return Waits(leader, at, np.full(len(at), after), np.zeros((len(at), 2)))


def test_reach_finds_who_would_wait_for_ever() -> None:
    """a waits at 40 for b to pass 260; b, at 40, for a to pass 160: each for the
    other. With b waiting for a only until it passes 30, both get through."""
    ends = {"a": 200.0, "b": 300.0}
    circle = PassingOrder({"a": [_waits("b", 40.0, 260.0)], "b": [_waits("a", 40.0, 160.0)]},
                          {}, 0.1)  # fmt: skip
    assert circle.reach({"a": 0.0, "b": 0.0}, ends) == {"a": 40.0, "b": 40.0}
    line = PassingOrder({"a": [_waits("b", 40.0, 260.0)], "b": [_waits("a", 40.0, 30.0)]}, {}, 0.1)
    assert line.reach({"a": 0.0, "b": 0.0}, ends) == {"a": math.inf, "b": math.inf}


def _three() -> PassingOrder:
    """f stands at 10, 2 m past where it waits for l to pass 20 (all through an
    encounter from 8 to 17 along f's path); at 15, f waits for x to pass 30; x waits
    at 25 for l to pass 25."""
    return PassingOrder(
        {
            "f": [_waits("l", np.arange(8.0, 17.0, 0.1), 20.0), _waits("x", 15.0, 30.0)],
            "l": [],
            "x": [_waits("l", 25.0, 25.0)],
        },
        {},
        0.1,
    )


def test_a_circle_the_lead_makes_is_broken_where_a_wait_can_be_turned() -> None:
    """Once l waits for f, f (waiting for x, who waits for l) waits for itself: f
    takes the lead over x as well."""
    at, ends = {"f": 10.0, "l": 0.0, "x": 0.0}, {"f": 100.0, "l": 100.0, "x": 100.0}

    taken = take_the_lead(_three(), "f", at, ends, lambda *_: True)

    assert taken is not None
    assert taken.turned == [("f", "l"), ("f", "x")]
    assert all(s == math.inf for s in taken.order.reach(at, ends).values())


def test_a_circle_that_cannot_be_broken_leaves_the_order_as_it_was() -> None:
    """Only l can still stop, and only for f: the circle stays, and so does the order."""
    at, ends = {"f": 10.0, "l": 0.0, "x": 0.0}, {"f": 100.0, "l": 100.0, "x": 100.0}

    def only_l_for_f(order: PassingOrder, uav: str, leader: str) -> bool:
        return (uav, leader) == ("l", "f")

    assert take_the_lead(_three(), "f", at, ends, only_l_for_f) is None


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(PLANS, st.integers(0, 2**31 - 1))
def test_whoever_stops_late_and_takes_the_lead_nobody_waits_for_ever_or_comes_too_close(
    family_seed: tuple[str, int], seed: int
) -> None:
    """The adversary of test_passing_order, which now and then pushes a vehicle waiting
    at its limit 0.6 to 3 m past it (a stop that came late), where it takes the lead if
    it can (a leader that can still stop: short of its new limit): nobody is ever stuck,
    and no pair comes closer than its reach."""
    _, paths = planned(*family_seed)
    ends = {uav: p.length for uav, p in paths.items()}
    turned: list[list[tuple[str, str]]] = []

    def overshoot(
        order: PassingOrder, at: dict[str, float], rng: np.random.Generator
    ) -> PassingOrder:
        if rng.random() > 0.05:
            return order
        waiting = [u for u in at if at[u] < ends[u] and order.limit(u, at).at_m - at[u] < 1e-6]
        for uav in rng.permutation(waiting):  # the first that can take the lead
            pushed = {**at, uav: min(at[uav] + rng.uniform(0.6, 3.0), ends[uav])}

            def can_wait(turned_order: PassingOrder, follower: str, leader: str) -> bool:
                wait = next(w for w in turned_order.waits[follower] if w.leader == leader)
                return wait.limit(pushed[leader]) > pushed[follower]  # noqa: B023

            taken = take_the_lead(order, str(uav), pushed, ends, can_wait)
            if taken is not None:
                at.update(pushed)
                turned.append(taken.turned)
                return taken.order
        return order

    fly_adversary(paths, PassingOrder.derive(paths.values(), margin_m=0.6), seed, overshoot)
    note(f"leads taken: {turned}")
