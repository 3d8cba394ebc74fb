"""The complete start: the whole fleet searched at once (LaCAM over PIBT), its steps
valid, its answer "no solution" only where none exists, and its flights safe by the
exact check."""

from __future__ import annotations

import itertools
from collections import deque
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs.cli.main import main
from planner.check.safety import check_plan
from planner.experiments.scenario_generator import random_scenario
from planner.flows.complete_start import CORNER_REACH, lockstep_flight
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory
from planner.pipeline import PlannerSettings, plan
from planner.search import lacam

Cell = tuple[int, int]


def _steps_are_valid(
    steps: list[list[Cell | None]], free: np.ndarray, starts: list[Cell], goals: list[Cell]
) -> None:
    assert steps[0] == starts and all(c is None for c in steps[-1])
    for before, after in itertools.pairwise(steps):
        placed = [c for c in after if c is not None]
        assert len(placed) == len(set(placed)), "two UAVs in one cell"
        for uav, (a, b) in enumerate(zip(before, after, strict=True)):
            if a is None:
                assert b is None, "a UAV came back after it left"
                continue
            if b is None:
                assert a == goals[uav], "a UAV left away from its goal"
                continue
            assert free[b] and abs(a[0] - b[0]) + abs(a[1] - b[1]) <= 1
            if a != b and b in before:
                assert after[before.index(b)] != a, "two UAVs swapped cells"
        for uav, cell in enumerate(before):
            if cell is not None and cell == goals[uav]:
                assert after[uav] is None, "a UAV stayed on after its goal"


def _solvable(free: np.ndarray, starts: list[Cell], goals: list[Cell]) -> bool:
    """Breadth-first search over every joint state of a few UAVs (None: left)."""
    moves = ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1))

    def options(uav: int, cell: Cell | None) -> list[Cell | None]:
        if cell is None or cell == goals[uav]:
            return [None]
        near = [(cell[0] + dx, cell[1] + dy) for dx, dy in moves]
        return [
            c for c in near if 0 <= c[0] < free.shape[0] and 0 <= c[1] < free.shape[1] and free[c]
        ]

    first: tuple[Cell | None, ...] = tuple(starts)
    seen, queue = {first}, deque([first])
    while queue:
        state = queue.popleft()
        if all(c is None for c in state):
            return True
        for nxt in itertools.product(*(options(u, c) for u, c in enumerate(state))):
            placed = [c for c in nxt if c is not None]
            swapped = any(
                nxt[i] is not None and nxt[i] == state[j] and nxt[j] == state[i] and i != j
                for i in range(len(state))
                for j in range(len(state))
            )
            if len(placed) == len(set(placed)) and not swapped and nxt not in seen:
                seen.add(nxt)
                queue.append(nxt)
    return False


@st.composite
def small_fleets(draw: st.DrawFn) -> tuple[np.ndarray, list[Cell], list[Cell]]:
    width, height = draw(st.integers(1, 4)), draw(st.integers(1, 3))
    free = np.array(draw(st.lists(st.booleans(), min_size=width * height, max_size=width * height)))
    free = free.reshape(width, height) | (np.arange(width * height).reshape(width, height) < 2)
    cells = [(int(x), int(y)) for x, y in np.argwhere(free)]
    count = draw(st.integers(1, min(3, len(cells))))
    starts = draw(st.permutations(cells))[:count]
    goals = draw(st.permutations(cells))[:count]
    return free, starts, goals


@settings(max_examples=150, deadline=None)
@given(small_fleets(), st.integers(0, 2**32 - 1))
def test_the_search_solves_what_can_be_solved_and_only_that(
    fleet: tuple[np.ndarray, list[Cell], list[Cell]], seed: int
) -> None:
    free, starts, goals = fleet
    found = lacam.search(free, starts, goals, np.random.default_rng(seed))
    assert found.outcome in ("solved", "no solution")
    assert (found.outcome == "solved") == _solvable(free, starts, goals)
    if found.outcome == "solved":
        _steps_are_valid(found.steps, free, starts, goals)


def test_two_uavs_that_must_pass_each_other_in_a_corridor_have_no_solution() -> None:
    corridor = np.ones((3, 1), dtype=bool)
    found = lacam.search(corridor, [(0, 0), (1, 0)], [(2, 0), (0, 0)], np.random.default_rng(0))
    assert found.outcome == "no solution" and found.nodes > 1


def test_the_node_limit_and_the_clock_stop_the_search_and_say_so() -> None:
    free = np.ones((8, 8), dtype=bool)
    starts, goals = [(x, 0) for x in range(8)], [(7 - x, 7) for x in range(8)]
    assert lacam.search(free, starts, goals, np.random.default_rng(0), max_nodes=1).outcome == (
        "node limit"
    )
    stopped = lacam.search(free, starts, goals, np.random.default_rng(0), expired=lambda: True)
    assert stopped.outcome in ("time limit", "solved")  # the clock is read every 64 nodes


