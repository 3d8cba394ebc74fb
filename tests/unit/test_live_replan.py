"""The live wormhole step: an object reported in flight changes only the UAVs it touches.

Every outcome is judged by dense sampling that shares no code with planner.check.safety.
"""

import functools
import json
import math
from pathlib import Path
from typing import Any, cast

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.typing import ArrayLike

from planner.cases import load_case
from planner.experiments.scenario_generator import crossing_scenario
from planner.live.replan import LiveReplan, NewObject, replan_live
from planner.live.search import _entry_cell
from planner.model.plan import Plan
from planner.model.scenario import Scenario, load_scenario
from planner.model.trajectory import Trajectory
from planner.pipeline import PlannerSettings, plan

STEP = 0.005  # seconds between the judge's samples
SETTINGS = PlannerSettings(population=20, iterations=150)


@functools.cache
def planned(name: str) -> tuple[Scenario, Plan]:
    scenario = load_case(name) if name.startswith("case") else crossing_scenario(3)
    result = plan(scenario, SETTINGS)
    assert result.feasible
    return scenario, result


def track(points: ArrayLike, t: np.ndarray) -> np.ndarray:
    """Positions at `t`, NaN when not airborne."""
    p = np.array(points)
    out = np.column_stack([np.interp(t, p[:, 0], p[:, 1]), np.interp(t, p[:, 0], p[:, 2])])
    out[(t < p[0, 0]) | (t > p[-1, 0])] = np.nan
    return out


def square_distance(xy: np.ndarray, cell: tuple[int, int]) -> np.ndarray:
    off = np.maximum(np.abs(xy - np.array(cell)) - 0.5, 0.0)
    return np.hypot(off[:, 0], off[:, 1])


def cells_touched(points: ArrayLike, radius: float, t0: float, t1: float) -> set:
    """Cells whose square the disc enters while flying during [t0, t1]."""
    end = min(t1, float(np.asarray(points)[-1, 0]))
    t = np.append(np.arange(t0, end, STEP), end)
    xy = track(points, t)
    xy = xy[~np.isnan(xy[:, 0])]
    found = set()
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            cells = np.rint(xy).astype(int) + np.array([dx, dy])
            off = np.maximum(np.abs(xy - cells) - 0.5, 0.0)
            near = np.hypot(off[:, 0], off[:, 1]) < radius
            found |= {(int(x), int(y)) for x, y in cells[near]}
    return found


def fleet_after(result: Plan, live: LiveReplan) -> dict[str, list[list[float]]]:
    """Every flight as it now stands (the changed ones start at `now`)."""
    return {
        u.id: live.changed[u.id].to_json() if u.id in live.changed else u.trajectory
        for u in result.uavs
    }


def judge(
    scenario: Scenario, result: Plan, live: LiveReplan, objects: list[NewObject]
) -> list[str]:
    """Every problem of the remaining flights after `now`, found by dense sampling."""
    flights = fleet_after(result, live)
    radius = {u.id: u.radius for u in scenario.uavs}
    end = max(p[-1][0] for p in flights.values())
    t = np.arange(live.now, end + STEP, STEP)
    where = {u: track(p, t) for u, p in flights.items()}
    forever = [(c, -math.inf, math.inf) for c in scenario.obstacles]
    forever += [((c[0], c[1]), -math.inf, math.inf) for c in result.non_uav_objects]
    timed = [(o.cell, *(o.window or (live.now, math.inf))) for o in objects]
    problems = []
    ids = list(flights)
    for i, a in enumerate(ids):
        for b in ids[i + 1 :]:
            gap = np.hypot(*(where[a] - where[b]).T)
            if np.nanmin(gap, initial=np.inf) < radius[a] + radius[b] - 1e-6:
                problems.append(f"{a}-{b}")
        for cell, t0, t1 in forever + timed:
            during = (t >= t0) & (t <= t1) & ~np.isnan(where[a][:, 0])
            if during.any() and square_distance(where[a][during], cell).min() < radius[a] - 1e-6:
                problems.append(f"{a}@{cell}")
    return problems


