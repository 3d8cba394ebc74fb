"""The space-time search's heuristic: the time to the goal round the obstacles
(`space_time.goal_distances`), not the octile distance that ignores them. It is admissible
(never above the true distance), kept per grid and goal, and it lets a search behind a
wall finish within the expansions the octile one spends in vain; a search that still runs
out of its limit leaves the UAV to the rest of the safe start, and the plan stays safe.
Before a UAV searches, the UAVs it meets try hovering out of its way (`make_way`); a path
it found is pulled whole and in pieces (`pulled_in_pieces`)."""

from __future__ import annotations

import functools
from collections.abc import Iterator

import numpy as np
import pytest

from planner.check.safety import check_plan, closest_approach
from planner.experiments.scenario_generator import gap_swap_scenario
from planner.flows import anytime, lone_paths
from planner.flows.engine import Engine
from planner.flows.planning import Map
from planner.geometry.grid_search import GridGraph
from planner.model.scenario import UAVSpec
from planner.model.trajectory import Trajectory
from planner.pipeline import PlannerSettings, plan
from planner.search import space_time
from planner.search.any_angle import pull_string
from planner.search.sipp import Mover
from planner.search.space_time import Flight, Search, SearchLimits


@pytest.fixture
def expansions(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """The expansions of every search that ran."""
    seen: list[int] = []
    real = space_time._IndexedSearch.run

    def counted(self: space_time._IndexedSearch) -> list[tuple[float, int, int]] | str:
        out = real(self)
        seen.append(self.expansions)
        return out

    monkeypatch.setattr(space_time._IndexedSearch, "run", counted)
    yield seen


def _walled() -> np.ndarray:
    """A wall across x = 10 with its one gap at the far end (y 27 to 29)."""
    free = np.ones((21, 30), dtype=bool)
    free[10, :27] = False
    return free


def test_goal_distances_are_the_grid_distances_never_below_octile_and_kept() -> None:
    rng = np.random.default_rng(3)
    free = rng.random((40, 30)) > 0.2
    free[5, 7] = True
    field = space_time.goal_distances(free, (5, 7))
    assert np.array_equal(field, GridGraph.build(~free).distances_to((5, 7)))
    xs, ys = np.nonzero(np.isfinite(field))
    dx, dy = np.abs(xs - 5), np.abs(ys - 7)
    octile = np.maximum(dx, dy) + (np.sqrt(2.0) - 1.0) * np.minimum(dx, dy)
    assert np.all(field[xs, ys] >= octile - 1e-9)
    assert space_time.goal_distances(free, (5, 7)) is field  # kept for this grid
    assert space_time.goal_distances(free.copy(), (5, 7)) is not field  # another grid


def test_only_the_last_goals_are_kept() -> None:
    free = np.ones((12, 12), dtype=bool)
    first = space_time.goal_distances(free, (0, 0))
    for k in range(space_time.GOALS_KEPT):
        space_time.goal_distances(free, (1 + k % 11, k // 11))
    assert space_time.goal_distances(free, (0, 0)) is not first
    assert np.array_equal(space_time.goal_distances(free, (0, 0)), first)


def test_behind_a_wall_it_finishes_where_the_octile_search_runs_out(
    expansions: list[int],
) -> None:
    free = _walled()
    spec = UAVSpec(id="a", start=(2, 3), goal=(18, 3))
    other = Trajectory.from_waypoints([(10, 29), (10, 20), (4, 14)], 1.0)  # through the gap
    horizon = other.end_time + 2 * sum(free.shape) / spec.speed  # as `search` sets it
    octile = Search(spec, free, [Flight.of(other, 0.3)], SearchLimits(), horizon)
    assert isinstance(octile.run(), str)
    assert octile.expansions > SearchLimits().max_expansions
    flight = space_time.search(spec, free, [Mover(other, 0.3, 1.0)])
    assert flight is not None and np.allclose(flight.end, spec.goal)
    assert expansions[-1] < SearchLimits().max_expansions
    assert closest_approach(flight, other)[0] >= 0.6
    assert flight.max_speed() <= 1.0 + 1e-9
    assert check_plan({"a": flight}, {"a": 0.3}, ~free).safe


@pytest.mark.parametrize("seed", [1, 3, 6])  # seeds where a search runs
def test_a_search_out_of_expansions_leaves_the_plan_safe(
    monkeypatch: pytest.MonkeyPatch, expansions: list[int], seed: int
) -> None:
    """Every space-time search of the safe start runs out (5 expansions): the UAVs that
    needed one are made safe another way (after the others' changes, or by the optimizer),
    and the plan passes the exact check."""
    tight = SearchLimits(max_expansions=5)
    limits = functools.partial(SearchLimits, max_expansions=tight.max_expansions)
    monkeypatch.setattr(anytime, "SearchLimits", limits)
    scenario = gap_swap_scenario(seed)
    result = plan(scenario, PlannerSettings(seed=seed, time_budget_s=None))
    assert expansions and all(e == tight.max_expansions + 1 for e in expansions)
    assert result.feasible
    paths = {u.id: Trajectory(np.array(u.trajectory)) for u in result.uavs}
    radii = {u.id: u.radius for u in scenario.uavs}
    assert check_plan(paths, radii, scenario.blocked(), scenario.object_cells()).safe


def test_the_other_side_of_a_head_on_meeting_hovers_first(monkeypatch: pytest.MonkeyPatch) -> None:
    """Corridor swaps (seed 0), every trip taken as long (`LONG_TRIP` 0): a UAV that
    cannot wait out its meeting lets the UAVs it meets hover along their own paths
    (`make_way`) before it searches; the plan is safe."""
    monkeypatch.setattr(anytime, "LONG_TRIP", 0.0)
    made_way: list[bool] = []
    real = anytime.make_way

    def spied(engine: Engine, uav: str, world: Map) -> bool:
        made_way.append(real(engine, uav, world))
        return made_way[-1]

    monkeypatch.setattr(anytime, "make_way", spied)
    scenario = gap_swap_scenario(0)
    result = plan(scenario, PlannerSettings(seed=0, time_budget_s=None))
    assert any(made_way)
    assert result.feasible
    paths = {u.id: Trajectory(np.array(u.trajectory)) for u in result.uavs}
    radii = {u.id: u.radius for u in scenario.uavs}
    assert check_plan(paths, radii, scenario.blocked(), scenario.object_cells()).safe


def test_a_path_pulled_in_pieces_keeps_its_cuts_and_is_never_longer() -> None:
    free = _walled()
    spec = UAVSpec(id="a", start=(2, 3), goal=(18, 3))
    flight = space_time.search(spec, free, [])
    assert flight is not None
    geometry = lone_paths.geometry_of(flight)
    length = Trajectory.from_waypoints(geometry, 1.0).length
    whole = anytime.pulled_in_pieces(geometry, 1, 0.3, ~free)
    assert np.array_equal(whole, pull_string(geometry, 0.3, ~free))
    for pieces in (2, 3, len(geometry) - 1):
        pulled = anytime.pulled_in_pieces(geometry, pieces, 0.3, ~free)
        cuts = np.linspace(0, len(geometry) - 1, pieces + 1).round().astype(int)
        assert all((geometry[c] == pulled).all(axis=1).any() for c in cuts)
        assert (
            Trajectory.from_waypoints(whole, 1.0).length - 1e-9
            <= (Trajectory.from_waypoints(pulled, 1.0).length)
            <= length + 1e-9
        )