def test_a_loop_becomes_a_wait_unless_someone_else_comes_through() -> None:
    a, b, c, d, e = (0, 0), (1, 0), (2, 0), (0, 1), (1, 1)
    wandering: list[list[Cell | None]] = [[a], [b], [a], [b], [c], [None]]
    assert lacam.without_loops(wandering) == [[a], [a], [a], [b], [c], [None]]
    # uav 1 passes through a while uav 0 is away from it: uav 0 cannot wait at a, but
    # it can wait at b (its next loop), and uav 1 at d
    passing: list[list[Cell | None]] = [[a, d], [b, a], [a, d], [b, e], [c, None], [None, None]]
    assert lacam.without_loops(passing) == [
        [a, d], [b, d], [b, d], [b, e], [c, None], [None, None]
    ]  # fmt: skip


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000))
def test_lockstep_flights_keep_the_corner_reach_by_the_exact_check(seed: int) -> None:
    """Two UAVs in lockstep that never share a cell or swap come no closer than √½ cell."""
    scenario = random_scenario(seed, size=8, uavs=10, objects=0)
    free = ~scenario.blocked()
    starts = [u.start for u in scenario.uavs]
    goals = [u.goal for u in scenario.uavs]
    found = lacam.search(free, starts, goals, np.random.default_rng(seed))
    if found.outcome != "solved":
        return
    flights = {
        u.id: lockstep_flight(cells, 1.0)
        for u, cells in zip(scenario.uavs, zip(*found.steps, strict=True), strict=True)
    }
    report = check_plan(flights, {u: CORNER_REACH / 2 for u in flights}, scenario.blocked(), [])
    assert report.safe, report.conflicts[:1]
    assert report.min_separation >= np.sqrt(0.5) - 1e-9


@pytest.mark.parametrize(
    ("scenario", "trigger"),
    [
        (random_scenario(0, size=8, uavs=7, objects=0), "dense"),  # 0.12 UAVs per free cell
        (random_scenario(53, size=10, uavs=8, objects=0), "a UAV the safe start cannot make safe"),
    ],
)
def test_a_fleet_the_safe_start_cannot_finish_gets_the_complete_start(
    scenario: Scenario, trigger: str
) -> None:
    result = plan(scenario, PlannerSettings(population=10, iterations=20, time_budget_s=None))
    m = result.metrics
    assert result.feasible, trigger
    assert m.complete_start is not None and m.complete_start.startswith("safe:"), trigger
    assert m.cost is not None and m.first_safe_cost is not None
    assert m.cost <= m.first_safe_cost + 1e-9  # the safe start's plan kept only if cheaper
    flights = {u.id: _flight(u.trajectory) for u in result.uavs}
    radii = {u.id: u.radius for u in scenario.uavs}
    assert check_plan(flights, radii, scenario.blocked(), scenario.object_cells()).safe


def test_radii_too_large_for_lockstep_are_not_given_the_complete_start() -> None:
    scenario = random_scenario(0, size=8, uavs=7, objects=0)
    wide = scenario.model_copy(
        update={"uavs": [u.model_copy(update={"radius": 0.36}) for u in scenario.uavs]}
    )
    result = plan(wide, PlannerSettings(population=10, iterations=20, time_budget_s=None))
    reason = result.metrics.complete_start
    assert reason == "not tried: two radii add up to 0.72 cells (at most 0.7)"


def _flight(points: list[list[float]]) -> Trajectory:
    return Trajectory(np.array(points))


def test_the_complete_starts_flights_are_returned_when_no_budget_is_left_for_more() -> None:
    """A budget spent before the complete start ends the safe start at once: its flights
    are the plan, and the exact check passes them (lockstep, radius 0.3)."""
    scenario = random_scenario(3, size=8, uavs=7, objects=0)
    result = plan(scenario, PlannerSettings(population=10, iterations=20, time_budget_s=1e-4))
    assert result.feasible and result.metrics.complete_start is not None
    assert all(u.replanned[-1:] == ["complete start"] for u in result.uavs)
    flights = {u.id: _flight(u.trajectory) for u in result.uavs}
    report = check_plan(flights, {u.id: u.radius for u in scenario.uavs}, scenario.blocked(), [])
    assert report.safe and report.min_separation >= np.sqrt(0.5) - 1e-6


def test_the_cli_says_when_the_complete_start_gave_the_plan(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "dense.json"
    path.write_text(random_scenario(0, size=8, uavs=7, objects=0).model_dump_json())
    assert main(["plan", str(path), "--time-budget", "0", "--iterations", "20"]) == 0
    said = capsys.readouterr().err
    assert "first safe plan after" in said and "complete start: safe:" in said
