"""An interrupted flight followed again (issue 25's adoption): the service stopped or
died mid-flight, and the operator resumes the flight from where its vehicles are. The
service in process, vehicles in memory, one virtual clock."""

from __future__ import annotations

from typing import Any

import pytest

from gcs.mavlink import client as mavlink_client
from gcs.mavlink.mission_item import Mission
from gcs.mavlink.mission_protocol import MissionClient
from planner.cases import load_case
from sitl_mock import Simulator
from tests.inprocess.flying import Flight, assert_down_apart_at_the_goals, ground_speed, online
from tests.inprocess.service import InProcessService, until

pytestmark = [pytest.mark.virtual_clock, pytest.mark.slow]


async def _interrupted(gcs: InProcessService, case: str) -> tuple[Simulator, Flight]:
    """A flight of `case` stopped mid-cruise by a service that stops (which holds every
    vehicle in the air) and comes back: `interrupted`, its vehicles held in the air."""
    sim = await gcs.vehicles.at_starts(load_case(case))
    flight = await Flight.make(gcs.client, sim, case)
    await flight.fly()
    await until(lambda: all(ground_speed(sim, k) > 2.0 for k in sim.sysids), 60, "cruise")
    await gcs.stop()
    await gcs.start()
    flight.client = gcs.client
    assert await flight.state() == "interrupted"
    await until(flight.online, 30, "every vehicle online again")
    return sim, flight


@pytest.mark.parametrize("case", ["case-1", "case-6"])
async def test_a_resumed_flight_is_flown_to_its_goals_in_the_passing_order(
    gcs: InProcessService, case: str
) -> None:
    sim, flight = await _interrupted(gcs, case)
    answer = await flight.post("resume")
    assert answer.status_code == 200, answer.text
    body: dict[str, Any] = answer.json()
    assert body["flight"]["state"] == "flying", body
    assert all(v["ok"] for v in body["vehicles"]), body
    assert await flight.wait_state("landed", "ended", "interrupted", "aborted") == "landed"
    assert_down_apart_at_the_goals(sim, flight.scenario)
    kinds = [e["kind"] for e in await flight.events()]
    assert "VehicleFinished" in kinds and "FlightEnded" in kinds


async def test_only_an_interrupted_flight_resumes(gcs: InProcessService) -> None:
    sim = await gcs.vehicles.at_starts(load_case("case-1"))
    flight = await Flight.make(gcs.client, sim)
    refused = await flight.post("resume")
    assert refused.status_code == 409 and "only an interrupted flight" in refused.text
    assert (await gcs.client.post("/flights/nope/resume")).status_code == 404


async def test_a_flight_held_during_its_start_is_not_resumed(gcs: InProcessService) -> None:
    """Its vehicles are up but never started their missions together: a resume would
    start them one by one, so it is refused (found by the fuzzer: it was a 500)."""
    sim = await gcs.vehicles.at_starts(load_case("case-1"))
    flight = await Flight.make(gcs.client, sim)
    await flight.upload()
    assert (await flight.post("start")).status_code == 202
    await until(lambda: all(sim.state(k).alt > 2.0 for k in sim.sysids), 120, "all up")
    assert await flight.state() == "starting"
    assert (await flight.post("pause")).status_code == 200
    assert await flight.state() == "interrupted"
    refused = await flight.post("resume")
    assert refused.status_code == 409 and "has not started its mission" in refused.text, (
        refused.text
    )
    assert (await flight.post("abort", mode="land")).status_code == 200
    await flight.wait_state("aborted")


async def test_a_flight_with_a_vehicle_not_heard_stays_interrupted(
    gcs: InProcessService,
) -> None:
    sim, flight = await _interrupted(gcs, "case-1")
    sim.silence(2, seconds=30.0)
    await until(lambda: _offline(flight, 1), 30, "uav2's link lost")
    refused = await flight.post("resume")
    assert refused.status_code == 409 and "offline" in refused.text, refused.text
    assert await flight.state() == "interrupted"
    assert (await flight.post("abort", mode="land")).status_code == 200
    await flight.wait_state("aborted")


async def test_a_vehicle_holding_another_mission_is_not_resumed(gcs: InProcessService) -> None:
    """Nothing is uploaded by a resume: a vehicle whose mission is not this flight's any
    more (changed by another ground station meanwhile) refuses the whole resume."""
    sim, flight = await _interrupted(gcs, "case-1")
    link = await mavlink_client.connect(sim.connection_string(1), opener=gcs.vehicles.open)
    try:
        mission = await MissionClient(link).download()
        await MissionClient(link).upload(Mission(mission[:-1]))  # without its last item
    finally:
        await link.close()
    refused = await flight.post("resume")
    assert refused.status_code == 409 and "another mission" in refused.text, refused.text
    assert await flight.state() == "interrupted"
    assert (await flight.post("abort", mode="land")).status_code == 200
    await flight.wait_state("aborted")


async def _offline(flight: Flight, index: int) -> bool:
    return not await online(flight.client, flight.vehicle_ids[index])
