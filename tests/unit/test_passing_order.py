"""The plan's passing order: derived from the plan's own clock, it can neither wait in a
circle nor let two vehicles closer than their reach, however they are delayed."""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from gcs.mission.passing_order import PassingOrder, PlannedPath, Waits
from planner.experiments.scenario_generator import crossing_scenario, random_scenario
from planner.model.scenario import Scenario
from planner.pipeline import PlannerSettings, plan

CELL_M = 10.0


@functools.cache
def planned(family: str, seed: int) -> tuple[Scenario, dict[str, PlannedPath]]:
    """A plan of a generated scenario, as metres on the plan's clock."""
    if family == "crossing":
        scenario = crossing_scenario(seed, size=14, uavs=5, objects=0)
    else:
        scenario = random_scenario(seed, size=16, uavs=6, objects=0)
    result = plan(scenario, PlannerSettings(seed=seed))
    assert result.feasible, result.conflicts
    cell = scenario.grid.cell_size_m
    radii = {u.id: u.radius * cell for u in scenario.uavs}
    paths = {u.id: PlannedPath.of(u.id, u.trajectory, cell, radii[u.id]) for u in result.uavs}
    return scenario, paths


PLANS = st.tuples(st.sampled_from(["crossing", "random"]), st.integers(0, 5))


def _crossing_pair(offset_s: float) -> dict[str, PlannedPath]:
    """a flies east through (50, 0), b north through it, `offset_s` later, both 5 m/s."""
    a = PlannedPath("a", np.array([[0.0, 0.0], [100.0, 0.0]]), np.array([0.0, 20.0]),
                    np.array([0.0, 20.0]), 3.0)  # fmt: skip
    b = PlannedPath("b", np.array([[50.0, -50.0], [50.0, 50.0]]),
                    np.array([offset_s, offset_s + 20.0]), np.array([offset_s, offset_s + 20.0]),
                    3.0)  # fmt: skip
    return {"a": a, "b": b}


def test_at_a_crossing_the_later_one_waits_short_of_it_until_the_first_has_passed() -> None:
    order = PassingOrder.derive(_crossing_pair(offset_s=5.0).values(), margin_m=0.5)
    assert order.waits["a"] == []  # a crosses first in the plan
    first = order.limit("b", {"a": 0.0, "b": 0.0})
    assert first.leader == "a"
    assert 50.0 - 6.5 - 0.5 <= first.at_m <= 50.0 - 6.5  # short of the crossing by 2R + margin
    assert order.limit("b", {"a": 50.0 + 6.5 + 0.6}).at_m == np.inf  # a is through


def test_where_the_plan_flies_two_side_by_side_the_reach_is_what_the_plan_keeps() -> None:
    a = PlannedPath("a", np.array([[0.0, 0.0], [100.0, 0.0]]), np.array([0.0, 20.0]),
                    np.array([0.0, 20.0]), 3.0)  # fmt: skip
    b = PlannedPath("b", np.array([[0.0, 6.3], [100.0, 6.3]]), np.array([0.0, 20.0]),
                    np.array([0.0, 20.0]), 3.0)  # fmt: skip
    order = PassingOrder.derive([a, b], margin_m=0.5)
    assert order.reach_m[("a", "b")] == pytest.approx(6.3 - order.step_m)
    assert order.narrowest_margin_m({"a": 3.0, "b": 3.0}) == pytest.approx(0.3 - order.step_m)


def test_a_kept_path_restarted_at_a_replan_keeps_the_order_its_vehicle_can_keep() -> None:
    """A live replan continues a vehicle the order held back from where it is, at the
    replan's moment (as the replan takes it). On the old clock b (held back 3 s) seemed
    to cross just when the replanned a does, and the order kept no more than the plan did
    at once (fuzzed flight 3034: 3.4 m); restarted at the replan, b crosses 3 s after a
    and waits for it."""
    now = 20.0
    b = _crossing_pair(offset_s=13.0)["b"]  # north through (50, 0), 5 m/s, from t = 13
    a = PlannedPath("a", np.array([[35.0, 0.0], [100.0, 0.0]]), np.array([now, now + 13.0]),
                    np.array([now, now + 13.0]), 3.0)  # fmt: skip  # replanned: (50, 0) at 23
    rest = b.after(20.0)  # b has flown 20 m
    assert rest.arrive[0] == pytest.approx(17.0)  # on the old clock, 3 s ago
    assert PassingOrder.derive([a, rest], margin_m=0.5).reach_m[("a", "b")] < 6.0
    restarted = rest.starting_at(now)
    assert restarted.ahead_s == pytest.approx(3.0)
    assert restarted.leaves(30.0) - restarted.ahead_s == pytest.approx(b.leaves(50.0))
    order = PassingOrder.derive([a, restarted], margin_m=0.5)
    assert order.reach_m[("a", "b")] == pytest.approx(6.5)
    assert order.limit("b", {"a": 0.0, "b": 0.0}).leader == "a"


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(PLANS)
def test_every_wait_points_forward_in_the_plans_time(family_seed: tuple[str, int]) -> None:
    """The leader leaves before the follower arrives, on the plan's clock: so no chain of
    waits can come back to where it began."""
    _, paths = planned(*family_seed)
    order = PassingOrder.derive(paths.values(), margin_m=0.6)
    for waits in order.waits.values():
        for wait in waits:
            leaves, arrives = wait.plan_times.T
            assert np.all(leaves <= arrives + 1e-9)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(PLANS, st.integers(0, 2**31 - 1))
