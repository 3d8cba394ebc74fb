"""Fleet flights on simulated vehicles: the paper's six cases and a 10-UAV crossing.

The ground station's `Fleet` and the vehicles share the virtual clock (in-memory links,
tests/inprocess/fleet.py), so each plan is flown to the end in simulated time, the same
way for a seed whatever the machine's load. Every vehicle must land within the
acceptance radius of its goal, and the closest approach the SIMULATOR measured over the
whole flight must be at least the plan's 2R.
"""

from __future__ import annotations

import asyncio
import functools
from collections.abc import AsyncIterator
from dataclasses import replace

import pytest

from gcs.fleet.events import (
    Aborted,
    FleetEvent,
    ItemReached,
    LeadTaken,
    StartCancelled,
    Waiting,
)
from gcs.fleet.fleet import Fallback, Fleet, FleetSettings
from gcs.mavlink.actions import ReadinessPolicy
from gcs.mavlink.link import LinkSettings, VehicleLink
from gcs.mavlink.mission_item import Autopilot
from gcs.mission.flight_plan import DEFAULT_CLEARANCE_M, flight_plan
from planner.cases import load_case
from planner.experiments.scenario_generator import crossing_scenario, random_scenario
from planner.model.plan import Plan
from planner.model.scenario import Origin, Scenario
from planner.pipeline import PlannerSettings, plan
from sitl_mock import Faults, Simulator
from sitl_mock.readiness import EKF_S
from tests.inprocess.fleet import GOAL_RADIUS_M, connect_all, fly_plan
from tests.inprocess.service import until
from tests.inprocess.vehicles import SimulatedVehicles, configs_at_starts

from .conftest import CMAC

pytestmark = [pytest.mark.virtual_clock]

CROSSING_SEED = 0


@functools.cache
def planned(name: str) -> tuple[Scenario, Plan]:
    """The plan flown, with the service's default clearance between paths: iterations and
    patience only, no time budget, so that it is the same plan however busy the machine is
    (the budget never ends these plans anyway)."""
    if name == "crossing-10":
        scenario = crossing_scenario(CROSSING_SEED, uavs=10)
        scenario = scenario.model_copy(
            update={"origin": Origin(lat=CMAC[0], lon=CMAC[1], alt_m=CMAC[2])}
        )
        settings = PlannerSettings(iterations=200, time_budget_s=None)
    else:
        scenario = load_case(name)
        settings = PlannerSettings(time_budget_s=None)
    return scenario, plan(scenario.with_clearance(DEFAULT_CLEARANCE_M), settings)


@pytest.fixture
async def opened() -> AsyncIterator[list[VehicleLink]]:
    """Links a test opens; all are closed when it ends."""
    links: list[VehicleLink] = []
    yield links
    for link in links:
        await link.close()


@pytest.mark.slow
@pytest.mark.parametrize("name", [*(f"case-{k}" for k in range(1, 7)), "crossing-10"])
async def test_a_planned_flight_keeps_its_separation(
    vehicles: SimulatedVehicles, name: str
) -> None:
    scenario, the_plan = planned(name)
    assert the_plan.feasible
    sim = await vehicles.at_starts(scenario)
    flown = await fly_plan(vehicles, sim, scenario, the_plan)
    assert flown.report.completed, flown.report.failed
    assert max(flown.goal_misses_m.values()) <= GOAL_RADIUS_M, flown.goal_misses_m
    assert flown.sim_min_separation_m >= flown.two_r_m, (
        f"{name}: flown {flown.sim_min_separation_m:.2f} m < 2R {flown.two_r_m:.2f} m "
        f"(plan {flown.plan_min_separation_m:.2f} m)"
    )
    print(
        f"\n{name}: plan {flown.plan_min_separation_m:.2f} m, 2R {flown.two_r_m:.2f} m, "
        f"flown {flown.sim_min_separation_m:.2f} m (GCS {flown.report.min_separation_m:.2f} m)"
    )


