"""The service's live links to the registered vehicles.

Each registered vehicle gets a task that connects, and connects again after a failure,
so that a vehicle switched on after the service (or rebooted) is picked up without an
operator's help. The routers only ever see `link()` (or `VehicleOffline`) and `state()`.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from dataclasses import dataclass
from typing import Any

from gcs.mavlink import client
from gcs.mavlink.errors import GcsError
from gcs.mavlink.link import LinkSettings, VehicleLink
from gcs.mavlink.vehicle_state import VehicleState
from gcs.service.metrics import ServiceMetrics

log = logging.getLogger("mvo_gcs.vehicles")
RETRY_S = (0.5, 1.0, 2.0, 5.0)  # back-off between connection attempts


class VehicleOffline(Exception):
    def __init__(self, vehicle_id: str, why: str) -> None:
        super().__init__(f"vehicle {vehicle_id} is offline: {why}")
        self.vehicle_id = vehicle_id


@dataclass
class _Entry:
    connection: str
    sysid: int | None
    task: asyncio.Task[None] | None = None
    link: VehicleLink | None = None
    last_error: str = "not connected yet"


class VehicleRegistry:
    def __init__(self, metrics: ServiceMetrics, settings: LinkSettings | None = None) -> None:
        self._metrics = metrics
        self._settings = settings or LinkSettings()
        self._entries: dict[str, _Entry] = {}

    def add(self, vehicle_id: str, connection: str, sysid: int | None) -> None:
        entry = _Entry(connection, sysid)
        self._entries[vehicle_id] = entry
        entry.task = asyncio.create_task(self._keep_connected(vehicle_id, entry))

    async def remove(self, vehicle_id: str) -> None:
        entry = self._entries.pop(vehicle_id, None)
        if entry is not None:
            await _close(entry)
            self._metrics.link_up.remove(vehicle_id)

    def link(self, vehicle_id: str) -> VehicleLink:
        """The vehicle's link if it is up now; `VehicleOffline` says why not."""
        entry = self._entries.get(vehicle_id)
        if entry is None:
            raise VehicleOffline(vehicle_id, "not registered")
        if entry.link is None:
            raise VehicleOffline(vehicle_id, entry.last_error)
        if not entry.link.state.link_up:
            raise VehicleOffline(vehicle_id, "no HEARTBEAT lately (link lost)")
        return entry.link

    def state(self, vehicle_id: str) -> dict[str, Any]:
        entry = self._entries.get(vehicle_id)
        link = entry.link if entry else None
        if link is None:
            return {"online": False, "error": entry.last_error if entry else "not registered"}
        return describe(link.state, link.autopilot.name.lower())

    async def wait_online(self, vehicle_id: str, timeout: float) -> VehicleLink:
        deadline = time.monotonic() + timeout
        while True:
            try:
                return self.link(vehicle_id)
            except VehicleOffline:
                if time.monotonic() > deadline:
                    raise
                await asyncio.sleep(0.1)

    async def close(self) -> None:
        for entry in self._entries.values():
            await _close(entry)
        self._entries.clear()

    async def _keep_connected(self, vehicle_id: str, entry: _Entry) -> None:
        attempt = 0
        while True:
            try:
                entry.link = await client.connect(
                    entry.connection, sysid=entry.sysid, settings=self._settings
                )
            except (GcsError, OSError) as exc:
                entry.last_error = f"cannot connect to {entry.connection}: {exc}"
                self._metrics.link_up.labels(vehicle_id).set(0)
                await asyncio.sleep(RETRY_S[min(attempt, len(RETRY_S) - 1)])
                attempt += 1
                continue
            log.info("vehicle %s connected: %r", vehicle_id, entry.link)
            attempt = 0
            while True:  # the link re-finds a vehicle that went quiet; just report it
                self._metrics.link_up.labels(vehicle_id).set(int(entry.link.state.link_up))
                await asyncio.sleep(1.0)


async def _close(entry: _Entry) -> None:
    if entry.task is not None:
        entry.task.cancel()
        with contextlib.suppress(asyncio.CancelledError, Exception):
            await entry.task
    if entry.link is not None:
        await entry.link.close()


def describe(state: VehicleState, autopilot: str) -> dict[str, Any]:
    """A vehicle's live state as the API shows it."""
    position = state.position
    return {
        "online": state.link_up,
        "sysid": state.sysid,
        "autopilot": autopilot,
        "mode": state.mode,
        "armed": state.armed,
        "airborne": state.airborne,
        "lat": position.lat if position else None,
        "lon": position.lon if position else None,
        "relative_alt_m": position.relative_alt_m if position else None,
        "groundspeed_m_s": state.groundspeed_m_s,
        "heading_deg": state.heading_deg,
        "mission_seq": state.mission_seq,
        "mission_total": state.mission_total,
        "mission_state": state.mission_state,
        "seconds_since_heard": round(max(0.0, time.monotonic() - state.last_heard), 3)
        if state.last_heard
        else None,
    }