def test_whatever_the_delays_someone_can_always_move_and_nobody_comes_closer_than_reach(
    family_seed: tuple[str, int], seed: int
) -> None:
    """An adversary moves the vehicles at random speeds, holding some still for a while
    and keeping each over its goal a while before it is down (out of everyone's way),
    always within their limits: the fleet never ends up with every vehicle still up stuck
    at its limit, and no pair ever comes closer than its reach (less a step)."""
    _, paths = planned(*family_seed)
    fly_adversary(paths, PassingOrder.derive(paths.values(), margin_m=0.6), seed)


Overshoot = Callable[[PassingOrder, dict[str, float], np.random.Generator], PassingOrder]


def fly_adversary(
    paths: dict[str, PlannedPath],
    order: PassingOrder,
    seed: int,
    overshoot: Overshoot | None = None,
) -> None:
    """The adversary above; `overshoot`, called every step, may move a vehicle on past
    its limit (a stop that came late) and give the order to keep from then on."""
    rng = np.random.default_rng(seed)
    at = dict.fromkeys(paths, 0.0)
    lengths = {uav: p.length for uav, p in paths.items()}
    for _ in range(20_000):
        up = [uav for uav in paths if at[uav] < np.inf]
        if not up:
            return
        for uav in up:  # over its goal: down at some point, never before
            if at[uav] >= lengths[uav] and rng.random() < 0.05:
                at[uav] = np.inf
        if overshoot is not None:
            order = overshoot(order, at, rng)
        flying = [uav for uav in up if at[uav] < lengths[uav]]
        room = {uav: min(order.limit(uav, at).at_m, lengths[uav]) - at[uav] for uav in flying}
        movable = [uav for uav in flying if room[uav] > 1e-9]
        assert movable or len(flying) < len(up), f"every vehicle still up is stuck: {at}"
        for uav in movable:
            if rng.random() < 0.7:  # the others are held up this step
                at[uav] += min(room[uav], rng.uniform(0.0, 2.0))
        for a, b in itertools.combinations(sorted(paths), 2):
            if np.inf in (at[a], at[b]):
                continue
            gap = np.hypot(*np.subtract(paths[a].position(at[a]), paths[b].position(at[b])))
            assert gap >= order.reach_m[(a, b)] - order.step_m - 1e-6, (a, b, at)
    pytest.fail("the adversary ran out of steps")


def test_after_a_replan_two_closer_than_their_radii_at_once_are_ordered_all_the_same() -> None:
    """The rest of a flight after a live replan may have two vehicles closer than their
    radii at once (fuzzed flight 3499: kept vehicles flew on while the missions went up).
    A plan's order keeps only what the plan keeps there; the rest's order makes the one
    that comes first lead, and keeps the whole reach."""
    paths = _crossing_pair(offset_s=0.5).values()  # both at the crossing within 0.5 s
    plain = PassingOrder.derive(paths, margin_m=0.5)
    assert plain.reach_m[("a", "b")] < 6.0
    ordered = PassingOrder.derive(paths, margin_m=0.5, order_together=True)
    assert ordered.reach_m[("a", "b")] == pytest.approx(6.5)
    assert ordered.waits["a"] == []  # a comes first: it leads
    first = ordered.limit("b", {"a": 0.0, "b": 0.0})
    assert first.leader == "a"
    assert first.at_m <= 50.0 - 6.5
    assert ordered.limit("b", {"a": 50.0 + 6.5 + 0.6}).at_m == np.inf


def test_after_a_replan_two_side_by_side_beyond_their_radii_keep_what_the_plan_keeps() -> None:
    a = PlannedPath("a", np.array([[0.0, 0.0], [100.0, 0.0]]), np.array([0.0, 20.0]),
                    np.array([0.0, 20.0]), 3.0)  # fmt: skip
    b = PlannedPath("b", np.array([[0.0, 6.3], [100.0, 6.3]]), np.array([0.0, 20.0]),
                    np.array([0.0, 20.0]), 3.0)  # fmt: skip
    order = PassingOrder.derive([a, b], margin_m=0.5, order_together=True)
    assert order.reach_m[("a", "b")] == pytest.approx(6.3 - order.step_m)
    assert order.waits == {"a": [], "b": []}  # nobody waits for a whole side-by-side leg


