"""Flying a mission's items ideally reproduces the plan it was built from.

Tolerance. Latitude and longitude are rounded to degE7: 0.5e-7 degree is at most 5.6 mm,
so a waypoint is off by at most R = 7.9 mm horizontally. Each leg's length is then off by
up to 2R, and a vehicle flying at the planned speed keeps the resulting delay, so after k
legs the flight is within (2k + 1) R of the plan at every moment (float32 params add under
1e-4 cell). Leg speeds within SPEED_RTOL of each other are flown as one, which puts the
flight up to SPEED_RTOL of the distance flown ahead or behind. For the paper's cases (10 m
cells, a few legs) that is well under TOL = 0.01 cell, which is what their separation
check allows.
"""

from __future__ import annotations

import itertools
import math
from typing import Literal

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from gcs.mavlink.mission_item import Autopilot, Command, Frame, Mission
from gcs.mission.build import (
    SPEED_RTOL,
    Route,
    build_mission,
    build_missions,
    flown_trajectory,
    fly_ideally,
    mission_schedule,
)
from gcs.mission.geodesy import GridFrame
from planner.cases import CASES, load_case
from planner.check.safety import check_plan
from planner.model.trajectory import Trajectory
from planner.pipeline import PlannerSettings, plan

TOL = 0.01  # cells
DEGE7_ROUNDING_M = 0.0079  # R: horizontal error of a position rounded to degE7
FAST = PlannerSettings(population=10, iterations=20)
CANBERRA = GridFrame(-35.363262, 149.165237, 584.0, 10.0)


def max_deviation(planned: Trajectory, flown: Trajectory) -> float:
    """Largest distance between where the plan and the flight put the UAV at one time."""
    end = min(planned.end_time, flown.end_time)
    times = np.unique(np.concatenate([planned.times, flown.times, np.linspace(0, end, 400)]))
    times = times[times <= end]
    gap = planned.at(times) - flown.at(times)
    return float(np.max(np.hypot(*gap.T)))


def tolerance(planned: Trajectory, frame: GridFrame) -> float:
    """(2k + 1) R in cells for a route of k legs, plus 1e-4 cell for float32 params and
    SPEED_RTOL of the route's length for speeds flown as one."""
    legs = len(Route.of(planned.points)) - 1
    length = float(np.sum(np.hypot(*np.diff(planned.points[:, 1:], axis=0).T)))
    return (2 * legs + 1) * DEGE7_ROUNDING_M / frame.cell_size_m + 1e-4 + SPEED_RTOL * length


def assert_flies_like(planned: Trajectory, mission: Mission, frame: GridFrame) -> float:
    """The flight's largest deviation from the plan, checked against the tolerance."""
    flown = flown_trajectory(mission, frame)
    bound = tolerance(planned, frame)
    deviation = max_deviation(planned, flown)
    assert deviation < bound
    assert np.hypot(*(flown.end - planned.end)) < bound
    speed = max(planned.max_speed(), 1e-9)
    assert flown.end_time == pytest.approx(planned.end_time, abs=bound / speed)
    return deviation


@st.composite
def trajectories(draw: st.DrawFn) -> tuple[np.ndarray, float]:
    """A random polyline on a grid with hovers, speed changes and collinear steps."""
    cruise = draw(st.floats(0.2, 5.0))
    cells = st.tuples(st.integers(0, 30), st.integers(0, 30))
    corners = draw(st.lists(cells, min_size=1, max_size=8))
    corners = [c for k, c in enumerate(corners) if k == 0 or c != corners[k - 1]]
    t = draw(st.floats(0.0, 5.0))  # a hover at the start
    rows = [(0.0, *corners[0])]
    if t > 0:
        rows.append((t, *corners[0]))
    for a, b in itertools.pairwise(corners):
        speed = cruise * draw(st.sampled_from([1.0, 1.0, 0.5, 1.7]))
        pieces = draw(st.integers(1, 3))  # collinear steps at one speed
        for k in range(1, pieces + 1):
            x, y = np.add(a, np.subtract(b, a) * k / pieces)
            t += math.dist(rows[-1][1:], (x, y)) / speed
            rows.append((t, x, y))
        hold = draw(st.sampled_from([0.0, 0.0, 0.25, 3.0]))
        if hold:
            t += hold
            rows.append((t, *b))
    return np.array(rows, dtype=float), cruise


frames = st.builds(
    GridFrame,
    st.floats(-60.0, 60.0),
    st.floats(-179.0, 179.0),
    st.floats(-50.0, 3000.0),
    st.floats(5.0, 50.0),
)


