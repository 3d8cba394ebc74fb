"""Inputs that cannot poison a mission, waits that always end, the token before the body
(issue 12), a vehicle whose packets are refused for their signature (issue 28), in
process on the virtual clock. What needs the wire (the Host header and a
WebSocket's Origin as uvicorn hands them over, chunked and slow bodies, SIGTERM) is in
tests/e2e/test_hardening.py."""

from __future__ import annotations

import json
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from gcs.mavlink.endpoint import Endpoint
from gcs.mavlink.transport import ByteTransport, MemoryTransport
from planner.cases import load_case
from sitl_mock import VehicleConfig
from tests.inprocess.service import InProcessService, until
from tests.inprocess.vehicles import FAST_BOOT, SimulatedVehicles

pytestmark = [pytest.mark.virtual_clock]

CASE_VI = load_case("case-6").model_dump(mode="json")


class SilentVehicles(SimulatedVehicles):
    """Every connection string opens a link to nothing that ever answers, as a UDP port
    with no vehicle behind it: the service's connect waits for a HEARTBEAT that never
    comes."""

    def __init__(self) -> None:
        super().__init__()
        self.opened = 0

    async def open(self, endpoint: Endpoint) -> ByteTransport:
        self.opened += 1
        near, _ = MemoryTransport.pair()
        return near


@pytest.fixture
async def silent(tmp_path: Path) -> AsyncIterator[tuple[InProcessService, SilentVehicles]]:
    nobody = SilentVehicles()
    service = InProcessService(tmp_path / "data", nobody)
    await service.start()
    yield service, nobody
    await service.stop()


# --- the token first -----------------------------------------------------------------------


async def test_the_token_is_checked_before_the_body_is_read(gcs: InProcessService) -> None:
    async with gcs.anonymous() as anonymous:
        malformed = await anonymous.post("/scenarios", content=b'{"grid": ')
        assert malformed.status_code == 401
        huge = b"[" + b"0," * 600_000 + b"0]"
        assert (await anonymous.post("/scenarios", content=huge)).status_code == 401


# --- inputs that cannot poison a mission -------------------------------------------------


@pytest.mark.parametrize(
    ("body", "where"),
    [
        (json.dumps({**CASE_VI, "origin": {**CASE_VI["origin"], "alt_m": float("nan")}}), "body"),
        (json.dumps({**CASE_VI, "origin": {**CASE_VI["origin"], "lat": float("inf")}}), "body"),
        (json.dumps({**CASE_VI, "origin": {**CASE_VI["origin"], "alt_m": 1e308}}), "alt_m"),
        (json.dumps({**CASE_VI, "origin": {**CASE_VI["origin"], "lon": -1e7}}), "lon"),
        (json.dumps({**CASE_VI, "name": "\ud800"}), "name"),
    ],
    ids=["nan", "infinity", "1e308", "lon -1e7", "lone surrogate"],
)
async def test_numbers_and_strings_that_poison_a_mission_are_422(
    gcs: InProcessService, body: str, where: str
) -> None:
    answer = await gcs.client.post(
        "/scenarios", content=body.encode(), headers={"content-type": "application/json"}
    )
    assert answer.status_code == 422, answer.text
    assert where in json.dumps(answer.json()["detail"])


async def test_a_plan_without_an_origin_makes_no_flight(gcs: InProcessService) -> None:
    client = gcs.client
    sid = (await client.post("/scenarios", json={**CASE_VI, "origin": None})).json()["id"]
    planned = await client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30})
    assert planned.status_code == 201, planned.text
    bindings = {}
    for k, uav in enumerate(CASE_VI["uavs"]):
        connection = f"udpout:127.0.0.1:{29000 + k}"
        registered = await client.post("/vehicles", json={"connection": connection})
        bindings[uav["id"]] = registered.json()["id"]
    answer = await client.post(
        "/flights", json={"plan_id": planned.json()["id"], "bindings": bindings}
    )  # refused when made, not only at the upload (issue 28)
    assert answer.status_code == 409 and "no origin" in answer.json()["detail"], answer.text
    assert (await client.get("/flights")).json() == []


@pytest.mark.parametrize(
    "connection",
    [
        "udpout:127.0.0.1:0",
        "udpout:127.0.0.1:65536",
        "udpout:127.0.0.1:١٤٥٦٠",
        "udpout:::1:14560",
        "udpin:0.0.0.0:14600",
        "tcp:999.1.1.1:5760",
    ],
)
async def test_connection_strings_that_cannot_work_are_422(
    gcs: InProcessService, connection: str
) -> None:
    answer = await gcs.client.post("/vehicles", json={"connection": connection})
    assert answer.status_code == 422, answer.text


async def test_lists_are_bounded_and_summarised(gcs: InProcessService) -> None:
    client = gcs.client
    assert (await client.post("/scenarios", json=CASE_VI)).status_code == 201
    assert (await client.get("/scenarios?limit=1000")).status_code == 422
    page = (await client.get("/scenarios?limit=200")).json()
    assert page and all("scenario" not in item and "uavs" in item for item in page)


# --- waits that always end ---------------------------------------------------------------


async def test_forty_deletes_in_a_row_all_answer(
    silent: tuple[InProcessService, SilentVehicles],
) -> None:
    """Each vehicle is deleted while the service is still connecting to it (waiting for a
    first HEARTBEAT from a link where nothing answers): every delete answers."""
    gcs, nobody = silent
    client = gcs.client
    for k in range(40):
        registered = await client.post(
            "/vehicles", json={"connection": f"udpout:127.0.0.1:{30000 + k}"}
        )
        assert registered.status_code == 201, registered.text

        def connecting(k: int = k) -> bool:
            return nobody.opened > k

        await until(connecting, 5, f"vehicle {k}'s link connecting")
        assert (await client.delete(f"/vehicles/{registered.json()['id']}")).status_code == 204


# --- a vehicle whose packets are refused (issue 28) ------------------------------------------


async def test_a_vehicle_refused_for_its_signature_is_reported_with_the_reason(
    gcs: InProcessService,
) -> None:
    """Issue 28: a vehicle whose packets were all refused for their signature was shown
    only as "no HEARTBEAT". Registered with a key other than the vehicle's, the service
    says that packets were refused, and why. (The signature check is the link's, whatever
    carries its bytes: in memory here, on the virtual clock, where the wait for a
    HEARTBEAT that never passes costs no wall time.)"""
    config = VehicleConfig(sysid=1, transport="memory", signing_key=bytes(range(32)), **FAST_BOOT)
    sim = await gcs.vehicles.start([config])
    client = gcs.client
    body = {"connection": sim.connection_string(1), "signing_key": "not its key"}
    answer = await client.post("/vehicles", json=body)
    assert answer.status_code == 201, answer.text
    vid = answer.json()["id"]

    async def reason() -> str:
        live = (await client.get(f"/vehicles/{vid}")).json()["live"]
        error = str(live.get("error", ""))
        return error if "signature" in error else ""

    error = await until(reason, 60, "the reason the vehicle is not heard")
    assert "refused for their signature" in error and "another key" in error, error
