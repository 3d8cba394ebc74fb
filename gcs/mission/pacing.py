"""Flying a plan slower than planned, keeping its geometry in space and time.

A plan is safe at every moment only if each vehicle is where the plan says. Real
vehicles accelerate at a few m/s², so each start, stop and turn puts them behind by
about v / (2a) seconds and up to v² / (2a) metres off: 20 m at 10 m/s, more than the
6 m a 0.3-cell radius leaves on 10 m cells. Stretching every time of the plan by the
same factor k keeps every relative position of the plan (vehicle i at plan time t is
now there at k·t) while the error shrinks with v²: at 1 m/s it is a few decimetres.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from gcs.mavlink.mission_item import Autopilot, Mission
from gcs.mission.build import DEFAULT_ALTITUDE_M, Finish, build_missions
from planner.plan import Plan
from planner.scenario import Scenario

DEFAULT_MAX_SPEED_M_S = 1.0


def slow_down_factor(plan: Plan, scenario: Scenario, max_speed_m_s: float) -> float:
    """k >= 1 such that no leg of the plan is flown faster than `max_speed_m_s`."""
    if max_speed_m_s <= 0:
        raise ValueError(f"max speed must be positive, got {max_speed_m_s}")
    fastest = 0.0
    for uav in plan.uavs:
        for (t0, x0, y0), (t1, x1, y1) in zip(uav.trajectory, uav.trajectory[1:], strict=False):
            if t1 > t0:
                fastest = max(fastest, ((x1 - x0) ** 2 + (y1 - y0) ** 2) ** 0.5 / (t1 - t0))
    return max(1.0, fastest * scenario.grid.cell_size_m / max_speed_m_s)


def stretched(plan: Plan, scenario: Scenario, factor: float) -> tuple[Plan, Scenario]:
    """The plan with every time multiplied by `factor`, and the scenario with speeds divided."""
    uavs = [
        u.model_copy(update={"trajectory": [[t * factor, x, y] for t, x, y in u.trajectory]})
        for u in plan.uavs
    ]
    specs = [u.model_copy(update={"speed": u.speed / factor}) for u in scenario.uavs]
    return plan.model_copy(update={"uavs": uavs}), scenario.model_copy(update={"uavs": specs})


TURN_RADIUS_M = 0.5
"""A vehicle passing a waypoint cuts the corner by up to its acceptance radius; the plan's
margins are decimetres, so waypoints are accepted close (ArduCopter's default is 2 m)."""


@dataclass(frozen=True)
class PacedFlight:
    """What vehicles fly: the plan slowed by `factor`, and one mission per UAV."""

    factor: float
    plan: Plan  # times multiplied by `factor`: the clock the fleet keeps
    scenario: Scenario  # speeds divided by `factor`
    missions: dict[str, Mission]


def paced_flight(
    plan: Plan,
    scenario: Scenario,
    autopilots: Mapping[str, Autopilot],
    *,
    altitude_m: float = DEFAULT_ALTITUDE_M,
    finish: Finish = "land",
    max_speed_m_s: float = DEFAULT_MAX_SPEED_M_S,
    turn_radius_m: float = TURN_RADIUS_M,
) -> PacedFlight:
    """The missions that fly `plan` no faster than `max_speed_m_s`, each for its vehicle's
    autopilot (ArduPilot missions start with a home item, PX4 ones do not)."""
    factor = slow_down_factor(plan, scenario, max_speed_m_s)
    slow_plan, slow_scenario = stretched(plan, scenario, factor)
    missions: dict[str, Mission] = {}
    for autopilot in set(autopilots.values()):
        built = build_missions(
            slow_plan,
            slow_scenario,
            autopilot,
            altitude_m=altitude_m,
            finish=finish,
            acceptance_radius_m=turn_radius_m,
        )
        missions |= {uav: m for uav, m in built.items() if autopilots[uav] == autopilot}
    return PacedFlight(factor, slow_plan, slow_scenario, missions)
