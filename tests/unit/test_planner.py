"""Algorithm 1 end to end, on the paper's cases and on generated scenarios."""

from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner.cases import CASES, PAPER_TABLE_III, load_case
from planner.model.plan import Plan
from planner.model.scenario import load_scenario
from planner.model.trajectory import Trajectory
from planner.pipeline import PlannerSettings, PlanProgress, plan
from planner.search.objectives import ObjectiveName

FAST: dict[str, Any] = {"population": 20, "iterations": 150}


def independent_check(result: Plan, radii: dict[str, float], blocked: set) -> list[str]:
    """A dense-sampling judge that shares no code with planner.check.safety."""
    tracks = {u.id: Trajectory(np.array(u.trajectory)) for u in result.uavs}
    end = max(t.end_time for t in tracks.values())
    t = np.linspace(0.0, end, int(end / 0.005) + 2)
    where = {u: tr.at(t) for u, tr in tracks.items()}
    problems = []
    ids = list(tracks)
    for i, a in enumerate(ids):
        for b in ids[i + 1 :]:
            d = np.hypot(*(where[a] - where[b]).T)
            if np.nanmin(d, initial=np.inf) < radii[a] + radii[b] - 1e-6:
                problems.append(f"{a}-{b}")
        p = where[a][~np.isnan(where[a][:, 0])]
        for cx, cy in blocked:
            off = np.maximum(np.abs(p - (cx, cy)) - 0.5, 0)
            if np.hypot(*off.T).min() < radii[a] - 1e-6:
                problems.append(f"{a}@{(cx, cy)}")
    return problems


@pytest.mark.parametrize("case", CASES)
def test_paper_objective_reproduces_table_iii_deviations(case: str) -> None:
    result = plan(load_case(case), PlannerSettings(objective="paper", **FAST))
    assert result.feasible
    assert result.metrics.mean_deviation == pytest.approx(
        PAPER_TABLE_III[case]["deviation"], abs=0.005
    )


@pytest.mark.parametrize("case", CASES)
def test_qos_objective_reaches_every_goal_safely_and_short(case: str) -> None:
    scenario = load_case(case)
    result = plan(scenario, PlannerSettings(objective="qos", **FAST))
    assert result.feasible and result.metrics.conflicts == 0
    assert all(u.deviation == 0 for u in result.uavs)
    shortest = sum(u.shortest_length for u in result.uavs)
    assert result.metrics.total_length <= 1.10 * shortest
    radii = {u.id: u.radius for u in scenario.uavs}
    blocked = set(scenario.obstacles) | set(map(tuple, result.non_uav_objects))
    assert independent_check(result, radii, blocked) == []


def test_speed_is_never_exceeded_and_trajectories_start_at_t0() -> None:
    scenario = load_case("case-5")
    result = plan(scenario, PlannerSettings(**FAST))
    for u, spec in zip(result.uavs, scenario.uavs, strict=True):
        tr = Trajectory(np.array(u.trajectory))
        assert tr.points[0].tolist() == [0.0, *spec.start]
        assert tr.max_speed() <= spec.speed * (1 + 1e-6)
        assert np.all(np.diff(tr.times) >= 0)


def test_same_seed_same_plan_without_a_time_budget() -> None:
    settings = PlannerSettings(seed=5, time_budget_s=None, **FAST)
    a = plan(load_case("case-6"), settings)
    b = plan(load_case("case-6"), settings)
    clock = {"metrics": {"seconds", "first_safe_s"}}  # the only wall-clock fields
    assert a.model_dump(exclude=clock) == b.model_dump(exclude=clock)


def test_wormhole_replans_only_the_uavs_an_object_touches() -> None:
    base = {
        "grid": {"width": 10, "height": 10},
        "uavs": [
            {"id": "near", "start": [0, 2], "goal": [9, 2]},
            {"id": "far", "start": [0, 8], "goal": [9, 8]},
        ],
    }
    # Algorithm 1's rule alone: the improvement phase after it may shorten any UAV's path.
    settings = PlannerSettings(**FAST, improve_rounds=0)
    without = plan(load_scenario(base), settings)
    with_object = plan(load_scenario({**base, "non_uav_objects": [[5, 2]]}), settings)
    near, far = with_object.uavs
    assert near.replanned == ["non-UAV object"] and far.replanned == []
    assert far.trajectory == without.uavs[1].trajectory
    assert with_object.feasible


