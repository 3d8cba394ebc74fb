"""A geographic scenario whose vehicles stand off their start cells' centres (where a
start "at vehicle X" snaps to): three UAVs crossing a 90 x 60 m field in 10 m cells,
shared by the in-process and the real-SITL tests of the fly-to-start launch."""

from __future__ import annotations

import functools

from gcs.mission.flight_plan import DEFAULT_CLEARANCE_M
from gcs.mission.geodesy import GridFrame
from gcs.mission.geographic import derive, load_geographic
from planner.model.plan import Plan
from planner.model.scenario import Scenario
from planner.pipeline import PlannerSettings, plan

CMAC = (-35.363262, 149.165237, 584.0)
CELL_M = 10.0
OFF_CENTRE_M = {"uav1": (4.0, 3.5), "uav2": (-4.0, 4.0), "uav3": (3.0, -4.5)}
"""Where each vehicle stands from its start cell's centre: 5.3, 5.7 and 5.4 m."""


def _point(east: float, north: float) -> list[float]:
    frame = GridFrame(CMAC[0], CMAC[1], CMAC[2], 1.0)
    lat, lon = frame.to_geodetic(east, north)
    return [float(lon), float(lat)]


def _feature(role: str, geometry: dict[str, object], uav: str | None = None) -> dict[str, object]:
    properties: dict[str, object] = {"role": role}
    if uav is not None:
        properties["uav"] = uav
    return {"type": "Feature", "geometry": geometry, "properties": properties}


@functools.cache
def planned() -> tuple[Scenario, Plan]:
    """Three UAVs crossing a 90 x 60 m field, starts and goals 30 m apart."""
    corners = [_point(0, 0), _point(90, 0), _point(90, 60), _point(0, 60), _point(0, 0)]
    ends = {
        "uav1": ((12, 12), (78, 48)),
        "uav2": ((12, 48), (78, 12)),
        "uav3": ((45, 12), (45, 48)),
    }
    features = [_feature("area", {"type": "Polygon", "coordinates": [corners]})]
    for uav, (start, goal) in ends.items():
        features.append(_feature("start", {"type": "Point", "coordinates": _point(*start)}, uav))
        features.append(_feature("goal", {"type": "Point", "coordinates": _point(*goal)}, uav))
    document = {
        "type": "FeatureCollection",
        "features": features,
        "properties": {"cell_size_m": CELL_M, "name": "off-centre", "alt_m": CMAC[2]},
    }
    scenario = derive(load_geographic(document)).scenario
    the_plan = plan(
        scenario.with_clearance(DEFAULT_CLEARANCE_M), PlannerSettings(time_budget_s=None)
    )
    assert the_plan.feasible
    return scenario, the_plan


def homes_off_centre(
    scenario: Scenario, offsets: dict[str, tuple[float, float]]
) -> list[tuple[float, float, float]]:
    """Each UAV's vehicle standing `offsets` metres (east, north) from its start cell's
    centre, in the scenario's order."""
    frame = GridFrame.of(scenario)
    homes = []
    for uav in scenario.uavs:
        de, dn = offsets[uav.id]
        lat, lon = frame.to_geodetic(uav.start[0] + de / CELL_M, uav.start[1] + dn / CELL_M)
        homes.append((float(lat), float(lon), frame.alt0))
    return homes
