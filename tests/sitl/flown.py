"""What a flight on real autopilots came to, measured by the independent observer.

- separation: the closest horizontal approach of two vehicles both more than 1 m up;
- landing: how far from its goal each vehicle was once down (disarmed, under 0.5 m);
- mission time: from the common start (each vehicle's mission going past its take-off
  item: AUTO at altitude over its start) to the last vehicle's arrival over its goal
  (first report within the goal's acceptance radius), each on the vehicle's own clock
  (time_boot_ms), so a SITL speed-up does not enter it.

The yardstick of the mission time is the ground station's own timed flight
(`gcs.mission.flight_plan.FlightPlan.duration_s`: the common start to the last arrival
over a goal, flown with the vehicles' limits and the passing order's waits).
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass

import numpy as np

from gcs.mission.flight_plan import TURN_RADIUS_M
from gcs.mission.geodesy import GridFrame
from gcs.mission.motion import CopterLimits
from planner.cases import load_case
from planner.experiments.scenario_generator import crossing_scenario, gap_swap_scenario
from planner.model.scenario import Origin, Scenario
from tests.sitl.observer import Mark, Observer, metres_apart

CANBERRA = Origin(lat=-35.363262, lon=149.165237, alt_m=584.0)
CROSSING_SEED = 0  # the 10-UAV crossing of the fleet tests
GAP_SWAP_SEED = 0  # six UAVs trading sides through a 2-cell gap in a wall
ARRIVAL_M = TURN_RADIUS_M
"""A goal's acceptance radius: the waypoint radius the ground station gives its missions."""
LAND_DRIFT_M = 0.5
"""Beyond the acceptance radius, what a 20 m descent in still air may drift."""
WIND_LAND_DRIFT_M = 1.5
"""The same in a 5 m/s wind with turbulence (SIM_WIND_TURB 2)."""
TIME_FACTOR = 1.15
"""The mission may take at most this much longer than the ground station's timed flight."""
DOWN_M = 0.5
LIMIT_PARAMS = ("WP_ACC", "WP_JERK", "WP_ACC_CNR", "PSC_JERK_NE", "WP_SPD_DN")
"""ArduCopter 4.8's names of what the ground station reads as a vehicle's limits."""


def two_r(scenario: Scenario) -> float:
    return 2 * max(u.radius for u in scenario.uavs) * scenario.grid.cell_size_m


def named(name: str) -> Scenario:
    """case-1 .. case-6, crossing-10 (seed 0) or gap-swap-6 (seed 0), at CMAC."""
    if name.startswith("case"):
        return load_case(name)
    if name == "crossing-10":
        scenario = crossing_scenario(CROSSING_SEED, uavs=10)
    elif name == "gap-swap-6":
        scenario = gap_swap_scenario(GAP_SWAP_SEED, uavs=6)
    else:
        raise ValueError(f"no scenario {name}")
    return scenario.model_copy(update={"origin": CANBERRA})


def speedup(scenario: Scenario) -> float:
    """Ten SITL instances on two cores keep real time only at a lower speed-up."""
    return 5.0 if len(scenario.uavs) <= 3 else 2.0


@dataclass(frozen=True)
class Flown:
    separation_m: float | None  # by the observer
    landed_m: dict[str, float]  # each vehicle's distance from its goal, once down
    down: dict[str, bool]  # disarmed and under DOWN_M
    started_s: dict[str, float | None]  # own clock at the common start
    arrival_s: dict[str, float | None]  # seconds from the start to over its goal
    mission_s: float | None  # the last arrival; None if one never arrived

    def describe(self) -> str:
        sep = f"{self.separation_m:.2f} m" if self.separation_m is not None else "-"
        mission = f"{self.mission_s:.1f} s" if self.mission_s is not None else "-"
        worst = max(self.landed_m.values(), default=float("nan"))
        return f"observer separation {sep}, mission {mission}, worst landing {worst:.2f} m"


def flown(observer: Observer, scenario: Scenario, takeoff_seq: int = 1) -> Flown:
    frame = GridFrame.of(scenario)
    landed, down, started, arrival = {}, {}, {}, {}
    for k, uav in enumerate(scenario.uavs):
        lat, lon = (float(v) for v in frame.to_geodetic(*uav.goal))
        track = observer.tracks[k]
        last = track.latest()
        goal = Mark(0.0, lat, lon, 0.0)
        landed[uav.id] = float(metres_apart(np.array([last.lat]), np.array([last.lon]), goal)[0])
        down[uav.id] = last.alt < DOWN_M and track.armed is False
        start = observer.started_at(k, takeoff_seq)
        started[uav.id] = start
        over = None if start is None else observer.arrived_at(k, lat, lon, ARRIVAL_M, start)
        arrival[uav.id] = None if over is None or start is None else over - start
    times = list(arrival.values())
    mission = None if any(t is None for t in times) else max(t for t in times if t is not None)
    return Flown(observer.min_separation(), landed, down, started, arrival, mission)


def limits_of(observer: Observer, k: int = 0) -> CopterLimits:
    """Vehicle k's limits from its parameters (the observer asked for LIMIT_PARAMS), the
    way the ground station reads them (`gcs.fleet.vehicle_limits`)."""
    p = observer.tracks[k].params
    values = {
        "accel_m_s2": p.get("WP_ACC"),
        "jerk_m_s3": p.get("WP_JERK"),
        "corner_accel_m_s2": p.get("WP_ACC_CNR"),
        "stop_jerk_m_s3": p.get("PSC_JERK_NE"),
        "descent_m_s": p.get("WP_SPD_DN"),
    }
    if values["corner_accel_m_s2"] is not None and values["corner_accel_m_s2"] <= 0:
        values["corner_accel_m_s2"] = 2 * (values["accel_m_s2"] or CopterLimits().accel_m_s2)
    return dataclasses.replace(
        CopterLimits(), **{k: v for k, v in values.items() if v is not None and v > 0}
    )


PLANNED = re.compile(r"flying at up to ([\d.]+) m/s.*?: ([\d.]+) s to the last goal")
SEPARATION = re.compile(r"separation flown: ([\d.]+) m")
HIGHEST = re.compile(r"the highest speed it can keep safe is ([\d.]+) m/s")


def planned_s(stdout: str) -> float | None:
    """The timed flight's duration `mvo-gcs fly` printed (whole seconds)."""
    found = PLANNED.search(stdout)
    return float(found.group(2)) if found else None


def gcs_separation(stdout: str) -> float | None:
    found = SEPARATION.search(stdout)
    return float(found.group(1)) if found else None
