"""The reference planners: their plans are judged by our exact check, never by their own."""

from __future__ import annotations

import math
import sys
import time

import numpy as np
import pytest

from planner.cases import CASES, load_case
from planner.check.safety import check_plan, closest_approach
from planner.model.scenario import Scenario, load_scenario
from planner.model.trajectory import Trajectory
from planner.references import ReferenceResult, judge, shortest_lengths
from planner.references.prioritized import plan_prioritized
from planner.search.space_time import Flight, SearchLimits, min_gap


def scenario(width: int, height: int, uavs: list[tuple], obstacles=()) -> Scenario:
    return load_scenario(
        {
            "grid": {"width": width, "height": height},
            "uavs": [{"id": i, "start": s, "goal": g} for i, s, g in uavs],
            "obstacles": list(obstacles),
        }
    )


def our_check(s: Scenario, result: ReferenceResult):
    assert result.trajectories is not None
    radii = {u.id: u.radius for u in s.uavs}
    return check_plan(result.trajectories, radii, s.blocked(), s.object_cells())


def assert_sound(s: Scenario, result: ReferenceResult) -> dict:
    """Solved, safe by check_plan, on every goal, never faster than the UAV's speed."""
    assert result.solved, result.note
    assert our_check(s, result).safe
    verdict = judge(s, result)
    assert verdict["feasible"] and verdict["conflicts"] == 0
    assert verdict["mean_deviation"] == 0 and verdict["max_speed_ratio"] <= 1 + 1e-9
    assert verdict["length_ratio"] >= 1 - 1e-9
    return verdict


def wide_and_mixed(name: str) -> Scenario:
    """A paper case with radius 0.45 and speeds 1, 2, 3: separations of √2/2 now conflict."""
    data = load_case(name).model_dump()
    for k, uav in enumerate(data["uavs"]):
        uav.update(radius=0.45, speed=1.0 + k)
    return load_scenario(data)


HEAD_ON = scenario(7, 3, [("a", (0, 1), (6, 1)), ("b", (6, 1), (0, 1))])
CORRIDOR = scenario(5, 1, [("a", (0, 0), (4, 0)), ("b", (4, 0), (0, 0))])
# A wall at x = 3 with one gap at y = 2, crossed by two UAVs in opposite directions.
GAP = scenario(
    7,
    5,
    [("a", (0, 2), (6, 2)), ("b", (6, 1), (0, 3))],
    obstacles=[(3, y) for y in (0, 1, 3, 4)],
)


# --- prioritized planning ----------------------------------------------------------


@pytest.mark.parametrize("name", CASES)
def test_prioritized_solves_the_paper_cases_safely(name: str) -> None:
    s = load_case(name)
    assert_sound(s, plan_prioritized(s))


@pytest.mark.parametrize("name", CASES)
def test_prioritized_is_safe_for_wide_uavs_of_mixed_speeds(name: str) -> None:
    s = wide_and_mixed(name)
    assert_sound(s, plan_prioritized(s))


@pytest.mark.parametrize("s", [HEAD_ON, GAP], ids=["head-on swap", "wall gap"])
def test_prioritized_solves_swaps_safely(s: Scenario) -> None:
    result = plan_prioritized(s)
    assert_sound(s, result)
    # Solved by search, not by luck of the clock: far inside the expansion limit.
    assert result.expansions is not None
    assert result.expansions < SearchLimits().max_expansions // 10


def test_prioritized_honours_a_given_order() -> None:
    result = plan_prioritized(HEAD_ON, order=["b", "a"])
    assert_sound(HEAD_ON, result)
    assert result.note.startswith("order b, a")
    # The first UAV flies its shortest path undisturbed.
    assert result.trajectories is not None
    assert result.trajectories["b"].length == pytest.approx(6.0)
    with pytest.raises(ValueError, match="permutation"):
        plan_prioritized(HEAD_ON, order=["a"])