def test_unsolvable_scenario_is_refused_with_the_conflict() -> None:
    corridor = load_scenario(
        {
            "name": "corridor",
            "grid": {"width": 5, "height": 1},
            "uavs": [
                {"id": "east", "start": [0, 0], "goal": [4, 0]},
                {"id": "west", "start": [4, 0], "goal": [0, 0]},
            ],
        }
    )
    result = plan(corridor, PlannerSettings(**FAST))
    assert not result.feasible and result.metrics.conflicts >= 1
    conflict = result.conflicts[0]
    assert conflict["kind"] == "uav" and set(conflict["uavs"]) == {"east", "west"}
    assert "come" in conflict["message"] and "at t =" in conflict["message"]


@st.composite
def small_scenarios(draw) -> dict:
    size = draw(st.integers(5, 8))
    cells = draw(
        st.lists(
            st.tuples(st.integers(0, size - 1), st.integers(0, size - 1)),
            min_size=6,
            max_size=6,
            unique=True,
        )
    )
    return {
        "grid": {"width": size, "height": size},
        "uavs": [
            {"id": f"u{k}", "start": list(cells[2 * k]), "goal": list(cells[2 * k + 1])}
            for k in range(3)
        ],
    }


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=small_scenarios(), seed=st.integers(0, 1000))
def test_any_feasible_plan_passes_an_independent_check(data: dict, seed: int) -> None:
    scenario = load_scenario(data)
    result = plan(scenario, PlannerSettings(seed=seed, population=15, iterations=60))
    problems = independent_check(result, {u.id: u.radius for u in scenario.uavs}, set())
    if result.feasible:
        assert problems == []
    else:
        assert result.conflicts, "an infeasible plan must say why"


def test_progress_reports_every_iteration_of_every_run() -> None:
    # Runs now stop when they converge, so a run may report fewer than `iterations`; the
    # safe start's and re-timing's steps are runs of one step that evaluate no population.
    seen: list[PlanProgress] = []
    result = plan(load_case("case-5"), PlannerSettings(**FAST), progress=seen.append)
    assert len(seen) == result.metrics.iterations_run == len(result.history)
    searched = [p for p in seen if p.reason not in ("safe start", "re-time")]
    assert searched and all(p.iterations == 1 for p in seen if p not in searched)
    # NFE also counts the hover probes tried before a search (see docs/planner.md).
    assert result.metrics.nfe >= FAST["population"] * len(searched)
    assert [p.run for p in seen] == sorted(p.run for p in seen)
    for run in {p.run for p in seen}:
        steps = [p.iteration for p in seen if p.run == run]
        assert steps == list(range(1, len(steps) + 1)) and len(steps) <= FAST["iterations"]
    assert seen[-1].plan_cost == pytest.approx(result.history[-1], abs=1e-6)


def test_iterations_only_runs_every_iteration_of_every_run() -> None:
    seen: list[PlanProgress] = []
    settings = PlannerSettings(**FAST).iterations_only()
    result = plan(load_case("case-5"), settings, progress=seen.append)
    assert len(seen) == result.metrics.replans * FAST["iterations"] == len(result.history)
    assert {p.iteration for p in seen} == set(range(1, FAST["iterations"] + 1))
    assert all(p.budget_percent is None for p in seen)
    assert result.stop_reason == "iterations" and result.time_budget_s is None


@pytest.mark.parametrize("algorithm", ["alo", "da", "gwo", "mfo", "mvo", "woa"])
@pytest.mark.parametrize("objective", ["qos", "paper"])
def test_every_optimizer_drives_either_objective(algorithm: str, objective: ObjectiveName) -> None:
    seen: list = []
    result = plan(
        load_case("case-1"), PlannerSettings(algorithm, objective, 3, 10, 40), seen.append
    )
    assert result.algorithm == algorithm and result.objective == objective
    m = result.metrics  # runs may end early (converged), never late; NFE counts probes too
    searched = [p for p in seen if p.reason not in ("safe start", "re-time")]
    assert result.feasible and m.nfe >= 10 * len(searched)
    assert m.iterations_run == len(seen) <= m.replans * 40
