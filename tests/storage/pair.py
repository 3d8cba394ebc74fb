"""Two real `mvo-gcs serve` processes on one PostgreSQL database, for the takeover test
and bench/takeover_bench.py: each with its own port, data directory and service id, both
able to reach every mock vehicle (a TCP port of the mock takes several clients, as
SITL's further serial ports or a MAVLink router would let two ground stations in)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx

from tests.e2e.flying import wait_for
from tests.service_process import ServiceProcess

LEASE_S = 3.0
RENEW_S = 1.0


def service(root: Path, name: str, database_url: str) -> ServiceProcess:
    """A service (not started) called `name` on the shared database."""
    proc = ServiceProcess(root / name, {"MVO_GCS_DATABASE_URL": database_url})
    proc.env.update(
        {
            "MVO_GCS_SERVICE_ID": name,
            "MVO_GCS_PUBLIC_URL": proc.url,
            "MVO_GCS_LEASE_S": str(LEASE_S),
            "MVO_GCS_LEASE_RENEW_S": str(RENEW_S),
        }
    )
    return proc


@contextlib.contextmanager
def pair(root: Path, database_url: str) -> Iterator[tuple[ServiceProcess, ServiceProcess]]:
    """Services `a` and `b`, started one after the other, stopped by their process ids."""
    a, b = service(root, "a", database_url), service(root, "b", database_url)
    try:
        a.start()
        b.start()
        yield a, b
    finally:
        a.stop()
        b.stop()


def events(client: httpx.Client, flight_id: str) -> list[dict[str, Any]]:
    answer = client.get(f"/flights/{flight_id}/events", params={"limit": 10_000})
    assert answer.status_code == 200, answer.text
    found: list[dict[str, Any]] = answer.json()
    return found


def taken_over_by(client: httpx.Client, flight_id: str, name: str) -> dict[str, Any] | None:
    """The `TakenOver` event of `name` for the flight, once stored."""
    for event in events(client, flight_id):
        if event["kind"] == "TakenOver" and event["data"]["by"] == name:
            return event
    return None


def wait_taken_over(client: httpx.Client, flight_id: str, name: str, timeout: float = 60) -> None:
    wait_for(
        lambda: (
            client.get(f"/flights/{flight_id}").json()["state"] == "interrupted"
            and taken_over_by(client, flight_id, name)
        ),
        timeout,
        f"service {name} to take flight {flight_id} over",
    )