def test_prioritized_fails_cleanly_on_an_impossible_corridor_swap() -> None:
    result = plan_prioritized(CORRIDOR, restarts=3)
    assert not result.solved and result.trajectories is None
    # Both orders were tried (there are only two) and each failure is named: the search
    # ran out of safe moves within its horizon, long before its expansion limit, so it
    # ends on its own rather than when some clock says so.
    assert "b found no path (after a)" in result.note
    assert "a found no path (after b)" in result.note
    assert result.note.count("no safe path within the horizon") == 2
    assert result.expansions is not None and result.expansions < SearchLimits().max_expansions
    verdict = judge(CORRIDOR, result)
    assert not verdict["feasible"] and verdict["conflicts"] is None


def test_prioritized_reports_the_expansion_limit() -> None:
    result = plan_prioritized(load_case("case-6"), limits=SearchLimits(max_expansions=1))
    assert not result.solved
    assert "expansion limit (1) reached" in result.note


def test_move_test_is_as_exact_as_closest_approach() -> None:
    """min_gap on a move equals closest_approach on the same window, shifted to t = 0."""
    rng = np.random.default_rng(7)
    for _ in range(300):
        n = int(rng.integers(1, 6))
        ts = np.concatenate([[0.0], np.cumsum(rng.choice([0.5, 1.0, math.sqrt(2)], n - 1))])
        flight = Trajectory(np.column_stack([ts, rng.integers(0, 5, (n, 2))]).astype(float))
        t0 = float(rng.uniform(0, 5))
        t1 = t0 + float(rng.choice([0.5, 1.0, math.sqrt(2)]))
        p0, p1 = rng.integers(0, 5, 2).astype(float), rng.integers(0, 5, 2).astype(float)
        gap = min_gap((t0, *p0, t1, *p1), Flight.of(flight, 0.3))
        lo, hi = t0, min(t1, flight.end_time)
        if lo > hi:
            assert gap == math.inf
            continue
        times = np.array([lo, *(t for t in flight.times if lo < t < hi), hi])
        along = p0 + ((times - t0) / (t1 - t0))[:, None] * (p1 - p0)
        move = Trajectory(np.column_stack([times - lo, along]))
        other = Trajectory(np.column_stack([times - lo, flight.at(times)]))
        assert gap == pytest.approx(closest_approach(move, other)[0], abs=1e-12)


# --- judge -------------------------------------------------------------------------


def test_judge_uses_pipeline_shortest_lengths() -> None:
    """Objects blocked and no corner cutting, as planner.pipeline measures `shortest`."""
    s = load_case("case-6")
    lengths = shortest_lengths(s)
    # (0,3) to (4,3) round the object at (3,3): up a diagonal, along, and down in two
    # straight steps, since the diagonal back down would cut the object's corner.
    assert lengths["uav1"] == pytest.approx(4 + math.sqrt(2))
    # (7,0) to (7,7) round the object at (7,4): out and back in on two diagonals.
    assert lengths["uav3"] == pytest.approx(5 + 2 * math.sqrt(2))


def test_judge_reports_a_collision_it_is_handed() -> None:
    s = HEAD_ON
    straight = {
        "a": Trajectory.from_waypoints([(0, 1), (6, 1)], 1.0),
        "b": Trajectory.from_waypoints([(6, 1), (0, 1)], 1.0),
    }
    verdict = judge(s, ReferenceResult("straight", straight, True, 0.0))
    assert verdict["conflicts"] == 1 and verdict["min_separation"] == pytest.approx(0.0)
    assert not verdict["safe"] and not verdict["feasible"]
    assert verdict["length_ratio"] == pytest.approx(1.0)


# --- CBS (pymapf) ------------------------------------------------------------------


def test_cbs_without_pymapf_says_how_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    from planner.references import cbs

    monkeypatch.setitem(sys.modules, "pymapf", None)  # makes `import pymapf` fail
    with pytest.raises(cbs.MapfDependencyError, match=r"pip install -e '\.\[mapf\]'"):
        cbs.plan_cbs(HEAD_ON)


def _cbs():
    pytest.importorskip("pymapf", reason="pymapf is not installed: pip install -e '.[mapf]'")
    from planner.references import cbs

    return cbs