@settings(max_examples=150, deadline=None)
@given(
    trajectories(),
    frames,
    st.sampled_from(list(Autopilot)),
    st.sampled_from(["land", "rtl"]),
)
@example(  # two legs at speeds 9e-5 apart, flown as one at 50 m/s
    (np.array([[0.0, 0.0, 15.0], [1.0001, 2.0, 15.0], [8.56647298, 0.0, 0.0]]), 1.9998),
    GridFrame(0.0, 0.0, 0.0, 25.0),
    Autopilot.ARDUPILOT,
    "land",
)
def test_flying_the_mission_reproduces_the_trajectory(
    case: tuple[np.ndarray, float],
    frame: GridFrame,
    autopilot: Autopilot,
    finish: Literal["land", "rtl"],
) -> None:
    """PX4 flies the plan's own timing; ArduCopter the same route with whole-second holds."""
    points, cruise = case
    mission = build_mission(points, cruise, frame, autopilot, finish=finish)
    route = Route.of(points)
    if autopilot == Autopilot.ARDUPILOT:
        route = route.whole_second_holds()
    assert_flies_like(Trajectory(route_points(route)), mission, frame)


def route_points(route: Route) -> np.ndarray:
    """A route as `[t, x, y]` rows: each place on arrival and, after a hold, on leaving."""
    rows = []
    for (x, y), arrive, hold in zip(route.xy, route.arrive, route.hold, strict=True):
        rows.append((arrive, x, y))
        if hold > 0:
            rows.append((arrive + hold, x, y))
    return np.array(rows)


@settings(max_examples=150, deadline=None)
@given(trajectories())
def test_whole_second_holds_keep_every_arrival_and_the_pace(
    case: tuple[np.ndarray, float],
) -> None:
    route = Route.of(case[0])
    rounded = route.whole_second_holds()
    assert np.array_equal(rounded.arrive, route.arrive)
    assert np.array_equal(rounded.hold, np.round(rounded.hold))
    assert np.all(np.abs(rounded.hold - route.hold) < 1.0)
    if len(route) > 1:
        assert np.max(rounded.speeds) <= np.max(route.speeds) * (1 + 1e-4)
    planned, flown = Trajectory(route_points(route)), Trajectory(route_points(rounded))
    fastest = float(np.max(route.speeds)) if len(route) > 1 else 0.0
    assert max_deviation(planned, flown) <= fastest * 1.0 + 1e-9  # one second at most


@pytest.mark.parametrize("case", CASES)
def test_the_paper_cases_keep_their_separation(case: str) -> None:
    scenario = load_case(case)
    result = plan(scenario, FAST)
    frame = GridFrame.of(scenario)
    missions = build_missions(result, scenario, Autopilot.PX4)
    flown = {}
    for uav in result.uavs:
        planned = Trajectory(np.array(uav.trajectory))
        assert assert_flies_like(planned, missions[uav.id], frame) < TOL
        flown[uav.id] = flown_trajectory(missions[uav.id], frame)
    # Every disc shrunk by TOL / 2: the flights are as safe as the plan, up to TOL.
    radii = {u.id: u.radius - TOL / 2 for u in scenario.uavs}
    report = check_plan(flown, radii, scenario.blocked(), scenario.object_cells())
    assert result.feasible and report.safe, report.conflicts


def test_items_follow_the_convention() -> None:
    # [t, x, y]: 2 cells east at 1 cell/s in two collinear steps, a 3 s hover, then 2 cells
    # north in 3 s.
    points = [[0, 0, 0], [1, 1, 0], [2, 2, 0], [5, 2, 0], [8, 2, 2]]
    mission = build_mission(points, 1.0, CANBERRA, Autopilot.ARDUPILOT, acceptance_radius_m=2)
    commands = [item.command for item in mission.items]
    assert commands == [
        Command.NAV_WAYPOINT,  # home
        Command.NAV_TAKEOFF,
        Command.DO_CHANGE_SPEED,
        Command.NAV_WAYPOINT,  # (2, 0), holding 3 s; (1, 0) merged away
        Command.DO_CHANGE_SPEED,  # the leg north at 2/3 cell/s
        Command.NAV_LAND,
    ]
    home, takeoff, speed, turn, slower, land = mission.items
    assert (home.frame, home.z) == (Frame.GLOBAL, 584.0)
    assert mission.home == pytest.approx((home.lat, home.lon, 584.0), abs=1e-7)
    assert (takeoff.frame, takeoff.x, takeoff.y, takeoff.z) == (6, home.x, home.y, 20.0)
    assert speed.frame == Frame.MISSION and speed.params[:3] == (1.0, 10.0, -1.0)
    assert turn.params[:3] == (3.0, 2.0, 0.0) and math.isnan(turn.params[3])
    assert (turn.frame, turn.z) == (Frame.GLOBAL_RELATIVE_ALT_INT, 20.0)
    assert slower.params[1] == pytest.approx(20 / 3)
    assert (land.frame, land.z) == (Frame.GLOBAL_RELATIVE_ALT_INT, 0.0)


def test_px4_has_no_home_item_and_rtl_ends_after_the_last_waypoint() -> None:
    mission = build_mission([[0, 0, 0], [3, 3, 0]], 1.0, CANBERRA, Autopilot.PX4, finish="rtl")
    commands = [item.command for item in mission.items]
    assert commands == [
        Command.NAV_TAKEOFF,
        Command.DO_CHANGE_SPEED,
        Command.NAV_WAYPOINT,
        Command.NAV_RETURN_TO_LAUNCH,
    ]
    assert mission.home is not None and mission.home[2] == 584.0


