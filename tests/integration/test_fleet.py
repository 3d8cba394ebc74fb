"""Fleet flights on simulated vehicles: the paper's six cases and a 10-UAV crossing.

Each plan is flown to the end at 20x; every vehicle must land within the acceptance
radius of its goal, and the closest approach the SIMULATOR measured over the whole
flight must be at least the plan's 2R.
"""

from __future__ import annotations

import asyncio
import functools

import pytest

from gcs.fleet.events import Aborted, ItemReached, StartCancelled
from gcs.fleet.fleet import Fallback, Fleet, FleetSettings
from gcs.mavlink.actions import ReadinessPolicy
from gcs.mavlink.link import LinkSettings
from gcs.mavlink.mission_item import Autopilot
from gcs.mission.build import build_missions
from planner.cases import load_case
from planner.experiments.scenario_generator import crossing_scenario
from planner.pipeline import PlannerSettings, plan
from planner.plan import Plan
from planner.scenario import Origin, Scenario
from sitl_mock import Faults

from .conftest import CMAC
from .flights import GOAL_RADIUS_M, fly_plan, vehicles_at_starts

SPEEDUP = 20.0  # the floor the issue sets; more turns wall-clock jitter into sim seconds
CROSSING_SEED = 0


@functools.cache
def planned(name: str) -> tuple[Scenario, Plan]:
    if name == "crossing-10":
        scenario = crossing_scenario(CROSSING_SEED, uavs=10)
        scenario = scenario.model_copy(
            update={"origin": Origin(lat=CMAC[0], lon=CMAC[1], alt_m=CMAC[2])}
        )
        return scenario, plan(scenario, PlannerSettings(iterations=200))
    scenario = load_case(name)
    return scenario, plan(scenario, PlannerSettings())


@pytest.mark.slow
@pytest.mark.parametrize("name", [*(f"case-{k}" for k in range(1, 7)), "crossing-10"])
async def test_a_planned_flight_keeps_its_separation(simulator, name: str) -> None:
    scenario, the_plan = planned(name)
    assert the_plan.feasible
    sim = simulator(vehicles_at_starts(scenario), speedup=SPEEDUP)
    flown = await fly_plan(sim, scenario, the_plan)
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


async def _fleet(sim, links, scenario: Scenario, the_plan: Plan, settings: FleetSettings) -> Fleet:
    """A fleet on `sim`'s vehicles; the `links` fixture closes the links after the test."""
    missions = build_missions(the_plan, scenario, Autopilot.ARDUPILOT, altitude_m=10.0)
    connect = [links(sim, k, settings=LinkSettings()) for k in range(1, len(scenario.uavs) + 1)]
    links = await asyncio.gather(*connect)
    return Fleet(
        {u.id: link for u, link in zip(scenario.uavs, links, strict=True)},
        missions,
        settings=settings,
    )


async def test_a_rejected_mission_leaves_every_vehicle_on_the_ground(simulator, links) -> None:
    scenario, the_plan = planned("case-2")
    sim = simulator(vehicles_at_starts(scenario), speedup=SPEEDUP)
    sim.set_faults(2, Faults(reject_missions=True))
    fleet = await _fleet(sim, links, scenario, the_plan, FleetSettings())
    report = await fleet.fly()
    assert not report.completed and "uav2" in report.failed
    assert "refused the upload" in report.failed["uav2"]
    assert not any(sim.state(k).armed for k in (1, 2))


async def test_a_vehicle_failing_before_the_start_starts_nobody(simulator, links) -> None:
    scenario, the_plan = planned("case-2")
    configs = vehicles_at_starts(scenario)
    from dataclasses import replace

    configs[0] = replace(configs[0], estimate_delay_s=1.0, position_delay_s=0.5)  # ready soon
    configs[1] = replace(configs[1], estimate_delay_s=10_000.0)  # never ready to arm
    sim = simulator(configs, speedup=SPEEDUP)
    settings = FleetSettings(
        fallback=Fallback.LAND, readiness=ReadinessPolicy(arm_timeout_s=1.0, arm_retry_period_s=0.1)
    )
    fleet = await _fleet(sim, links, scenario, the_plan, settings)
    events = []
    listener = asyncio.create_task(_collect(fleet, events))
    report = await fleet.fly()
    await asyncio.wait_for(listener, 2.0)
    assert not report.completed and "need position estimate" in report.failed["uav2"].lower()
    assert any(isinstance(e, StartCancelled) and e.failed == ("uav2",) for e in events)
    assert all(sim.state(k).mission_state != 3 for k in (1, 2))  # no mission active
    assert sim.wait_until(lambda: not sim.state(1).armed, timeout=30.0)  # uav1 landed


async def test_abort_brings_every_vehicle_down(simulator, links) -> None:
    scenario, the_plan = planned("case-1")
    sim = simulator(vehicles_at_starts(scenario), speedup=SPEEDUP)
    fleet = await _fleet(sim, links, scenario, the_plan, FleetSettings())
    for step in (fleet.upload, fleet.prepare, fleet.start):
        assert all(o.ok for o in (await step()).values())
    events = []
    listener = asyncio.create_task(_collect(fleet, events))
    following = asyncio.create_task(fleet.follow())
    while not any(isinstance(e, ItemReached) for e in events):
        await asyncio.sleep(0.02)
    outcomes = await fleet.abort("land", "test")
    report = await following
    fleet.close()
    await asyncio.wait_for(listener, 2.0)
    assert all(o.ok for o in outcomes.values())
    assert not report.completed
    assert any(isinstance(e, Aborted) for e in events)
    assert {sim.state(k).mode for k in (1, 2)} == {"LAND"}


async def _collect(fleet: Fleet, into: list) -> None:
    async for event in fleet.events():
        into.append(event)


async def test_a_vehicle_away_from_its_start_starts_nobody(simulator, links) -> None:
    scenario, the_plan = planned("case-1")
    configs = vehicles_at_starts(scenario)
    lat, lon, alt = configs[0].home
    from dataclasses import replace

    configs[0] = replace(configs[0], home=(lat + 1e-4, lon, alt))  # 11 m north of its start
    sim = simulator(configs, speedup=SPEEDUP)
    fleet = await _fleet(sim, links, scenario, the_plan, FleetSettings(fallback=Fallback.HOLD))
    report = await fleet.fly()
    assert not report.completed and "from its start" in report.failed["uav1"]
    assert not any(sim.state(k).armed for k in (1, 2))
