"""Inputs that cannot poison a mission, waits that always end, a service that answers only
to its own names (issue 12), over raw sockets and a real `mvo-gcs serve`."""

from __future__ import annotations

import json
import os
import signal
import socket
import stat
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect

from planner.cases import load_case
from tests.service_process import TOKEN, ServiceProcess

CASE_VI = load_case("case-6").model_dump(mode="json")


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServiceProcess]:
    proc = ServiceProcess(
        tmp_path_factory.mktemp("hardening") / "data", {"MVO_GCS_BODY_TIMEOUT_S": "1"}
    )
    proc.start()
    yield proc
    proc.stop()


def raw(service: ServiceProcess, request: bytes, *, pause_after: int | None = None) -> bytes:
    """Send bytes as they are (optionally stopping after `pause_after` of them); the answer."""
    with socket.create_connection(("127.0.0.1", service.port), timeout=30) as sock:
        sock.sendall(request if pause_after is None else request[:pause_after])
        answer = b""
        while b"\r\n\r\n" not in answer or len(answer) < answer.find(b"\r\n\r\n") + 4:
            chunk = sock.recv(65536)
            if not chunk:
                break
            answer += chunk
        return answer


def status(answer: bytes) -> int:
    return int(answer.split(b" ", 2)[1])


# --- a service that answers only to its own names ---------------------------------------


def test_an_unknown_host_is_refused(service: ServiceProcess) -> None:
    evil = httpx.get(f"{service.url}/scenarios", headers={"Host": "rebind.example"})
    assert evil.status_code == 400 and "unknown host" in evil.json()["detail"]
    for host in (f"127.0.0.1:{service.port}", f"localhost:{service.port}"):
        assert httpx.get(f"{service.url}/scenarios", headers={"Host": host}).status_code == 200


def test_a_websocket_from_a_foreign_origin_is_refused(service: ServiceProcess) -> None:
    url = service.url.replace("http", "ws") + "/jobs/nope/live"
    with pytest.raises(InvalidStatus):
        connect(url, origin="http://rebind.example", open_timeout=10)  # type: ignore[arg-type]
    ours = f"http://127.0.0.1:{service.port}"
    socket_ = connect(url, origin=ours, open_timeout=10)  # type: ignore[arg-type]
    with socket_, pytest.raises(ConnectionClosed) as closed:
        socket_.recv(timeout=10)
    assert closed.value.rcvd is not None and closed.value.rcvd.code == 4404  # no such job


# --- the token first, bounded bodies ------------------------------------------------------


def test_the_token_is_checked_before_the_body_is_read(service: ServiceProcess) -> None:
    malformed = httpx.post(f"{service.url}/scenarios", content=b'{"grid": ', timeout=30)
    assert malformed.status_code == 401
    huge = b"[" + b"0," * 600_000 + b"0]"
    assert httpx.post(f"{service.url}/scenarios", content=huge, timeout=30).status_code == 401


def test_an_over_limit_chunked_body_is_413(service: ServiceProcess) -> None:
    chunk = b"0," * 100_000
    body = b"".join(b"%x\r\n%s\r\n" % (len(chunk), chunk) for _ in range(8)) + b"0\r\n\r\n"
    request = (
        b"POST /scenarios HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
        b"Authorization: Bearer " + TOKEN.encode() + b"\r\nTransfer-Encoding: chunked\r\n\r\n"
    )
    assert status(raw(service, request + body)) == 413


def test_a_slow_body_times_out(service: ServiceProcess) -> None:
    request = (
        b"POST /scenarios HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
        b"Authorization: Bearer " + TOKEN.encode() + b"\r\nContent-Length: 1000\r\n\r\n{"
    )
    assert status(raw(service, request)) == 408  # 1 byte of 1000, then nothing


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
def test_numbers_and_strings_that_poison_a_mission_are_422(
    service: ServiceProcess, body: str, where: str
) -> None:
    with service.client() as client:
        answer = client.post(
            "/scenarios", content=body.encode(), headers={"content-type": "application/json"}
        )
    assert answer.status_code == 422, answer.text
    assert where in json.dumps(answer.json()["detail"])


def test_a_plan_without_an_origin_is_not_uploaded(service: ServiceProcess) -> None:
    with service.client() as client:
        sid = client.post("/scenarios", json={**CASE_VI, "origin": None}).json()["id"]
        plan = client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30}).json()
        bindings = {}
        for k, uav in enumerate(CASE_VI["uavs"]):
            connection = f"udpout:127.0.0.1:{29000 + k}"
            bindings[uav["id"]] = client.post("/vehicles", json={"connection": connection}).json()[
                "id"
            ]
        flight = client.post("/flights", json={"plan_id": plan["id"], "bindings": bindings})
        answer = client.post(f"/flights/{flight.json()['id']}/upload")
    assert answer.status_code == 409 and "no origin" in answer.json()["detail"], answer.text


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
def test_connection_strings_that_cannot_work_are_422(
    service: ServiceProcess, connection: str
) -> None:
    with service.client() as client:
        answer = client.post("/vehicles", json={"connection": connection})
    assert answer.status_code == 422, answer.text


def test_lists_are_bounded_and_summarised(service: ServiceProcess) -> None:
    with service.client() as client:
        client.post("/scenarios", json=CASE_VI)
        assert client.get("/scenarios?limit=1000").status_code == 422
        page = client.get("/scenarios?limit=200").json()
    assert page and all("scenario" not in item and "uavs" in item for item in page)


# --- waits that always end ---------------------------------------------------------------


def test_forty_deletes_in_a_row_all_answer(service: ServiceProcess) -> None:
    with service.client() as client:
        for k in range(40):
            vehicle = client.post(
                "/vehicles", json={"connection": f"udpout:127.0.0.1:{30000 + k}"}
            ).json()
            assert client.delete(f"/vehicles/{vehicle['id']}").status_code == 204


def test_sigterm_ends_the_service_within_seconds(tmp_path: Path) -> None:
    proc = ServiceProcess(tmp_path / "data", {"MVO_GCS_TOKEN": ""})  # it makes its own
    proc.start()
    try:
        with proc.client((tmp_path / "data" / "token").read_text().strip()) as client:
            for k in range(5):
                client.post("/vehicles", json={"connection": f"tcp:127.0.0.1:{31000 + k}"})
        data = tmp_path / "data"
        for path in (data, data / "mvo-gcs.db", data / "token"):
            mode = stat.S_IMODE(path.stat().st_mode)
            assert not mode & 0o077, f"{path} is {oct(mode)}: not the owner's only"
        assert proc.process is not None
        proc.process.send_signal(signal.SIGTERM)
        proc.process.wait(timeout=20)  # a bound for a hang, not a measurement
        assert proc.process.returncode is not None
    finally:
        if proc.process is not None and proc.process.poll() is None:
            os.kill(proc.process.pid, signal.SIGKILL)
        proc.process = None
