"""What clients read is typed in the OpenAPI document (issue 24, "typed edges"): vehicles'
live state, stored events and their kinds, a flight's live state with each vehicle's
progress; and the typed answers are the JSON the service sent before they were typed."""

from __future__ import annotations

import dataclasses
import json
from typing import Any, cast

import pytest

from gcs.fleet.events import EventKind
from gcs.fleet.route_tracker import VehicleProgress
from gcs.service.api.deps import Services
from gcs.service.api.routers.flights import FlightLiveState
from gcs.service.api.schemas import LIVE
from planner.cases import load_case
from tests.inprocess.flying import Flight
from tests.inprocess.service import InProcessService

pytestmark = [pytest.mark.virtual_clock]

LIVE_FIELDS = [
    "online", "stale", "sysid", "uid", "autopilot", "mode", "armed", "airborne",
    "system_status", "lat", "lon", "relative_alt_m", "groundspeed_m_s", "heading_deg",
    "mission_seq", "mission_total", "mission_state", "ignored_packets", "claimed_from",
    "seconds_since_heard",
]  # fmt: skip


def _ref(schema: dict[str, Any]) -> str:
    return str(schema["$ref"]).rsplit("/", 1)[-1]


def _refs(schema: dict[str, Any]) -> set[str]:
    return {_ref(s) for s in schema.get("anyOf", [schema]) if "$ref" in s}


async def test_the_openapi_document_types_what_clients_read(gcs: InProcessService) -> None:
    document = (await gcs.client.get("/openapi.json")).json()
    schemas = document["components"]["schemas"]

    assert schemas["EventKind"]["enum"] == [k.value for k in EventKind]
    event = schemas["EventOut"]["properties"]
    assert _refs(event["kind"]) == {"EventKind"}  # or any string: a newer service's kind
    assert {"id", "uav_id", "data", "created_at"} <= set(event)

    assert list(schemas["VehicleLive"]["properties"]) == LIVE_FIELDS
    assert set(schemas["VehicleUnheard"]["properties"]) == {"online", "error"}
    assert _refs(schemas["VehicleOut"]["properties"]["live"]) == {"VehicleLive", "VehicleUnheard"}
    assert _refs(schemas["DiscoveredOut"]["properties"]["live"]) == {"VehicleLive"}

    live_state = document["paths"]["/flights/{flight_id}/live-state"]["get"]
    answer = live_state["responses"]["200"]["content"]["application/json"]["schema"]
    assert _ref(answer) == "FlightLiveState"
    state = schemas["FlightLiveState"]["properties"]
    assert list(state) == [
        "type",
        "flight_id",
        "state",
        "pace_factor",
        "min_separation_m",
        "vehicles",
    ]
    assert _refs(state["vehicles"]["items"]) == {"FlightVehicleLive", "FlightVehicleUnheard"}
    vehicle = schemas["FlightVehicleLive"]["properties"]
    assert list(vehicle) == ["uav_id", "vehicle_id", *LIVE_FIELDS, "progress"]
    assert _refs(vehicle["progress"]) == {"VehicleProgress"}
    progress = schemas["VehicleProgress"]["properties"]
    assert list(progress) == [f.name for f in dataclasses.fields(VehicleProgress)]
    assert {"waits_for", "paused", "held", "along_m", "lag_s"} <= set(progress)


def _same_json(typed: Any, sent: Any) -> None:
    """Byte for byte: the same keys in the same order, the same numbers (an int stays one)."""
    assert json.dumps(typed) == json.dumps(sent)


async def test_typed_answers_are_the_json_the_service_sends(gcs: InProcessService) -> None:
    client = gcs.client
    assert gcs.app is not None
    services: Services = gcs.app.state.services
    sim = await gcs.vehicles.at_starts(load_case("case-1"))
    flight = await Flight.make(client, sim)

    registered = (await client.get(f"/vehicles/{flight.vehicle_ids[0]}")).json()["live"]
    assert set(registered) == set(LIVE_FIELDS) or set(registered) == {"online", "error"}
    unheard = {"online": False, "error": "not connected yet"}
    _same_json(LIVE.dump_python(LIVE.validate_python(unheard), mode="json"), unheard)

    before = (await client.get(f"/flights/{flight.id}/live-state")).json()
    assert all("progress" not in v for v in before["vehicles"])  # absent, not null

    await flight.upload()
    for vehicle_id in flight.vehicle_ids:
        raw = json.loads(json.dumps(services.registry.state(vehicle_id)))
        _same_json(LIVE.dump_python(LIVE.validate_python(raw), mode="json"), raw)
        assert list((await client.get(f"/vehicles/{vehicle_id}")).json()["live"]) == LIVE_FIELDS

    states: list[dict[str, Any]] = []
    async with gcs.websocket(f"/flights/{flight.id}/live") as ws:
        assert (await flight.post("start")).status_code == 202
        while len(states) < 40:  # the stream sends them as the service made them: untyped
            message = await ws.receive_json()
            if message["type"] == "state":
                states.append(message)
        rest = (await client.get(f"/flights/{flight.id}/live-state")).json()
    assert any("progress" in v for v in states[-1]["vehicles"])
    for message in [*states, before, rest]:
        typed = FlightLiveState.model_validate(message)
        _same_json(typed.model_dump(mode="json", exclude_unset=True), message)
    assert list(rest) == list(states[-1])
    assert [list(v) for v in rest["vehicles"]] == [list(v) for v in states[-1]["vehicles"]]

    stored = await flight.events()
    assert stored and {e["kind"] for e in stored} <= set(EventKind)
    assert all(e["data"]["kind"] == e["kind"] for e in stored)


async def test_a_kind_this_version_does_not_know_is_served_as_it_is(
    gcs: InProcessService,
) -> None:
    """Two services of different versions on one database: the older one reads back the
    newer one's events (never a 500 for a kind it has not heard of)."""
    assert gcs.app is not None
    services: Services = gcs.app.state.services
    sim = await gcs.vehicles.at_starts(load_case("case-1"))
    flight = await Flight.make(gcs.client, sim)
    newer = cast(EventKind, "SomethingNewer")
    services.events.record(flight.id, newer, {"type": "event", "kind": newer}, "uav1")
    await services.events.flush()

    answer = await gcs.client.get(f"/flights/{flight.id}/events")
    assert answer.status_code == 200, answer.text
    assert [e["kind"] for e in answer.json()][-1] == "SomethingNewer"
