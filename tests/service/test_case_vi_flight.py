"""Case VI end to end through the service's API and its live WebSocket, flown by simulated
vehicles, in process on one virtual clock: scenario → plan → (service restart) →
vehicles → flight → upload → start → live stream until every vehicle has landed; then
the separation the simulator measured and the stored events."""

from __future__ import annotations

from typing import Any

import pytest
from httpx_ws import AsyncWebSocketSession

from planner.cases import load_case
from tests.inprocess.flying import (
    assert_down_apart_at_the_goals,
    bind,
    register,
    upload_once_online,
)
from tests.inprocess.service import InProcessService

pytestmark = [pytest.mark.virtual_clock]

STREAM_QUIET_S = 120.0
"""Virtual seconds the live stream may stay silent before the test gives up on it."""


async def test_case_vi_is_planned_uploaded_flown_and_recorded(gcs: InProcessService) -> None:
    scenario = load_case("case-6")
    vehicles = await gcs.vehicles.at_starts(scenario)
    client = gcs.client
    sid = (await client.post("/scenarios", json=scenario.model_dump(mode="json"))).json()["id"]
    planned = await client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30})
    assert planned.status_code == 201, planned.text
    plan = planned.json()
    assert plan["plan"]["feasible"]

    await gcs.restart()  # a restart between planning and flying loses nothing
    client = gcs.client
    ids = [await register(client, vehicles.connection_string(k)) for k in vehicles.sysids]
    fid = await bind(client, plan["id"], scenario, ids)

    early = await client.post(f"/flights/{fid}/start")
    assert early.status_code == 409 and "upload" in early.json()["detail"]

    uploaded = await upload_once_online(client, fid)
    assert uploaded["flight"]["state"] == "uploaded", uploaded
    assert all(v["ok"] for v in uploaded["vehicles"])
    for uav in ("uav1", "uav3"):  # the files users download are the missions flown
        for kind in ("plan", "waypoints"):
            flown = await client.get(f"/flights/{fid}/missions/{uav}.{kind}")
            offered = await client.get(f"/plans/{plan['id']}/missions/{uav}.{kind}")
            assert flown.status_code == offered.status_code == 200
            assert flown.text == offered.text, (uav, kind)

    async with gcs.websocket(f"/flights/{fid}/live") as ws:
        started = await client.post(f"/flights/{fid}/start")
        assert started.status_code == 202, started.text
        assert started.json()["state"] == "starting", started.text
        messages = await _read_until_ended(ws)
    kinds = {m["kind"] for m in messages if m["type"] == "event"}
    assert {"ItemReached", "VehicleFinished", "FlightEnded"} <= kinds
    states = [m for m in messages if m["type"] == "state"]
    assert states and states[-1]["state"] == "landed"
    assert all(v["lat"] is not None for v in states[-1]["vehicles"])

    stored = (await client.get(f"/flights/{fid}/events", params={"limit": 10_000})).json()
    stored_kinds = [e["kind"] for e in stored]
    streamed = [
        m["kind"]
        for m in messages
        if m["type"] == "event" and m["kind"] not in ("Progress", "FlightState")
    ]
    for kind in set(streamed):
        assert stored_kinds.count(kind) >= streamed.count(kind), kind
    assert (await client.get(f"/flights/{fid}")).json()["state"] == "landed"

    assert_down_apart_at_the_goals(vehicles, scenario)


async def _read_until_ended(ws: AsyncWebSocketSession) -> list[dict[str, Any]]:
    messages = []
    while True:
        message: dict[str, Any] = await ws.receive_json(timeout=STREAM_QUIET_S)
        messages.append(message)
        if message["type"] == "state" and message["state"] in ("landed", "ended", "aborted"):
            return messages