@pytest.mark.slow
async def test_a_vehicle_sent_on_from_its_start_keeps_to_its_approach(
    vehicles: SimulatedVehicles,
) -> None:
    """A random scatter of 8 at 10 m/s, 20 m up (`bench/flight_speed.py`'s random-s1-8):
    uav6 must let uav1 by 7 m from its start, and is sent on from its hover there at 1 m/s.
    From NAV_TAKEOFF its mission ran the DO_CHANGE_SPEED after it and flew on at cruise
    speed: it stopped 1.71 m inside the encounter and took the lead, and uav1 waited out
    its landing (1.22x the timed flight on the mock, 1.24x on SITL). Its first leg made
    current first (`FlightActions.approach`), it waits short of the encounter."""
    scenario = random_scenario(1, size=20, uavs=8, objects=2)
    scenario = scenario.model_copy(
        update={"origin": Origin(lat=CMAC[0], lon=CMAC[1], alt_m=CMAC[2])}
    )
    the_plan = plan(
        scenario.with_clearance(DEFAULT_CLEARANCE_M), PlannerSettings(time_budget_s=None)
    )
    sim = await vehicles.at_starts(scenario)
    events: list[FleetEvent] = []
    flown = await fly_plan(
        vehicles, sim, scenario, the_plan, max_speed_m_s=10.0, altitude_m=20.0,
        record=events.append,
    )  # fmt: skip
    assert flown.report.completed, flown.report.failed
    assert [e for e in events if isinstance(e, LeadTaken)] == []
    approaches = [e for e in events if isinstance(e, Waiting) and e.uav_id == "uav6"]
    assert any(e.how == "creep" for e in approaches), approaches  # the case still arises
    assert flown.sim_min_separation_m >= flown.two_r_m, flown.sim_min_separation_m


async def _fleet(
    vehicles: SimulatedVehicles,
    sim: Simulator,
    opened: list[VehicleLink],
    scenario: Scenario,
    the_plan: Plan,
    settings: FleetSettings,
) -> Fleet:
    """A fleet on `sim`'s vehicles; the `opened` fixture closes the links after the test."""
    autopilots = {u.id: Autopilot.ARDUPILOT for u in scenario.uavs}
    flight = flight_plan(the_plan, scenario, autopilots, altitude_m=10.0)
    links = await connect_all(vehicles, sim, LinkSettings())
    opened.extend(links)
    return Fleet(
        {u.id: link for u, link in zip(scenario.uavs, links, strict=True)},
        flight,
        settings=settings,
    )


async def test_a_rejected_mission_leaves_every_vehicle_on_the_ground(
    vehicles: SimulatedVehicles, opened: list[VehicleLink]
) -> None:
    scenario, the_plan = planned("case-2")
    sim = await vehicles.at_starts(scenario)
    sim.set_faults(2, Faults(reject_missions=True))
    fleet = await _fleet(vehicles, sim, opened, scenario, the_plan, FleetSettings())
    report = await fleet.fly()
    assert not report.completed and "uav2" in report.failed
    assert "refused the upload" in report.failed["uav2"]
    assert not any(sim.state(k).armed for k in (1, 2))