def test_schedule_gives_each_nav_item_its_plan_time() -> None:
    points: list[list[float]] = [[0, 0, 0], [1.5, 0, 0], [4.5, 3, 0], [5.5, 3, 0], [7.5, 3, 2]]
    mission = build_mission(points, 1.0, CANBERRA, Autopilot.PX4)
    schedule = mission_schedule(mission)
    # seq 2: the hover at the start; 3: (3, 0) hold 1 s; 4: land at (3, 2)
    assert list(schedule) == [2, 3, 4]
    assert [schedule[s] for s in (2, 3, 4)] == pytest.approx([0.0, 4.5, 7.5], abs=1e-3)
    assert fly_ideally(mission)[1].leave == pytest.approx(5.5, abs=1e-3)


def test_an_ardupilot_schedule_holds_whole_seconds_and_arrives_on_time() -> None:
    """The 1.5 s hover at the start becomes 1 s (2 s would make the next leg too fast);
    that leg is then flown slower, so (3, 0) is still reached at 4.5 s."""
    points: list[list[float]] = [[0, 0, 0], [1.5, 0, 0], [4.5, 3, 0], [5.5, 3, 0], [7.5, 3, 2]]
    mission = build_mission(points, 1.0, CANBERRA, Autopilot.ARDUPILOT)
    visits = fly_ideally(mission)
    assert [v.leave - v.arrive for v in visits] == pytest.approx([1.0, 1.0, 0.0], abs=1e-6)
    assert [v.arrive for v in visits] == pytest.approx([0.0, 4.5, 7.5], abs=1e-3)


def test_route_keeps_turns_speed_changes_and_hovers_only() -> None:
    # [t, x, y]: 3 collinear cells at 1 cell/s, a 1 s hover, 1 cell at 1 cell/s, 1 at 0.5.
    points = [[0, 0, 0], [1, 1, 0], [2, 2, 0], [3, 3, 0], [4, 3, 0], [5, 3, 1], [7, 3, 2]]
    route = Route.of(points)
    assert route.xy.tolist() == [[0, 0], [3, 0], [3, 1], [3, 2]]
    assert route.arrive.tolist() == [0, 3, 5, 7]
    assert route.hold.tolist() == [0, 1, 0, 0]
    assert route.speeds.tolist() == pytest.approx([1.0, 1.0, 0.5])


def test_without_holds_every_leg_keeps_its_own_speed_and_a_straight_line_is_one_leg() -> None:
    """For a flight by passing order: a hover on a straight line is neither a waypoint
    (ArduCopter plans one waypoint ahead, so short legs hold it back) nor spread over the
    next leg as a slower speed (the timing and the order take that leg at its own)."""
    # east at 1 cell/s with hovers of 2 s and 1 s on the way, then north at 0.5 cell/s
    points = [[0, 0, 0], [1, 1, 0], [3, 1, 0], [4, 2, 0], [5, 2, 0], [6, 3, 0], [8, 3, 1]]
    route = Route.of(points).without_holds()
    assert route.xy.tolist() == [[0, 0], [3, 0], [3, 1]]
    assert route.speeds.tolist() == pytest.approx([1.0, 0.5])
    assert route.hold.tolist() == [0, 0, 0]
    mission = build_mission(points, 1.0, CANBERRA, Autopilot.ARDUPILOT, holds=False)
    waypoints = [i for i in mission.items if i.command == Command.NAV_WAYPOINT][1:]  # no home
    speeds = [i.params[1] for i in mission.items if i.command == Command.DO_CHANGE_SPEED]
    assert len(waypoints) == 1 and all(w.params[0] == 0 for w in waypoints)
    assert speeds == pytest.approx([10.0, 5.0])  # m/s, 10 m cells


def test_refuses_what_cannot_be_flown() -> None:
    with pytest.raises(ValueError, match="zero time"):
        Route.of([[0, 0, 0], [0, 1, 0]])
    with pytest.raises(ValueError, match="decrease"):
        Route.of([[1, 0, 0], [0, 1, 0]])
    scenario = load_case("case-1").model_copy(update={"origin": None})
    with pytest.raises(ValueError, match="no origin"):
        GridFrame.of(scenario)
    infeasible = plan(load_case("case-1"), FAST).model_copy(update={"feasible": False})
    with pytest.raises(ValueError, match="infeasible"):
        build_missions(infeasible, load_case("case-1"))


def test_geodesy_round_trips_and_points_east_and_north() -> None:
    x, y = np.array([0.0, 3.0, -2.5]), np.array([0.0, 4.0, 7.25])
    lat, lon = CANBERRA.to_geodetic(x, y)
    back = CANBERRA.to_cells(lat, lon)
    assert np.allclose(back, (x, y), atol=1e-9)
    assert lat[1] > lat[0] and lon[1] > lon[0]  # north and east
