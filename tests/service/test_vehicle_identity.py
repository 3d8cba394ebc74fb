"""One vehicle is one vehicle however it is reached (issue 28): the service in process,
simulated vehicles in memory, on the virtual clock.

Each vehicle is reached here two ways, `tcp:` and `udpout:` on its port (the in-memory
opener connects both to the same vehicle), as SITL is on its own port and on the
listening port behind MAVProxy. Over real sockets and the real listening port:
tests/e2e/test_discovery.py.
"""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from planner.cases import load_case
from sitl_mock import Simulator, VehicleConfig
from tests.impostor import forged
from tests.inprocess.flying import Flight, bind, live, plan_scenario, register
from tests.inprocess.service import InProcessService, until
from tests.inprocess.vehicles import FAST_BOOT

pytestmark = [pytest.mark.virtual_clock]


def _other_way(sim: Simulator, sysid: int) -> str:
    return sim.connection_string(sysid).replace("tcp:", "udpout:")


async def _identified(client: httpx.AsyncClient, connection: str) -> str:
    vehicle_id = await register(client, connection)

    async def said() -> bool:
        return (await live(client, vehicle_id)).get("uid") is not None

    await until(said, 30, f"{connection} says which board it is")
    return vehicle_id


async def test_a_vehicle_registered_again_another_way_is_refused(gcs: InProcessService) -> None:
    client = gcs.client
    sim = await gcs.vehicles.at_starts(load_case("case-1"))
    first = await _identified(client, sim.connection_string(1))
    again = await client.post("/vehicles", json={"connection": _other_way(sim, 1)})
    assert again.status_code == 409, again.text
    detail = again.json()["detail"]
    assert first in detail and (await live(client, first))["uid"] in detail

    # the same system id on another board (a second SITL, also sysid 1) is another vehicle
    twin = await gcs.vehicles.start([VehicleConfig(sysid=1, transport="memory", **FAST_BOOT)])
    other = await _identified(client, twin.connection_string(1))
    assert (await live(client, other))["uid"] != (await live(client, first))["uid"]


async def test_one_vehicle_has_one_owner_under_any_registration(gcs: InProcessService) -> None:
    """Registered twice while it was silent (it could not say which it was), the vehicle
    still belongs to one flight: a second flight through the other registration is
    refused, one flight cannot bind it twice, and a command through the other
    registration goes through the flight that flies it."""
    client = gcs.client
    scenario = load_case("case-1")
    sim = await gcs.vehicles.at_starts(scenario)
    spare = await gcs.vehicles.start([VehicleConfig(sysid=3, transport="memory", **FAST_BOOT)])
    plan = await plan_scenario(client, scenario)
    by_port = await _identified(client, sim.connection_string(1))
    sim.silence(1, 10.0)
    heard = await register(client, _other_way(sim, 1))  # nobody answered: registered
    second = await _identified(client, sim.connection_string(2))
    third = await _identified(client, spare.connection_string(3))

    async def heard_says() -> bool:
        return (await live(client, heard)).get("uid") == (await live(client, by_port))["uid"]

    await until(heard_says, 60, "the second registration says it is the first's board")

    twice = await bind(client, plan["id"], scenario, [by_port, heard])
    refused = await client.post(f"/flights/{twice}/upload")
    assert refused.status_code == 409, refused.text
    assert "one vehicle reached two ways" in refused.json()["detail"]

    flying = await bind(client, plan["id"], scenario, [by_port, second])
    assert (await client.post(f"/flights/{flying}/upload")).status_code == 200
    assert (await client.post(f"/flights/{flying}/start")).status_code == 202
    intruder = await bind(client, plan["id"], scenario, [heard, third])
    refused = await client.post(f"/flights/{intruder}/upload")
    assert refused.status_code == 409, refused.text
    assert flying in refused.json()["detail"] and by_port in refused.json()["detail"]

    held = await client.post(f"/vehicles/{heard}/land")
    assert held.status_code == 200, held.text
    assert held.json()["uav_id"] == "uav1"  # answered as the flight's uav1
    events = (await client.get(f"/flights/{flying}/events", params={"limit": 1000})).json()
    assert any(e["kind"] == "OperatorCommand" and e["uav_id"] == "uav1" for e in events)


async def test_another_address_sending_as_a_flying_vehicle_is_an_event(
    gcs: InProcessService,
) -> None:
    """Issue 28: a second address claiming a known system id is reported in the flight
    that flies it (and ignored), once per address."""
    sim = await gcs.vehicles.at_starts(load_case("case-1"))
    flight = await Flight.make(gcs.client, sim)
    await flight.fly()
    assert gcs.app is not None
    registry = gcs.app.state.services.registry
    link = registry.link(flight.vehicle_ids[0])
    for _ in range(3):
        link.connection._received(forged(link.sysid), ("127.0.0.9", 4444))  # as a socket would

    async def claimed() -> list[dict[str, Any]]:
        return [e for e in await flight.events() if e["kind"] == "AddressClaimed"]

    [event] = await until(claimed, 30, "the claim in the flight's events")
    assert event["uav_id"] == "uav1" and event["data"]["address"] == "127.0.0.9:4444"
    assert sim.state(1).alt > 1.0  # the vehicle flies on, its address unchanged
    assert link.connection.contested[link.sysid].packets == 6  # two packets each time