def assert_replanned_from_where_it_is(
    scenario: Scenario, result: Plan, live: LiveReplan, uav: str, at: np.ndarray
) -> None:
    new = live.changed[uav].points
    spec = next(u for u in scenario.uavs if u.id == uav)
    assert new[0, 0] == pytest.approx(live.now, abs=1e-6)
    assert new[0, 1:] == pytest.approx(at, abs=1e-6)
    assert new[-1, 1:] == pytest.approx(spec.goal, abs=1e-9)
    assert np.all(np.diff(new[:, 0]) >= 0)
    legs = np.hypot(*np.diff(new[:, 1:], axis=0).T)
    moving = legs > 1e-9
    assert np.all(
        legs[moving] / np.diff(new[:, 0])[moving] <= spec.speed * (1 + 1e-4)
    )  # json rounds to 1e-6


def a_cell_only_on(scenario: Scenario, result: Plan, now: float) -> tuple[str, tuple[int, int]]:
    """A UAV and a free cell ahead on its remaining path that no other remaining path,
    its goal or its present position touches."""
    radius = {u.id: u.radius for u in scenario.uavs}
    goals = {u.id: tuple(u.goal) for u in scenario.uavs}
    blocked = set(scenario.obstacles) | {tuple(c) for c in result.non_uav_objects}
    ahead = {
        u.id: cells_touched(u.trajectory, radius[u.id], now + 1.0, math.inf) for u in result.uavs
    }
    for u in result.uavs:
        others = set().union(
            *(
                cells_touched(v.trajectory, radius[v.id], now, math.inf)
                for v in result.uavs
                if v is not u
            )
        )
        here = cells_touched(u.trajectory, radius[u.id], now, now)
        free = sorted(ahead[u.id] - others - here - blocked - {goals[u.id]})
        if free:
            return u.id, free[len(free) // 2]
    raise AssertionError("no cell on exactly one remaining path")


@pytest.mark.parametrize("name", ["case-6", "crossing"])
def test_object_on_one_remaining_path_changes_only_that_uav(name: str) -> None:
    scenario, result = planned(name)
    now = 0.5 * min(u.trajectory[-1][0] for u in result.uavs)
    uav, cell = a_cell_only_on(scenario, result, now)
    obj = NewObject(cell)
    live = replan_live(scenario, result, obj, now=now, settings=SETTINGS)
    assert live.touched == [uav] and list(live.changed) == [uav] and live.unresolved == []
    at = track(next(u.trajectory for u in result.uavs if u.id == uav), np.array([now]))[0]
    assert_replanned_from_where_it_is(scenario, result, live, uav, at)
    assert cell not in cells_touched(live.changed[uav].points, 0.3, now, math.inf)
    assert live.feasible and live.conflicts == []
    assert judge(scenario, result, live, [obj]) == []
    assert uav in live.explanation


def test_object_on_nobodys_path_or_on_a_flown_part_changes_nothing() -> None:
    scenario, result = planned("case-6")
    now = 2.5
    radius = {u.id: u.radius for u in scenario.uavs}
    later = set().union(*(cells_touched(u.trajectory, radius[u.id], now, 99) for u in result.uavs))
    flown = set().union(*(cells_touched(u.trajectory, radius[u.id], 0, now) for u in result.uavs))
    assert flown - later, "the test needs a cell flown over but not ahead"
    for cell in [sorted(flown - later)[0], (0, 8)]:
        assert cell not in later
        live = replan_live(scenario, result, NewObject(cell), now=now, settings=SETTINGS)
        assert (live.touched, live.changed, live.feasible) == ([], {}, True)
        assert "touches no" in live.explanation


def test_a_landed_uav_is_not_touched_even_on_its_goal() -> None:
    scenario, result = planned("case-6")
    first = min(result.uavs, key=lambda u: u.trajectory[-1][0])
    goal = next(u.goal for u in scenario.uavs if u.id == first.id)
    live = replan_live(scenario, result, NewObject(goal), now=first.trajectory[-1][0] + 0.1)
    assert first.id not in live.touched and first.id not in live.changed


def window_cases() -> tuple:
    scenario, result = planned("case-6")
    now = 1.0
    uav, cell = a_cell_only_on(scenario, result, now)
    points = next(u.trajectory for u in result.uavs if u.id == uav)
    t = np.arange(now, points[-1][0], STEP)
    inside = square_distance(track(points, t), cell) < 0.3
    return scenario, result, now, uav, cell, t[inside][0], t[inside][-1]


def test_object_there_only_before_or_after_the_uav_passes_touches_nothing() -> None:
    scenario, result, now, _, cell, enter, leave = window_cases()
    for window in [(0.0, enter - 0.05), (leave + 0.05, leave + 5.0), (0.0, now - 0.1)]:
        live = replan_live(scenario, result, NewObject(cell, window), now=now, settings=SETTINGS)
        assert (live.touched, live.changed, live.feasible) == ([], {}, True)


def test_object_there_while_the_uav_passes_replans_it_within_the_window() -> None:
    scenario, result, now, uav, cell, enter, leave = window_cases()
    obj = NewObject(cell, (enter - 0.5, leave + 0.5))
    live = replan_live(scenario, result, obj, now=now, settings=SETTINGS)
    assert live.touched == [uav] and list(live.changed) == [uav] and live.feasible
    assert judge(scenario, result, live, [obj]) == []


def corridor() -> tuple[Scenario, Plan]:
    scenario = load_scenario(
        {
            "grid": {"width": 7, "height": 1},
            "uavs": [{"id": "east", "start": [0, 0], "goal": [6, 0]}],
        }
    )
    return scenario, plan(scenario, SETTINGS)


def test_a_walled_off_uav_is_reported_not_handed_an_unsafe_path() -> None:
    scenario, result = corridor()
    live = replan_live(scenario, result, NewObject((4, 0)), now=1.0, settings=SETTINGS)
    assert live.touched == ["east"] and live.changed == {} and live.unresolved == ["east"]
    assert not live.feasible and live.conflicts[0]["kind"] == "non_uav_object"
    assert live.conflicts[0]["time"] > 1.0  # plan time
    assert "east" in live.explanation and "no way" in live.explanation


def test_a_uav_waits_for_an_object_with_a_window_to_go() -> None:
    scenario, result = corridor()
    obj = NewObject((4, 0), (0.0, 5.0))
    live = replan_live(scenario, result, obj, now=1.0, settings=SETTINGS)
    assert live.feasible and list(live.changed) == ["east"]
    assert judge(scenario, result, live, [obj]) == []
    new = live.changed["east"].points
    t = np.arange(1.0, new[-1, 0], STEP)
    entered = t[square_distance(track(live.changed["east"].points, t), (4, 0)) < 0.3]
    assert entered.min() > 5.0


def test_an_object_on_a_goal_with_no_end_is_explained() -> None:
    scenario, result = planned("case-6")
    uav = scenario.uavs[2]
    live = replan_live(scenario, result, NewObject(uav.goal), now=2.0, settings=SETTINGS)
    assert uav.id in live.touched and uav.id in live.unresolved and uav.id not in live.changed
    assert not live.feasible and "goal" in live.explanation and uav.id in live.explanation


def test_an_object_on_a_goal_for_a_while_makes_the_uav_hover_until_it_goes() -> None:
    scenario, result = planned("case-6")
    uav = scenario.uavs[2]
    obj = NewObject(uav.goal, (0.0, 12.0))
    live = replan_live(scenario, result, obj, now=2.0, settings=SETTINGS)
    assert live.feasible and list(live.changed) == [uav.id]
    assert live.changed[uav.id].end_time > 12.0
    assert judge(scenario, result, live, [obj]) == []


def test_an_object_on_the_uavs_own_cell_is_explained() -> None:
    scenario, result = planned("case-6")
    uav = result.uavs[2]
    here = track(uav.trajectory, np.array([1.0]))[0]
    cell = (round(here[0]), round(here[1]))
    live = replan_live(scenario, result, NewObject(cell), now=1.0, settings=SETTINGS)
    assert uav.id in live.unresolved and not live.feasible
    assert "is in the object's cell" in live.explanation and uav.id in live.explanation


def test_a_reported_position_is_where_the_new_path_starts() -> None:
    scenario, result = planned("case-6")
    now = 1.0
    uav, cell = a_cell_only_on(scenario, result, now)
    points = next(u.trajectory for u in result.uavs if u.id == uav)
    at = track(points, np.array([now]))[0] + (0.12, -0.07)
    live = replan_live(
        scenario, result, NewObject(cell), now=now, positions={uav: tuple(at)}, settings=SETTINGS
    )
    assert live.feasible
    assert_replanned_from_where_it_is(scenario, result, live, uav, at)


def test_a_uav_behind_the_fleets_clock_is_replanned_from_where_it_is_on_its_own_plan() -> None:
    """Flown by the passing order, a UAV may be behind the plan's clock: an object ahead
    of it, on a stretch the clock alone says it has passed, still touches it."""
    scenario, result = planned("case-6")
    own = 1.0
    uav, cell = a_cell_only_on(scenario, result, own)
    spec = next(u for u in scenario.uavs if u.id == uav)
    points = next(u.trajectory for u in result.uavs if u.id == uav)
    end = points[-1][0]
    now = next(  # the fleet's clock: once this UAV's plan has gone past the cell
        t
        for t in np.arange(own, end, 0.05)
        if cell not in cells_touched(points, spec.radius, t, end)
    )
    by_clock = replan_live(scenario, result, NewObject(cell), now=now, settings=SETTINGS)
    assert uav not in by_clock.touched
    at = track(points, np.array([own]))[0]
    live = replan_live(
        scenario, result, NewObject(cell), now=now, positions={uav: tuple(at)},
        progress={uav: own}, settings=SETTINGS,
    )  # fmt: skip
    assert uav in live.touched and uav in live.changed
    assert_replanned_from_where_it_is(scenario, result, live, uav, at)
    with pytest.raises(ValueError, match="progress"):
        replan_live(scenario, result, NewObject(cell), now=now, progress={uav: math.nan})


@pytest.mark.parametrize("there", ["for good", "while it passes", "after it passed"])
def test_known_objects_are_part_of_the_check(there: str) -> None:
    scenario, result, now, uav, cell, enter, leave = window_cases()
    window = {
        "for good": None,
        "while it passes": (enter, leave),
        "after it passed": (leave + 0.1, 99),
    }
    known = NewObject(cell, window[there])
    live = replan_live(scenario, result, NewObject((0, 8)), now=now, known_objects=[known])
    assert live.touched == [] and live.changed == {}
    if there == "after it passed":
        assert live.feasible
    else:
        assert not live.feasible and "no safe plan" in live.explanation
        assert live.conflicts[0]["uavs"] == [uav] and live.conflicts[0]["cell"] == list(cell)
        assert enter - 0.01 <= live.conflicts[0]["time"] <= leave + 0.01  # plan time


def test_same_seed_same_answer() -> None:
    scenario, result = planned("case-6")
    _, cell = a_cell_only_on(scenario, result, 1.0)
    a, b = (replan_live(scenario, result, NewObject(cell), now=1.0) for _ in range(2))
    assert a.to_json() == b.to_json()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"new_object": NewObject((9, 0))}, "outside the 9x9 grid"),
        ({"new_object": NewObject((-1, 2))}, "outside"),
        ({"new_object": NewObject(cast(Any, (2.0, 2)))}, "two integers"),  # refused at run time
        ({"new_object": NewObject((2, 2), (5.0, 4.0))}, "t0 <= t1"),
        ({"new_object": NewObject((2, 2), (math.nan, 4.0))}, "t0 <= t1"),
        ({"now": -1.0}, "now"),
        ({"now": math.inf}, "now"),
        ({"positions": {"ghost": (1.0, 1.0)}}, "unknown UAV 'ghost'"),
        ({"positions": {"uav1": (1.0, 9.0)}}, "outside the grid"),
        ({"positions": {"uav1": (math.nan, 1.0)}}, "outside the grid"),
        ({"known_objects": [NewObject((3, 30))]}, "outside"),
    ],
)
def test_bad_input_is_refused_with_a_message(kwargs: dict, message: str) -> None:
    scenario, result = planned("case-6")
    args = {"new_object": NewObject((2, 2)), "now": 1.0, **kwargs}
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        replan_live(scenario, result, **args)


