"""A lander held short of its final approach instead of a passer waiting out its landing:
same paths, a new clock, the order derived from it (so still pointing forward in time),
kept only where the flight ends sooner and every pair stays apart."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pytest

from gcs.mavlink.mission_item import Autopilot
from gcs.mission.flight_plan import flight_plan
from gcs.mission.flight_timing import TimedPath, fly
from gcs.mission.landing_clearance import clear_landings, landing_waits
from gcs.mission.motion import CopterLimits
from gcs.mission.passing_order import PassingOrder, PlannedPath
from planner.experiments.scenario_generator import random_scenario
from planner.model.scenario import Origin
from planner.pipeline import PlannerSettings, plan

MARGIN_M = 0.6
LIMITS = CopterLimits(speed_m_s=5.0)


def _straight(
    uav: str, start: tuple[float, float], end: tuple[float, float], t0: float
) -> PlannedPath:
    """5 m/s from `start` to `end`, leaving at `t0`."""
    xy = np.array([start, end], dtype=float)
    arrive = np.array([t0, t0 + np.hypot(*(xy[1] - xy[0])) / 5.0])
    return PlannedPath(uav, xy, arrive, arrive.copy(), 3.0)


def _lands_on_the_way() -> dict[str, PlannedPath]:
    """`lander` comes east to its goal at (50, 0) at 10 s; `passer` flies north through
    that goal a second later, as a plan that has UAVs gone on arrival allows."""
    return {
        "lander": _straight("lander", (0.0, 0.0), (50.0, 0.0), 0.0),
        "passer": _straight("passer", (50.0, -55.0), (50.0, 45.0), 0.0),
    }


def _timed(paths: Mapping[str, PlannedPath], order: PassingOrder) -> dict[str, TimedPath]:
    legs = {uav: np.full(len(p.xy) - 1, 5.0) for uav, p in paths.items()}
    return fly(paths, legs, dict.fromkeys(paths, LIMITS), order, altitude_m=20.0)


def _score(paths: Mapping[str, PlannedPath], order: PassingOrder) -> tuple[float, float]:
    arrivals = [t.arrival_s for t in _timed(paths, order).values()]
    return max(arrivals), sum(arrivals)


def _derive(paths: Mapping[str, PlannedPath]) -> PassingOrder:
    return PassingOrder.derive(paths.values(), margin_m=MARGIN_M)


def _closest_m(timed: Mapping[str, TimedPath]) -> float:
    """The closest two vehicles come while both are up (a lander is up until down)."""
    ta, tb = timed.values()
    t = np.union1d(ta.t, tb.t)
    t = t[t <= min(ta.t[-1], tb.t[-1])]
    where = [
        np.column_stack(
            [np.interp(np.interp(t, x.t, x.s), x.path.s, x.path.xy[:, i]) for i in (0, 1)]
        )
        for x in (ta, tb)
    ]
    return float(np.hypot(*(where[0] - where[1]).T).min())


def test_a_held_path_hovers_where_asked_and_keeps_its_shape() -> None:
    path = PlannedPath(
        "a", np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]]), np.array([0.0, 2.0, 5.0]),
        np.array([0.0, 3.0, 5.0]), 3.0,
    )  # fmt: skip
    held = path.held(5.0, until=4.0)
    assert held.xy.tolist() == [[0.0, 0.0], [5.0, 0.0], [10.0, 0.0], [20.0, 0.0]]
    assert held.leaves(5.0) == pytest.approx(4.0)
    assert held.arrive.tolist() == pytest.approx([0.0, 1.0, 5.0, 8.0])  # 3 s later on
    assert path.held(10.0, until=6.0).leave.tolist() == pytest.approx([0.0, 6.0, 8.0])
    assert path.held(5.0, until=0.5) is path  # it leaves later anyway


def test_a_lander_holds_short_rather_than_the_passer_waiting_out_its_landing() -> None:
    paths = _lands_on_the_way()
    order = _derive(paths)
    [wait] = landing_waits(order, paths)
    assert (wait.passer, wait.lander) == ("passer", "lander")
    before = _timed(paths, order)
    held, held_order = clear_landings(paths, order, _derive, _score)
    after = _timed(held, held_order)
    assert landing_waits(held_order, held) == []
    assert held["passer"] is paths["passer"]
    assert np.allclose(held["lander"].position(30.0), paths["lander"].position(30.0))
    # the passer no longer waits out the landing; the lander waits a little instead
    assert after["passer"].arrival_s < before["passer"].arrival_s - 20.0
    assert max(t.arrival_s for t in after.values()) < max(t.arrival_s for t in before.values())
    assert _closest_m(after) >= held_order.reach_m[("lander", "passer")] - 2 * order.step_m


def test_a_hold_that_would_not_shorten_the_flight_is_not_kept() -> None:
    """The passer comes from far enough that the lander is down before it gets there:
    holding the lander short would only make it later."""
    paths = _lands_on_the_way()
    paths["passer"] = _straight("passer", (50.0, -300.0), (50.0, 45.0), 0.0)
    order = _derive(paths)
    assert clear_landings(paths, order, _derive, _score) == (paths, order)


@pytest.mark.parametrize("seed", [5, 9])
def test_a_re_timed_flight_still_points_forward_in_time_and_keeps_2r(seed: int) -> None:
    """Generated traffic on which holds are kept: every wait of the new order still has
    its leader leave before its follower arrives on the new clock (no circle), and the
    timed flight keeps every pair 2R apart."""
    scenario = random_scenario(seed, size=20, uavs=8, objects=2).model_copy(
        update={"origin": Origin(lat=-35.36, lon=149.16, alt_m=584.0)}
    )
    planned = plan(scenario.with_clearance(1.3), PlannerSettings(seed=1))
    autopilots = {u.id: Autopilot.ARDUPILOT for u in planned.uavs}
    flight = flight_plan(planned, scenario, autopilots)
    cell = scenario.grid.cell_size_m
    radius = {u.id: u.radius * cell for u in scenario.uavs}
    as_planned = {
        u.id: PlannedPath.of(u.id, u.trajectory, cell, radius[u.id]) for u in flight.plan.uavs
    }
    assert sum(map(_hovering_s, flight.paths.values())) > sum(
        map(_hovering_s, as_planned.values())
    )  # held short somewhere
    for waits in flight.order.waits.values():
        for wait in waits:
            leaves, arrives = wait.plan_times.T
            assert np.all(leaves <= arrives + 1e-9)
    radius_m = max(u.radius for u in scenario.uavs) * cell
    assert flight.min_separation_m() >= 2 * radius_m


def _hovering_s(path: PlannedPath) -> float:
    return float((path.leave - path.arrive).sum())
