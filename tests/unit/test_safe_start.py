"""The fast safe start's pieces: lone paths, safe intervals, the grid fallback, exact geometry."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.check.safety import cell_conflicts, closest_approach, uav_conflicts
from planner.experiments.scenario_generator import random_scenario
from planner.geometry.clearance import ExactClearance
from planner.geometry.grid_search import GridGraph, path_length
from planner.geometry.squares import pairs_square_distance
from planner.model.scenario import UAVSpec
from planner.model.trajectory import Trajectory
from planner.pipeline import PlannerSettings, plan
from planner.search import space_time
from planner.search.any_angle import pull_string, segments_clearance, tighten
from planner.search.sipp import Mover, schedule
from tests.unit.test_planner import independent_check


@st.composite
def maps(draw, size: int = 14) -> np.ndarray:
    seed = draw(st.integers(0, 10_000))
    share = draw(st.sampled_from([0.0, 0.1, 0.25]))
    return np.random.default_rng(seed).random((size, size)) < share


def _free_pair(blocked: np.ndarray, seed: int) -> tuple[tuple[int, int], tuple[int, int]]:
    free = np.argwhere(~blocked)
    a, b = np.random.default_rng(seed).choice(len(free), 2, replace=False)
    return (int(free[a][0]), int(free[a][1])), (int(free[b][0]), int(free[b][1]))


@settings(max_examples=60, deadline=None)
@given(blocked=maps(), seed=st.integers(0, 1000), radius=st.sampled_from([0.2, 0.3, 0.45]))
def test_shortcuts_are_exactly_clear_and_never_longer(blocked, seed: int, radius: float) -> None:
    start, goal = _free_pair(blocked, seed)
    graph = GridGraph.build(blocked)
    length, cells = graph.route(start, goal)
    assert length == pytest.approx(graph.distances_to(goal)[start])  # the bounded search
    if cells is None:
        return
    assert path_length(cells) == pytest.approx(length) if len(cells) > 1 else length == 0
    pulled = pull_string(np.array(cells, float), radius, blocked)
    tight = tighten(pulled, radius, blocked)
    for polyline in (pulled, tight):
        assert tuple(polyline[0]) == start and tuple(polyline[-1]) == goal
        flight = Trajectory.from_waypoints(polyline, 1.0)
        assert cell_conflicts("u", flight, radius, blocked) == []
    lengths = [Trajectory.from_waypoints(p, 1.0).length for p in (cells, pulled, tight)]
    assert lengths[2] <= lengths[1] + 1e-9 <= lengths[0] + 2e-9


def test_many_segments_are_measured_as_the_safety_check_measures_one() -> None:
    rng = np.random.default_rng(3)
    for _ in range(500):
        p0 = rng.uniform(-1, 8, (6, 2))
        p1 = np.where(rng.random((6, 1)) < 0.3, p0, rng.uniform(-1, 8, (6, 2)))
        p1[0, 0] = p0[0, 0]  # one parallel to an axis
        cells = rng.integers(0, 8, (int(rng.integers(1, 7)), 2))
        rows = len(cells)
        want = [
            pairs_square_distance(np.tile(a, (rows, 1)), np.tile(b, (rows, 1)), cells)[0].min()
            for a, b in zip(p0, p1, strict=True)
        ]
        assert segments_clearance(p0, p1, cells) == pytest.approx(want, abs=1e-12)


@settings(max_examples=40, deadline=None)
@given(blocked=maps(), seed=st.integers(0, 1000))
def test_exact_leg_clearance_agrees_with_the_safety_check(blocked, seed: int) -> None:
    rng = np.random.default_rng(seed)
    paths = rng.uniform(0.0, blocked.shape[0] - 1.0, (8, 4, 2))  # the map's edge counts too
    field = ExactClearance.near(blocked, paths.reshape(-1, 2), 20.0)
    _, hits = field.leg_terms(paths, 0.3)
    for k, path in enumerate(paths):
        exact = cell_conflicts("u", Trajectory.from_waypoints(path, 1.0), 0.3, blocked)
        assert (hits[k] > 0) == bool(exact)


def _movers(rng: np.random.Generator, count: int) -> list[Mover]:
    out = []
    for _ in range(count):
        points = rng.uniform(0, 10, (int(rng.integers(2, 5)), 2))
        waits = rng.choice([0.0, 0.0, 2.0], len(points))
        speed = float(rng.choice([0.5, 1.0, 2.0]))
        out.append(Mover(Trajectory.from_waypoints(points, speed, waits), 0.3, speed))
    return out


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 100_000), count=st.integers(1, 5))
def test_a_safe_interval_schedule_is_exactly_safe_and_never_too_fast(seed: int, count: int) -> None:
    rng = np.random.default_rng(seed)
    others = _movers(rng, count)
    path = rng.uniform(0, 10, (int(rng.integers(2, 5)), 2))
    flight = schedule(path, 1.0, 0.3, others)
    if flight is None:  # only when hovering at the start is unsafe, or all ways are cut
        return
    assert flight.max_speed() <= 1.0 + 1e-9
    assert np.allclose(flight.xy[0], path[0]) and np.allclose(flight.end, path[-1])
    assert flight.length == pytest.approx(Trajectory.from_waypoints(path, 1.0).length)
    for other in others:
        assert closest_approach(flight, other.trajectory)[0] >= 0.6 - 1e-9


def test_a_schedule_hovers_only_when_it_must_and_about_as_little_as_waiting_at_the_start() -> None:
    path = np.array([(0.0, 5.0), (10.0, 5.0)])
    alone = schedule(path, 1.0, 0.3, [])
    assert alone is not None and alone.end_time == pytest.approx(10.0)  # no one about
    crossing = Mover(Trajectory.from_waypoints([(5, 0), (5, 10)], 1.0), 0.3, 1.0)
    flight = schedule(path, 1.0, 0.3, [crossing])
    assert flight is not None and flight.end_time > 10.0
    # The best pure take-off delay, found by trying many and judging each exactly.
    delays = np.arange(0.0, 12.0, 0.01)
    best = next(
        d
        for d in delays
        if closest_approach(Trajectory.from_waypoints(path, 1.0, [d, 0.0]), crossing.trajectory)[0]
        >= 0.6
    )
    # The schedule's margins (half a sample of each motion) cost a little time, no more.
    assert 10.0 + best - 1e-9 <= flight.end_time + 1e-6 <= 10.0 + best + 0.5


def test_the_space_time_fallback_steps_aside_in_a_head_on_meeting() -> None:
    free = np.ones((9, 3), dtype=bool)
    other = Trajectory.from_waypoints([(8, 1), (0, 1)], 1.0)  # comes straight at it
    spec = UAVSpec(id="a", start=(0, 1), goal=(8, 1))
    assert schedule(np.array([(0.0, 1.0), (8.0, 1.0)]), 1.0, 0.3, [Mover(other, 0.3, 1.0)]) is None
    flight = space_time.search(spec, free, [Mover(other, 0.3, 1.0)])
    assert flight is not None and np.allclose(flight.end, (8, 1))
    assert closest_approach(flight, other)[0] >= 0.6
    assert flight.max_speed() <= 1.0 + 1e-9


def test_pruned_pair_checks_find_what_all_pairs_find() -> None:
    rng = np.random.default_rng(11)
    for _ in range(150):
        fleet = {
            f"u{k}": Trajectory.from_waypoints(
                rng.uniform(0, 30, (int(rng.integers(1, 4)), 2)), 1.0
            )
            for k in range(int(rng.integers(1, 9)))
        }
        radii = dict.fromkeys(fleet, float(rng.uniform(0.2, 0.45)))
        found, closest = uav_conflicts(fleet, radii)
        ids = list(fleet)
        pairs = [(a, b) for i, a in enumerate(ids) for b in ids[i + 1 :]]
        gaps = [closest_approach(fleet[a], fleet[b])[0] for a, b in pairs]
        assert closest == (min(gaps) if gaps else math.inf)
        assert [c.uavs for c in found] == [
            p for p, g in zip(pairs, gaps, strict=True) if g < 2 * radii["u0"]
        ]


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 10_000), uavs=st.integers(4, 12))
def test_a_feasible_fleet_plan_passes_an_independent_check(seed: int, uavs: int) -> None:
    scenario = random_scenario(seed, size=16, uavs=uavs, objects=2, min_gap=2.0)
    result = plan(scenario, PlannerSettings(seed=seed, population=15, iterations=60))
    blocked = set(scenario.obstacles) | set(map(tuple, result.non_uav_objects))
    problems = independent_check(result, {u.id: u.radius for u in scenario.uavs}, blocked)
    assert problems == [] if result.feasible else result.conflicts