def test_a_plan_of_another_scenario_is_refused() -> None:
    _, result = planned("case-6")
    with pytest.raises(ValueError, match="not the scenario's"):
        replan_live(corridor()[0], result, NewObject((2, 0)), now=1.0)


@st.composite
def reports(draw) -> tuple[str, NewObject, float]:
    """A scenario, an object and a time; half the objects land on a cell some UAV flies
    over later."""
    name = draw(st.sampled_from(["case-6", "case-6", "crossing"]))
    scenario, result = planned(name)
    now = draw(st.floats(0.0, 8.0 if name == "case-6" else 20.0))
    if draw(st.booleans()):
        points = draw(st.sampled_from(result.uavs)).trajectory
        ahead = track(points, np.array([now + draw(st.floats(0.0, 4.0))]))[0]
        cell = (0, 0) if np.isnan(ahead[0]) else (round(ahead[0]), round(ahead[1]))
    else:
        side = scenario.grid.width - 1
        cell = draw(st.tuples(st.integers(0, side), st.integers(0, side)))
    window = draw(st.none() | st.tuples(st.floats(0.0, 10.0), st.floats(0.0, 6.0)))
    return name, NewObject(cell, None if window is None else (window[0], sum(window))), now


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(report=reports(), seed=st.integers(0, 1000))
def test_whatever_comes_back_is_safe_or_says_it_is_not(
    report: tuple[str, NewObject, float], seed: int
) -> None:
    name, obj, now = report
    scenario, result = planned(name)
    live = replan_live(
        scenario,
        result,
        obj,
        now=now,
        settings=PlannerSettings(seed=seed, population=15, iterations=80),
    )
    assert set(live.changed) <= set(live.touched) and set(live.unresolved) <= set(live.touched)
    for uav, new in live.changed.items():
        old = next(u.trajectory for u in result.uavs if u.id == uav)
        points = new.points
        assert points[0][0] == pytest.approx(now, abs=1e-6)
        assert points[0][1:] == pytest.approx(track(old, np.array([now]))[0].tolist(), abs=1e-6)
    if live.feasible:
        assert live.conflicts == [] and live.unresolved == []
        assert judge(scenario, result, live, [obj]) == []
    else:
        assert live.conflicts and "no safe plan" in live.explanation


