"""Hardening (issue 12) where the wire is the point, over raw sockets and a real
`mvo-gcs serve`: a service that answers only to its own names (the Host header and a
WebSocket handshake's Origin as uvicorn hands them over), bodies that arrive chunked or
too slowly, and SIGTERM. The rest of issue 12 (inputs that cannot poison a mission,
waits that always end, the token before the body) runs in process, on the virtual
clock, in tests/service/test_hardening.py."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect
from websockets.typing import Origin

from tests.e2e.flying import wait_for
from tests.service_process import TOKEN, ServiceProcess


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
    for name in ("rebind.example", "[::1]evil.example", "127.0.0.1@evil.example", "[::1"):
        evil = httpx.get(f"{service.url}/scenarios", headers={"Host": name})
        assert evil.status_code == 400 and "unknown host" in evil.json()["detail"], name
    for host in (f"127.0.0.1:{service.port}", f"localhost:{service.port}"):
        assert httpx.get(f"{service.url}/scenarios", headers={"Host": host}).status_code == 200


def test_a_websocket_from_a_foreign_origin_is_refused(service: ServiceProcess) -> None:
    url = service.url.replace("http", "ws") + "/jobs/nope/live"
    for foreign in ("http://rebind.example", "http://127.0.0.1:9999", "file://"):
        with pytest.raises(InvalidStatus):  # another site, another local web app, a file
            connect(url, origin=Origin(foreign), open_timeout=10)
    ours = f"http://127.0.0.1:{service.port}"
    socket_ = connect(url, origin=Origin(ours), open_timeout=10)
    with socket_, pytest.raises(ConnectionClosed) as closed:
        socket_.recv(timeout=10)
    assert closed.value.rcvd is not None and closed.value.rcvd.code == 4404  # no such job


def test_no_page_of_the_service_can_be_framed(service: ServiceProcess) -> None:
    """Clickjacking: the API docs had no frame protection, and the console's CSP let the
    page open WebSockets to any host."""
    for path in ("/docs", "/", "/health/live", "/openapi.json"):
        answer = httpx.get(f"{service.url}{path}")
        assert answer.headers["x-frame-options"] == "DENY", path
        assert "frame-ancestors 'none'" in answer.headers["content-security-policy"], path
    console = httpx.get(f"{service.url}/").headers["content-security-policy"]
    assert "connect-src 'self';" in console and "ws:" not in console


def test_a_wrong_method_names_the_right_ones(service: ServiceProcess) -> None:
    auth = {"Authorization": f"Bearer {TOKEN}"}
    for method, path, allowed in [
        ("PUT", "/scenarios", "GET, POST"),
        ("POST", "/health/live", "GET"),
        ("POST", "/console/index.html", "GET, HEAD"),
    ]:
        answer = httpx.request(method, f"{service.url}{path}", headers=auth)
        assert answer.status_code == 405, (method, path)
        assert answer.headers["allow"] == allowed, (method, path)


# --- bounded bodies, as they come over the wire ---------------------------------------


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


# --- bodies an unauthenticated or careless client can send (issue 28) --------------------

CASE = {
    "name": "two",
    "grid": {"width": 6, "height": 6},
    "uavs": [{"id": "uav1", "start": [0, 0], "goal": [5, 5]}],
}


def post_scenario(service: ServiceProcess, body: bytes | dict) -> httpx.Response:
    headers = {"Authorization": f"Bearer {TOKEN}", "Content-Type": "application/json"}
    if isinstance(body, dict):
        return httpx.post(f"{service.url}/scenarios", json=body, headers=headers)
    return httpx.post(f"{service.url}/scenarios", content=body, headers=headers)


def test_a_number_too_large_for_a_float_is_422_naming_it(service: ServiceProcess) -> None:
    """`1e400` parses to infinity without passing a NaN check: it was a 500."""
    body = b'{"name": "x", "grid": {"width": 6, "height": 6}, "uavs": [{"id": "uav1", '
    body += b'"start": [0, 0], "goal": [5, 5], "speed": 1e400}]}'
    answer = post_scenario(service, body)
    assert answer.status_code == 422, answer.text
    assert "1e400 is not a finite number" in answer.text
    assert not service.problems()


@pytest.mark.parametrize("method", ["POST", "GET"])
def test_json_nested_a_thousand_deep_is_refused_or_ignored(
    service: ServiceProcess, method: str
) -> None:
    """Nested ~1,000 deep, a body overflowed the parser's recursion (a 500, a traceback
    in the log), even on GET /health/live: 400 where a body is read, ignored on a GET."""
    deep = b"[" * 1000 + b"]" * 1000
    if method == "POST":
        answer = post_scenario(service, deep)
        assert answer.status_code == 400 and "nested deeper than 32" in answer.text, answer.text
    else:
        answer = httpx.request(
            "GET", f"{service.url}/health/live", content=deep,
            headers={"Content-Type": "application/json"},
        )  # fmt: skip
        assert answer.status_code == 200, answer.text
    assert not service.problems()


@pytest.mark.parametrize(
    ("where", "value", "says"),
    [("speed", "1", "not a string"), ("radius", "0.3", "not a string")],
)
def test_a_number_sent_as_a_string_is_422(
    service: ServiceProcess, where: str, value: str, says: str
) -> None:
    uav = {**CASE["uavs"][0], where: value}  # type: ignore[index]
    answer = post_scenario(service, {**CASE, "uavs": [uav]})
    assert answer.status_code == 422 and says in answer.text, answer.text
    assert answer.json()["detail"][0]["loc"][-1] == where


def test_a_negative_seed_of_random_objects_is_422(service: ServiceProcess) -> None:
    answer = post_scenario(service, {**CASE, "non_uav_objects": {"random": 2, "seed": -1}})
    assert answer.status_code == 422, answer.text
    assert any(e["loc"][-1] == "seed" for e in answer.json()["detail"]), answer.text
    fine = post_scenario(service, {**CASE, "non_uav_objects": {"random": 2, "seed": 7}})
    assert fine.status_code == 201, fine.text


# --- live sockets that cannot be made to hold memory (issue 28) -------------------------


@pytest.fixture
def capped(tmp_path: Path) -> Iterator[ServiceProcess]:
    proc = ServiceProcess(
        tmp_path / "data",
        {"MVO_GCS_MAX_LIVE_SOCKETS": "4", "MVO_GCS_MAX_LIVE_SOCKETS_PER_SUBJECT": "2"},
    )
    proc.start()
    yield proc
    proc.stop()


CROSSING = {
    "name": "crossing",
    "grid": {"width": 6, "height": 6},
    "uavs": [
        {"id": f"uav{k}", "start": start, "goal": goal}
        for k, (start, goal) in enumerate(
            [([0, 0], [5, 5]), ([5, 5], [0, 0]), ([0, 5], [5, 0]), ([5, 0], [0, 5])]
        )
    ],
}
"""Four UAVs through one point: the paper's flow searches this until its budget is spent
(one UAV alone is planned, and its job over, within milliseconds)."""


def running_job(service: ServiceProcess, client: httpx.Client) -> str:
    """A planning job that runs for a minute unless cancelled."""
    scenario = client.post("/scenarios", json=CROSSING).json()["id"]
    request = {
        "wait_s": 0, "time_budget_s": 60, "iterations": 100_000, "patience": None,
        "objective": "paper",
    }  # fmt: skip
    answer = client.post(f"/scenarios/{scenario}/plans", json=request)
    assert answer.status_code == 202, answer.text
    return str(answer.json()["id"])


def closed_code(socket_: Any) -> int | None:
    """How the server closed the socket (every message before it read and dropped)."""
    with pytest.raises(ConnectionClosed) as closed:
        while True:
            socket_.recv(timeout=20)
    return closed.value.rcvd.code if closed.value.rcvd is not None else None


def admitted_within(url: str, attempts: int) -> bool:
    """Whether a socket is admitted (its first message arrives) within `attempts` tries:
    the server frees a closed socket's place once it has read the close."""
    for _ in range(attempts):
        with connect(url, open_timeout=10) as socket_:
            try:
                socket_.recv(timeout=20)
                return True
            except ConnectionClosed as closed:
                assert closed.rcvd is not None and closed.rcvd.code == 1013, closed
    return False


