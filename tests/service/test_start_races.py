"""A hold or an abort on the heels of a start (issue 28, critical): the start stops first
and really stops, and the flight stays open, owning its vehicles, for as long as anything
it sent may still arm one.

Before the fix, a hold or abort that reached the service between the start's state change
and its runner closed the flight as "all on the ground", and the runner, started a moment
later, armed the vehicles and took them to 20 m with no flight owning them (on the virtual
clock, with storage taking 2 ms a call: a hold 0 or 2 ms after the start, an abort 2 ms
after it, failed on the old code every time).
"""

from __future__ import annotations

import asyncio

import httpx
import pytest

from gcs.service.states import OPEN, FlightState
from planner.cases import load_case
from tests.inprocess.flying import Flight
from tests.inprocess.service import InProcessService

pytestmark = pytest.mark.virtual_clock

WATCH_S = 40.0  # virtual seconds: long enough for a start that went ahead to climb


async def _command_after(flight: Flight, delay: float, action: str) -> httpx.Response:
    await asyncio.sleep(delay)
    body = {"mode": "land"} if action == "abort" else {}
    return await flight.post(action, **body)


@pytest.mark.parametrize("action", ["pause", "abort"])
@pytest.mark.parametrize("delay", [0.0, 0.002, 0.01])  # 0 and 2 ms failed before the fix
async def test_a_command_right_after_start_stops_the_start_and_keeps_the_vehicles(
    gcs: InProcessService, action: str, delay: float
) -> None:
    sim = await gcs.vehicles.at_starts(load_case("case-1"))
    flight = await Flight.make(gcs.client, sim)
    await flight.upload()
    start, command = await asyncio.gather(
        flight.post("start"), _command_after(flight, delay, action)
    )
    assert start.status_code in (202, 409), start.text
    assert command.status_code == 200, command.text

    loop = asyncio.get_running_loop()
    until_t = loop.time() + WATCH_S
    while loop.time() < until_t:  # at every moment: a vehicle that is up has an owner
        state = FlightState(await flight.state())
        up = [k for k in sim.sysids if sim.state(k).armed or sim.state(k).alt > 0.5]
        assert not up or state in OPEN, (
            f"vehicles {up} armed or in the air while flight {flight.id} is {state.value}"
        )
        await asyncio.sleep(0.1)
    final = await flight.wait_state("ended", "aborted", timeout=120)
    assert all(not sim.state(k).armed and sim.state(k).alt < 0.5 for k in sim.sysids)
    assert final in ("ended", "aborted")


async def test_a_start_never_begins_after_an_abort_has_begun(gcs: InProcessService) -> None:
    """An abort sent with a start: whichever comes first, the flight ends aborted and
    nothing stays armed."""
    sim = await gcs.vehicles.at_starts(load_case("case-1"))
    flight = await Flight.make(gcs.client, sim)
    await flight.upload()
    abort, start = await asyncio.gather(flight.post("abort", mode="land"), flight.post("start"))
    assert abort.status_code == 200, abort.text
    assert start.status_code in (202, 409), start.text
    assert await flight.wait_state("aborted", timeout=120) == "aborted"
    assert all(not sim.state(k).armed for k in sim.sysids)