def test_numpy_numbers_are_accepted_and_printed_plainly() -> None:
    scenario, result = planned("case-6")
    cell = cast(Any, (np.int64(0), np.int64(8)))  # not ints to a type checker, but accepted
    obj = NewObject(cell, (np.float64(0.0), np.float64(9.0)))
    live = replan_live(scenario, result, obj, now=1.0)
    assert live.feasible and "(0, 8)" in live.explanation


def test_between_cuts_a_flight_at_any_two_times() -> None:
    flight = Trajectory(np.array([[0.0, 0, 0], [2, 2, 0], [5, 2, 0], [6, 2, 1]]))
    part = flight.between(1.0, 5.5)
    assert part is not None
    assert part.points.tolist() == [[1, 1, 0], [2, 2, 0], [5, 2, 0], [5.5, 2, 0.5]]
    assert flight.between(7.0, 9.0) is None and flight.between(-3.0, -1.0) is None
    whole = flight.between(-1.0, 99.0)
    assert whole is not None
    assert whole.points.tolist() == flight.points.tolist()


def test_kept_uavs_that_the_replans_moment_brings_together_are_replanned_too() -> None:
    """Fuzzed flight 3294's replan, as the service asked it: every rest starts at the
    replan's moment wherever its UAV is, and two kept UAVs (uav1, uav5) then met 0.198
    cells apart; the flight's order kept no more than that. One of them is replanned."""
    data = json.loads((Path(__file__).parent / "data" / "live_replan_3294.json").read_text())
    scenario = load_scenario(data["scenario"])
    result = replan_live(
        scenario,
        Plan.model_validate(data["plan"]),
        NewObject(tuple(data["object"]["cell"])),
        now=data["now"],
        positions={u: tuple(p) for u, p in data["positions"].items()},
        progress=data["progress"],
    )
    assert result.touched == ["uav4"]
    assert result.feasible, result.explanation
    assert set(result.changed) - set(result.touched), "no kept UAV was replanned"


def test_a_replanned_path_starts_from_a_cell_that_leads_to_the_goal() -> None:
    """Of the cells round a UAV, the ones it reaches without grazing a blocked cell are
    preferred, but never one cut off from the goal: the only way on here grazes the
    wall (fuzzed flight 3034, a 500 on an object report: "a finite distance always has
    a downhill neighbour" from a start cut off by the objects)."""
    blocked = np.zeros((5, 5), dtype=bool)
    blocked[2, 3] = True
    distance = np.full((5, 5), np.inf)
    distance[3, 3] = 1.0  # only (3, 3) leads on; the way there grazes (2, 3)
    assert _entry_cell(np.array([2.0, 2.0]), 0.3, distance, blocked) == (3, 3)