def assert_judged_honestly(s: Scenario, result: ReferenceResult) -> dict:
    """judge agrees with check_plan, whatever CBS believes of its own plan."""
    report = our_check(s, result)
    verdict = judge(s, result)
    assert verdict["conflicts"] == len(report.conflicts)
    assert verdict["safe"] == report.safe
    assert verdict["feasible"] <= report.safe
    return verdict


def test_cbs_solves_a_crossing_and_is_judged_by_our_check() -> None:
    cbs = _cbs()
    s = scenario(5, 5, [("a", (0, 2), (4, 2)), ("b", (2, 0), (2, 4))])
    result = cbs.plan_cbs(s, time_limit=5)
    assert result.solved, result.note
    verdict = assert_judged_honestly(s, result)
    # 4-connected unit steps with no shared cell and no swap keep centres >= √2/2 apart.
    assert verdict["min_separation"] >= math.sqrt(0.5) - 1e-9
    assert verdict["feasible"]


def test_cbs_diagonal_crossing_is_a_conflict_under_our_check() -> None:
    """8-connected CBS lets two UAVs cross on the diagonals of one square in one step:
    no shared cell, no swap, so valid MAPF, but the UAVs meet in the square's centre,
    and each diagonal is flown √2 times faster than the UAV's speed."""
    cbs = _cbs()
    s = scenario(2, 2, [("a", (0, 0), (1, 1)), ("b", (1, 0), (0, 1))])
    result = cbs.plan_cbs(s, time_limit=5, diagonals=True)
    assert result.solved, result.note
    verdict = assert_judged_honestly(s, result)
    assert verdict["conflicts"] == 1 and verdict["min_separation"] == pytest.approx(0.0)
    assert verdict["max_speed_ratio"] == pytest.approx(math.sqrt(2))
    assert not verdict["safe"] and not verdict["feasible"]


def test_cbs_right_angle_follow_is_a_conflict_for_wide_uavs() -> None:
    """4-connected CBS may move a UAV into a cell as another leaves it at a right angle:
    valid MAPF, but the centres pass √2/2 apart, less than two radii of 0.45."""
    cbs = _cbs()
    s = wide_and_mixed("case-3")
    result = cbs.plan_cbs(s, time_limit=5)
    assert result.solved, result.note
    verdict = assert_judged_honestly(s, result)
    assert verdict["conflicts"] >= 1 and not verdict["feasible"]
    assert verdict["min_separation"] == pytest.approx(math.sqrt(0.5))
    assert verdict["max_speed_ratio"] <= 1  # one clock for all: the slowest UAV's cell time


@pytest.mark.parametrize("diagonals", [False, True], ids=["4-connected", "8-connected"])
def test_cbs_on_the_paper_cases_is_judged_by_our_check(diagonals: bool) -> None:
    cbs = _cbs()
    for name in CASES:
        s = load_case(name)
        result = cbs.plan_cbs(s, time_limit=5, diagonals=diagonals)
        assert result.solved, f"{name}: {result.note}"
        verdict = assert_judged_honestly(s, result)
        assert verdict["mean_deviation"] == 0
        if not diagonals:
            assert verdict["feasible"], f"{name}: {verdict['conflict_messages']}"


def test_cbs_reports_its_own_time_limit() -> None:
    cbs = _cbs()
    result = cbs.plan_cbs(load_case("case-5"), time_limit=0.0)
    assert not result.solved and result.trajectories is None
    assert result.note.startswith("timed out")


def test_cbs_is_killed_when_it_overruns(monkeypatch: pytest.MonkeyPatch) -> None:
    cbs = _cbs()
    if cbs._context().get_start_method() != "fork":
        pytest.skip("the stalled solver is patched in this process; only a fork inherits it")
    import pymapf

    monkeypatch.setattr(pymapf.ConflictBasedSearch, "solve", lambda *a, **k: time.sleep(30))
    monkeypatch.setattr(cbs, "GRACE", 0.1)
    result = cbs.plan_cbs(HEAD_ON, time_limit=0.2)
    assert not result.solved
    assert result.note == "timed out after 0.2 s"
    assert result.seconds < 3