def test_live_sockets_only_send_hold_no_large_frames_and_are_capped(
    capped: ServiceProcess,
) -> None:
    """A client that speaks on a live socket is closed (1008), one that sends more than
    4 KiB in a frame too (1009: uvicorn's default let each park 16 MB); beyond 2 sockets
    on one job, or 4 in all, a socket is closed at once (1013, saying which limit)."""
    with capped.client() as client:
        jobs = [running_job(capped, client) for _ in range(3)]
        url = capped.url.replace("http", "ws") + "/jobs/{}/live"
        try:
            with contextlib.ExitStack() as sockets:

                def open_on(job: int) -> Any:
                    return sockets.enter_context(connect(url.format(jobs[job]), open_timeout=10))

                speaker = open_on(0)
                speaker.send("hello")
                assert closed_code(speaker) == 1008
                big = open_on(0)
                big.send("x" * 8192)
                assert closed_code(big) == 1009
                kept = [open_on(0), open_on(0)]
                assert closed_code(open_on(0)) == 1013  # 2 on that job already
                kept += [open_on(1), open_on(1)]
                assert closed_code(open_on(2)) == 1013  # 4 in all
                for socket_ in kept:
                    socket_.close()
            assert admitted_within(url.format(jobs[2]), 50)  # room again once they are gone
        finally:
            for job in jobs:
                client.post(f"/jobs/{job}/cancel")
    assert not capped.problems()


# --- a clean end ------------------------------------------------------------------------


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


def test_half_sent_requests_are_dropped_and_one_address_holds_few(tmp_path: Path) -> None:
    """Issue 28: 300 half-sent requests were held for 60 s, and with the descriptors gone
    the API stopped answering. A program at 127.0.0.2 now holds at most its share
    (MVO_GCS_MAX_CONNECTIONS_PER_CLIENT) while the operator at 127.0.0.1 is answered,
    and loses even those when their headers are late (MVO_GCS_HTTP_HEADER_TIMEOUT_S)."""
    share = 8
    proc = ServiceProcess(
        tmp_path / "data",
        {"MVO_GCS_HTTP_HEADER_TIMEOUT_S": "2", "MVO_GCS_MAX_CONNECTIONS_PER_CLIENT": str(share)},
    )
    proc.start()
    held: list[socket.socket] = []
    try:
        for _ in range(5 * share):
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.bind(("127.0.0.2", 0))
            sock.connect(("127.0.0.1", proc.port))
            sock.sendall(b"GET /health/live HTTP/1.1\r\nHost: 127.0.0.1\r\n")  # no end
            sock.setblocking(False)
            held.append(sock)

        def still_open() -> int:
            count = 0
            for sock in held:
                try:
                    count += sock.recv(1) != b""
                except BlockingIOError:
                    count += 1
                except OSError:
                    pass
            return count

        wait_for(lambda: still_open() <= share, 30, f"at most {share} held from 127.0.0.2")
        with proc.client() as client:
            assert client.get("/health/live").status_code == 200
        wait_for(lambda: still_open() == 0, 60, "the late headers dropped")
    finally:
        for sock in held:
            sock.close()
        proc.stop()
