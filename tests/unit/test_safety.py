import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.check.safety import cell_conflicts, check_plan, closest_approach
from planner.model.trajectory import Trajectory
from planner.search.path_cost import Traffic, separation_terms, timeline


def fly(points, speed=1.0, waits=None) -> Trajectory:
    return Trajectory.from_waypoints(points, speed, waits)


def test_head_on_conflict_where_and_when() -> None:
    a, b = fly([(0, 0), (4, 0)]), fly([(4, 0), (0, 0)])
    report = check_plan({"a": a, "b": b}, {"a": 0.3, "b": 0.3}, np.zeros((5, 1), dtype=bool))
    (conflict,) = report.conflicts
    assert conflict.uavs == ("a", "b") and conflict.time == pytest.approx(2.0)
    assert conflict.position == pytest.approx((2.0, 0.0)) and conflict.separation == 0.0
    assert "a and b come 0.000 cells apart (need 0.600) at t = 2.00 s" in conflict.describe()


def test_parallel_lanes_and_landed_uavs_are_safe() -> None:
    lanes = {"a": fly([(0, 0), (4, 0)]), "b": fly([(0, 1), (4, 1)])}
    assert check_plan(lanes, {"a": 0.3, "b": 0.3}, np.zeros((5, 2), dtype=bool)).safe
    # b lands on a's path at t = 1; a passes there at t = 3: a landed UAV is gone.
    landed = {"a": fly([(0, 0), (4, 0)]), "b": fly([(3, 1), (3, 0)])}
    assert check_plan(landed, {"a": 0.3, "b": 0.3}, np.zeros((5, 2), dtype=bool)).safe


def test_hovering_uav_is_still_there() -> None:
    a = fly([(0, 0), (4, 0)])
    b = fly([(2, 0), (2, 0.0001)], waits=[5.0, 0.0])  # hovers on a's path for 5 s
    assert closest_approach(a, b)[0] < 0.6


def test_corner_cutting_past_a_blocked_cell_is_a_conflict() -> None:
    blocked = np.zeros((3, 3), dtype=bool)
    blocked[1, 0] = True
    (hit,) = cell_conflicts("a", fly([(0, 0), (1, 1)]), 0.3, blocked)
    assert hit.cell == (1, 0) and hit.separation == 0.0
    assert not cell_conflicts("a", fly([(0, 1), (2, 1)]), 0.3, blocked)  # 0.5 away: clear
    assert cell_conflicts("a", fly([(0, 0.75), (2, 0.75)]), 0.3, blocked)  # 0.25 away


trajectory = st.lists(st.tuples(st.floats(0, 6), st.floats(0, 6)), min_size=1, max_size=5).map(
    lambda pts: fly(pts)
)


@settings(max_examples=150, deadline=None)
@given(a=trajectory, b=trajectory)
def test_exact_closest_approach_never_above_dense_sampling(a, b) -> None:
    exact, when = closest_approach(a, b)
    end = min(a.end_time, b.end_time)
    t = np.linspace(0, end, 4001)
    sampled = np.hypot(*(a.at(t) - b.at(t)).T).min()
    assert exact <= sampled + 1e-9
    assert exact >= sampled - 2 * 1.0 * end / 4000 - 1e-9  # the samples are at most that far
    assert 0 <= when <= end + 1e-9


def traffic(
    others: list[Trajectory], start: np.ndarray, lower=(-1.0, -1.0), upper=(7.0, 7.0)
) -> Traffic:
    return Traffic.around(
        [(o, 0.3, 1.0) for o in others],
        radius=0.3,
        speed=1.0,
        start=start,
        lower=np.array(lower),
        upper=np.array(upper),
    )


@settings(max_examples=150, deadline=None)
@given(
    mine=st.lists(st.tuples(st.floats(0, 6), st.floats(0, 6)), min_size=2, max_size=5),
    hold=st.lists(st.floats(0, 3), min_size=5, max_size=5),
    others=st.lists(trajectory, min_size=1, max_size=3),
)
def test_planner_cost_errs_on_the_safe_side_only(mine, hold, others) -> None:
    """Every real conflict is caught; a false alarm needs a near miss within the margin."""
    waypoints = np.array(mine)[None]
    waits = np.array(hold[: len(mine)])[None]
    times, positions = timeline(waypoints, waits, 1.0)
    _, hits = separation_terms(times, positions, traffic(others, waypoints[0, 0]))
    me = Trajectory(np.column_stack([times[0], positions[0]]))
    exact = min(closest_approach(me, o)[0] for o in others)
    if exact < 0.6:
        assert hits[0] > 0
    if exact >= 0.8:  # radii 0.6 + margin 0.1 + half a step of the other's motion, 0.05
        assert hits[0] == 0