async def test_a_vehicle_failing_before_the_start_starts_nobody(
    vehicles: SimulatedVehicles, opened: list[VehicleLink]
) -> None:
    scenario, the_plan = planned("case-2")
    configs = configs_at_starts(scenario)
    configs[0] = replace(configs[0], estimate_delay_s=1.0, position_delay_s=0.5)  # ready soon
    configs[1] = replace(configs[1], estimate_delay_s=10_000.0)  # never ready to arm
    sim = await vehicles.start(configs)
    settings = FleetSettings(
        fallback=Fallback.LAND, readiness=ReadinessPolicy(arm_timeout_s=1.0, arm_retry_period_s=0.1)
    )
    fleet = await _fleet(vehicles, sim, opened, scenario, the_plan, settings)
    # Booted far enough that what stops uav2 is the position estimate it never gets (its
    # arming checks ask for an altitude estimate until its EKF starts).
    await until(lambda: sim.sim_time > EKF_S, 30, "the vehicles' EKF started")
    events: list[FleetEvent] = []
    listener = asyncio.ensure_future(_collect(fleet, events))
    report = await fleet.fly()
    await asyncio.wait_for(listener, 2.0)
    assert not report.completed and "need position estimate" in report.failed["uav2"].lower()
    assert any(isinstance(e, StartCancelled) and e.failed == ("uav2",) for e in events)
    assert all(sim.state(k).mission_state != 3 for k in (1, 2))  # no mission active
    await until(lambda: not sim.state(1).armed, 30, "uav1 landed")


async def test_abort_brings_every_vehicle_down(
    vehicles: SimulatedVehicles, opened: list[VehicleLink]
) -> None:
    scenario, the_plan = planned("case-1")
    sim = await vehicles.at_starts(scenario)
    fleet = await _fleet(vehicles, sim, opened, scenario, the_plan, FleetSettings())
    for step in (fleet.upload, fleet.prepare, fleet.start):
        assert all(o.ok for o in (await step()).values())
    events: list[FleetEvent] = []
    listener = asyncio.ensure_future(_collect(fleet, events))
    following = asyncio.ensure_future(fleet.follow())
    await until(
        lambda: any(isinstance(e, ItemReached) for e in events), 120, "an item reached", 0.02
    )
    outcomes = await fleet.abort("land", "test")
    report = await following
    fleet.close()
    await asyncio.wait_for(listener, 2.0)
    assert all(o.ok for o in outcomes.values())
    assert not report.completed
    assert any(isinstance(e, Aborted) for e in events)
    assert {sim.state(k).mode for k in (1, 2)} == {"LAND"}


async def _collect(fleet: Fleet, into: list[FleetEvent]) -> None:
    async for event in fleet.events():
        into.append(event)


async def test_a_vehicle_away_from_its_start_starts_nobody(
    vehicles: SimulatedVehicles, opened: list[VehicleLink]
) -> None:
    scenario, the_plan = planned("case-1")
    configs = configs_at_starts(scenario)
    lat, lon, alt = configs[0].home
    configs[0] = replace(configs[0], home=(lat + 1e-4, lon, alt))  # 11 m north of its start
    sim = await vehicles.start(configs)
    fleet = await _fleet(
        vehicles, sim, opened, scenario, the_plan, FleetSettings(fallback=Fallback.HOLD)
    )
    report = await fleet.fly()
    assert not report.completed and "from its start" in report.failed["uav1"]
    assert not any(sim.state(k).armed for k in (1, 2))


async def test_a_start_cancelled_while_a_vehicle_does_not_answer_asks_it_no_more(
    vehicles: SimulatedVehicles, opened: list[VehicleLink]
) -> None:
    """The start asks a silent vehicle for AUTO again and again while the order is kept for
    the others (`Follower.starting`); cancelled (the operator's hold during the start), it
    stops asking at once: the vehicle, heard again, hovers on in GUIDED."""
    scenario, the_plan = planned("case-1")
    sim = await vehicles.at_starts(scenario)
    fleet = await _fleet(vehicles, sim, opened, scenario, the_plan, FleetSettings())
    for step in (fleet.upload, fleet.prepare):
        assert all(o.ok for o in (await step()).values())
    sim.silence(2, 1.0)
    starting = asyncio.ensure_future(fleet.start())
    await asyncio.sleep(0.5)
    starting.cancel()
    with pytest.raises(asyncio.CancelledError):
        await starting
    await asyncio.sleep(5.0)  # the silence over, and the start's 3.2 s of asking with it
    assert sim.state(1).mode == "AUTO"
    assert sim.state(2).mode == "GUIDED" and sim.state(2).armed