def test_a_vehicle_that_cannot_stop_short_of_a_crossing_leads_it() -> None:
    """b crosses second in the plan, but flies on at a live replan and cannot stop before
    the crossing (committed 60 m): a waits for it instead. Where both are committed, the
    plan's times decide."""
    paths = _crossing_pair(offset_s=5.0).values()
    committed = PassingOrder.derive(paths, margin_m=0.5, committed_m={"b": 60.0})
    assert committed.waits["b"] == []
    assert committed.limit("a", {"a": 0.0, "b": 0.0}).leader == "b"
    short = PassingOrder.derive(paths, margin_m=0.5, committed_m={"b": 30.0})
    assert short.limit("b", {"a": 0.0, "b": 0.0}).leader == "a"  # it can stop before
    both = PassingOrder.derive(paths, margin_m=0.5, committed_m={"a": 60.0, "b": 60.0})
    assert both.waits["a"] == [] and both.limit("b", {"a": 0.0, "b": 0.0}).leader == "a"
    # a already in the crossing: b cannot lead through it, committed or not
    a, b = _crossing_pair(offset_s=5.0).values()
    inside = [a.after(47.0), b]
    plain = PassingOrder.derive(inside, margin_m=0.5, order_together=True)
    kept = PassingOrder.derive(inside, margin_m=0.5, order_together=True, committed_m={"b": 60.0})
    assert kept.limit("b", {"a": 0.0, "b": 0.0}) == plain.limit("b", {"a": 0.0, "b": 0.0})
    assert kept.limit("b", {"a": 0.0, "b": 0.0}).leader == "a"


def _path(uav_id: str, corners: list[list[float]], speed_m_s: float) -> PlannedPath:
    xy = np.asarray(corners, dtype=float)
    t = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))]) / speed_m_s
    return PlannedPath(uav_id, xy, t, t, 3.0)


def test_a_vehicle_whose_rest_begins_inside_an_encounter_leads_it() -> None:
    """After a live replan, a's rest begins 4 m from b's new path, which comes head-on
    and passes a's start later. The plan's times have b meet a first where they pass
    each other at once, so b would lead the whole encounter and a wait where it already
    stands, with b flying by it 4 m away (fuzzed flight 4494, 4.10 m): a leads instead.
    Before the flight, nobody leads for having started close."""
    a = _path("a", [[47.0, 0.0], [100.0, 0.0]], 5.0)
    b = _path("b", [[120.0, 4.0], [40.0, 4.0]], 5.0)
    rest = PassingOrder.derive([a, b], margin_m=0.5, order_together=True)
    assert rest.waits["a"] == []
    assert rest.limit("b", {"a": 0.0, "b": 0.0}).leader == "a"
    assert rest.limit("b", {"a": a.length + 1.0, "b": 0.0}).at_m == np.inf  # a is through
    planned = PassingOrder.derive([a, b], margin_m=0.5)
    assert planned.reach_m[("a", "b")] < 6.0  # what the plan keeps; nobody leads it all


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 40), st.integers(0, 40)), min_size=1, max_size=60),
    st.integers(-1, 42),
)
@example([(0, 4), (4, 5)], 5)  # a rise by the least step
def test_a_waits_limit_is_the_first_place_whose_leader_has_not_passed(
    pairs: list[tuple[int, int]], leader_at: int
) -> None:
    """`Waits` keeps only the places where what it needs of the leader rises; the limit
    is the one a search of every sample pair finds."""
    at, after = (np.array(sorted(pairs), dtype=float) / 4).T
    wait = Waits("b", at, after, np.zeros((len(at), 2)))
    needed = np.maximum.accumulate(after)
    waiting = np.flatnonzero(needed >= leader_at / 4)
    assert wait.limit(leader_at / 4) == (at[waiting[0]] if len(waiting) else np.inf)


def test_an_order_derived_like_another_derives_only_the_pairs_whose_paths_changed() -> None:
    """Holding one UAV short changes only its own pairs: the others are taken as they
    were, and the order is the one derived from scratch."""
    _, paths = planned("random", 1)
    order = PassingOrder.derive(paths.values(), margin_m=0.6)
    held_uav = sorted(paths)[0]
    held = {**paths, held_uav: paths[held_uav].held(5.0, 30.0)}
    again = PassingOrder.derive(held.values(), margin_m=0.6, like=(order, paths))
    fresh = PassingOrder.derive(held.values(), margin_m=0.6)
    assert again.reach_m == fresh.reach_m
    for follower, waits in fresh.waits.items():
        assert [w.leader for w in again.waits[follower]] == [w.leader for w in waits]
        for kept, derived in zip(again.waits[follower], waits, strict=True):
            assert np.array_equal(kept.at, derived.at) and kept.needed == derived.needed
            untouched = held_uav not in (follower, kept.leader)
            previous = next(w for w in order.waits[follower] if w.leader == kept.leader)
            assert (kept is previous) == untouched
