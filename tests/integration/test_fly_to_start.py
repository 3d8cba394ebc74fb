"""Vehicles standing inside their start cells but off their planned starts (a geographic
scenario snaps every start to its cell's centre, up to 7.1 m away with 10 m cells): each
takes off where it stands, flies to its start at its altitude, and only then is ready;
the fleet starts together and flies the plan. A vehicle outside its start cell is still
refused before anything arms. On the virtual clock, with in-memory ArduCopters."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from gcs.fleet.events import FleetEvent, VehicleReady
from gcs.fleet.fleet import Fleet, FleetSettings, FlightReport
from gcs.fleet.launch import _segments_gap
from gcs.mavlink.mission_item import Autopilot
from gcs.mission.flight_plan import flight_plan
from gcs.mission.geodesy import GridFrame, distance_m
from planner.model.plan import Plan
from planner.model.scenario import Scenario
from sitl_mock import Simulator
from tests.inprocess.fleet import ALTITUDE_M, GOAL_RADIUS_M, connect_all, goal_misses
from tests.inprocess.vehicles import SimulatedVehicles, configs_at_starts
from tests.off_centre import CELL_M, OFF_CENTRE_M, homes_off_centre, planned

pytestmark = [pytest.mark.virtual_clock]


async def _off_centre(
    vehicles: SimulatedVehicles, scenario: Scenario, offsets: dict[str, tuple[float, float]]
) -> Simulator:
    """The vehicles standing `offsets` metres (east, north) from their start cells' centres."""
    configs = configs_at_starts(scenario)
    for config, home in zip(configs, homes_off_centre(scenario, offsets), strict=True):
        config.home = home
    return await vehicles.start(configs)


async def _fly(
    vehicles: SimulatedVehicles,
    sim: Simulator,
    scenario: Scenario,
    the_plan: Plan,
    settings: FleetSettings,
    on_event: Callable[[FleetEvent], None] | None = None,
) -> FlightReport:
    autopilots = {u.id: Autopilot.ARDUPILOT for u in scenario.uavs}
    flight = flight_plan(the_plan, scenario, autopilots, altitude_m=ALTITUDE_M)
    links = await connect_all(vehicles, sim)
    try:
        by_uav = {u.id: link for u, link in zip(scenario.uavs, links, strict=True)}
        fleet = Fleet(by_uav, flight, settings=settings)
        if on_event is not None:
            fleet.record(on_event)
        return await fleet.fly()
    finally:
        for link in links:
            await link.close()


async def test_vehicles_off_their_cell_centres_fly_to_their_starts_then_the_plan(
    vehicles: SimulatedVehicles,
) -> None:
    scenario, the_plan = planned()
    sim = await _off_centre(vehicles, scenario, OFF_CENTRE_M)
    frame = GridFrame.of(scenario)
    starts = {u.id: tuple(float(v) for v in frame.to_geodetic(*u.start)) for u in scenario.uavs}
    sysid = {u.id: k for k, u in enumerate(scenario.uavs, start=1)}
    for uav, (de, dn) in OFF_CENTRE_M.items():
        here = sim.state(sysid[uav])
        assert 5.0 <= distance_m(here.lat, here.lon, *starts[uav]) <= 6.0
        assert math.isclose(
            distance_m(here.lat, here.lon, *starts[uav]), math.hypot(de, dn), abs_tol=0.05
        )

    ready_at: dict[str, float] = {}

    def on_event(event: FleetEvent) -> None:
        if isinstance(event, VehicleReady):
            state = sim.state(sysid[event.uav_id])
            ready_at[event.uav_id] = distance_m(state.lat, state.lon, *starts[event.uav_id])

    report = await _fly(vehicles, sim, scenario, the_plan, FleetSettings(), on_event)
    assert report.completed, report.failed
    assert set(ready_at) == set(OFF_CENTRE_M) and max(ready_at.values()) <= 0.5, ready_at
    misses = goal_misses(sim, scenario)
    assert max(misses.values()) <= GOAL_RADIUS_M, misses
    separation = sim.min_separation()
    flown = separation.distance_m if separation else math.inf
    two_r = 2 * max(u.radius for u in scenario.uavs) * CELL_M
    assert flown >= two_r, (flown, two_r)
    assert not any(sim.state(k).armed for k in sysid.values())
    print(
        f"\noff-centre starts: ready within {max(ready_at.values()):.2f} m of the starts; "
        f"flown {flown:.2f} m apart at the closest, 2R {two_r:.2f} m, "
        f"goals missed by at most {max(misses.values()):.2f} m"
    )


async def test_a_vehicle_outside_its_start_cell_arms_nobody(vehicles: SimulatedVehicles) -> None:
    scenario, the_plan = planned()
    offsets = {**OFF_CENTRE_M, "uav2": (6.0, 0.0)}  # 6 m east: in the next cell
    sim = await _off_centre(vehicles, scenario, offsets)
    report = await _fly(vehicles, sim, scenario, the_plan, FleetSettings())
    assert not report.completed
    assert "outside its 10 m start cell" in report.failed["uav2"], report.failed
    assert not any(sim.state(k).armed for k in (1, 2, 3))
    assert max(sim.state(k).alt for k in (1, 2, 3)) <= 0.0


def test_moves_are_checked_against_each_other_as_segments() -> None:
    a = np.array
    assert _segments_gap(a([0.0, 0.0]), a([4.0, 0.0]), a([2.0, -1.0]), a([2.0, 1.0])) == 0.0
    assert _segments_gap(a([0.0, 0.0]), a([4.0, 0.0]), a([6.0, 3.0]), a([6.0, 3.0])) == (
        pytest.approx(math.hypot(2.0, 3.0))
    )
    assert _segments_gap(a([0.0, 0.0]), a([4.0, 0.0]), a([1.0, 2.0]), a([3.0, 5.0])) == (
        pytest.approx(2.0)
    )
