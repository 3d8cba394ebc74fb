"""The service's live links to the registered vehicles.

Each registered vehicle gets a task that connects, and connects again after a failure,
so that a vehicle switched on after the service (or rebooted) is picked up without an
operator's help. The routers only ever see `link()` (or `VehicleOffline`) and `state()`.
Removing a vehicle, and closing the registry, finish within a bound whatever the link
is doing.

Each link is asked which vehicle it reaches (`gcs.mavlink.identity`), so that one vehicle
registered twice (its own port, and the listening port) is known as one: a second
registration is refused when the vehicle answers at once, and `same_vehicles` lets the
flights refuse a second owner whenever it does.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

from gcs.mavlink import client
from gcs.mavlink.client import identify
from gcs.mavlink.connection import Signing
from gcs.mavlink.errors import GcsError
from gcs.mavlink.identity import VehicleIdentity
from gcs.mavlink.link import LinkSettings, VehicleLink
from gcs.mavlink.transport import TransportOpener, open_transport
from gcs.mavlink.vehicle_state import VehicleState
from gcs.service.discovery import Discovery
from gcs.service.metrics import ServiceMetrics
from gcs.service.states import StateConflict

log = logging.getLogger("mvo_gcs.vehicles")
RETRY_S = (0.5, 1.0, 2.0, 5.0)  # back-off between connection attempts
IDENTIFY_ASKS = 3  # an autopilot that never says which it is is not asked forever
PROBE_TIMEOUT_S = 3.0  # a registration waits this long at most to learn which vehicle it is
CLOSE_TIMEOUT_S = 3.0


class VehicleOffline(Exception):
    def __init__(self, vehicle_id: str, why: str) -> None:
        super().__init__(f"vehicle {vehicle_id} is offline: {why}")
        self.vehicle_id = vehicle_id


@dataclass
class _Entry:
    connection: str
    sysid: int | None
    signing: Signing | None = None
    task: asyncio.Task[None] | None = None
    link: VehicleLink | None = None
    last_error: str = "not connected yet"
    shared: bool = False  # a discovered vehicle's link: not ours to close


class VehicleRegistry:
    def __init__(
        self,
        metrics: ServiceMetrics,
        settings: LinkSettings | None = None,
        discovery: Discovery | None = None,
        opener: TransportOpener = open_transport,
    ) -> None:
        self._metrics = metrics
        self._settings = settings or LinkSettings()
        self._opener = opener
        self._entries: dict[str, _Entry] = {}
        self.discovery = discovery
        self.registering = asyncio.Lock()  # one registration at a time: its duplicate check holds

    def add(
        self, vehicle_id: str, connection: str, sysid: int | None, signing: Signing | None = None
    ) -> None:
        entry = _Entry(connection, sysid, signing)
        self._entries[vehicle_id] = entry
        if self.discovery is not None and self.discovery.serves(connection):
            entry.shared = True  # the listening port's link, owned by discovery
            entry.task = asyncio.ensure_future(self._follow_discovered(vehicle_id, entry))
        else:
            entry.task = asyncio.ensure_future(self._keep_connected(vehicle_id, entry))

    def knows(self, vehicle_id: str) -> bool:
        """Registered here (connected or trying to)."""
        return vehicle_id in self._entries

    def known(self) -> set[str]:
        return set(self._entries)

    async def remove(self, vehicle_id: str) -> None:
        entry = self._entries.pop(vehicle_id, None)
        if entry is not None:
            await _close(entry)
            self._metrics.link_up.remove(vehicle_id)
            if entry.shared and entry.link is not None and not self._shared_uses(entry.link):
                entry.link.connection.pinned.discard(entry.link.sysid)

    def _shared_uses(self, link: VehicleLink) -> bool:
        return any(e.shared and e.link is link for e in self._entries.values())

    def relock(self, vehicle_id: str, address: str) -> None:
        """The operator's word that the vehicle now speaks from `address`: the address
        that claimed its system id lately (StateConflict if none did)."""
        link = self.link_or_none(vehicle_id) or self._last_link(vehicle_id)
        contest = link.connection.contested.get(link.sysid)
        if contest is None or contest.address != address:
            claimed = f"only {contest.address} did" if contest else "no other address did"
            raise StateConflict(
                f"vehicle {vehicle_id}: nothing claiming system {link.sysid} came from "
                f"{address} lately ({claimed}); the vehicle keeps its address"
            )
        link.connection.relock(link.sysid, contest.peer)
        log.warning("vehicle %s: the operator moved it to %s", vehicle_id, address)

    def _last_link(self, vehicle_id: str) -> VehicleLink:
        entry = self._entries.get(vehicle_id)
        if entry is None or entry.link is None:
            raise VehicleOffline(vehicle_id, entry.last_error if entry else "not registered")
        return entry.link

    def link(self, vehicle_id: str) -> VehicleLink:
        """The vehicle's link if it is up now; `VehicleOffline` says why not."""
        entry = self._entries.get(vehicle_id)
        if entry is None:
            raise VehicleOffline(vehicle_id, "not registered")
        if entry.link is None:
            raise VehicleOffline(vehicle_id, entry.last_error)
        if not entry.link.state.link_up:
            refusals = entry.link.connection.refusals()
            raise VehicleOffline(vehicle_id, f"no HEARTBEAT lately (link lost){refusals}")
        return entry.link

    def link_or_none(self, vehicle_id: str) -> VehicleLink | None:
        try:
            return self.link(vehicle_id)
        except VehicleOffline:
            return None

    def why_offline(self, vehicle_id: str) -> str:
        try:
            self.link(vehicle_id)
        except VehicleOffline as exc:
            return str(exc)
        return "online"

    def vehicle_state(self, vehicle_id: str) -> VehicleState | None:
        entry = self._entries.get(vehicle_id)
        return entry.link.state if entry is not None and entry.link is not None else None

    def last_sent(self, vehicle_id: str) -> float | None:
        """Loop time the ground station last sent the vehicle anything (None: never)."""
        entry = self._entries.get(vehicle_id)
        return entry.link.last_sent if entry is not None and entry.link is not None else None

    def is_down(self, vehicle_id: str) -> bool:
        """Heard lately, disarmed and on the ground."""
        state = self.vehicle_state(vehicle_id)
        return state is not None and state.down

    def state(self, vehicle_id: str) -> dict[str, Any]:
        entry = self._entries.get(vehicle_id)
        link = entry.link if entry else None
        if link is None:
            return {"online": False, "error": entry.last_error if entry else "not registered"}
        return describe(link)

    def links(self) -> list[VehicleLink]:
        return [e.link for e in self._entries.values() if e.link is not None]

    def identity(self, vehicle_id: str) -> VehicleIdentity | None:
        """Which vehicle the registration reaches, once it has said (None before)."""
        entry = self._entries.get(vehicle_id)
        return entry.link.identity if entry is not None and entry.link is not None else None

    def same_vehicles(self, vehicle_id: str) -> set[str]:
        """Every registration known to reach the vehicle `vehicle_id` reaches (itself too)."""
        mine = self.identity(vehicle_id)
        if mine is None:
            return {vehicle_id}
        return {vehicle_id} | {
            other
            for other in self._entries
            if (theirs := self.identity(other)) is not None and mine.is_same_vehicle(theirs)
        }

    async def identify_all(self, vehicle_ids: Iterable[str]) -> None:
        """Ask each vehicle that is online which one it is, if it has not said yet."""
        links = [link for vid in vehicle_ids if (link := self.link_or_none(vid)) is not None]
        await asyncio.gather(*(identify(link) for link in links))

    async def registered_as(
        self, connection: str, sysid: int | None, signing: Signing | None
    ) -> tuple[str, VehicleIdentity] | None:
        """The registered vehicle that `connection` reaches too, if it answers within
        PROBE_TIMEOUT_S (a vehicle that is off cannot say; the flights still refuse it a
        second owner once it does)."""
        known = {vid: ident for vid in self._entries if (ident := self.identity(vid)) is not None}
        if not any(sysid in (None, ident.sysid) for ident in known.values()):
            return None  # nothing it could be: no need to knock
        found = await self._probe(connection, sysid, signing)
        if found is None:
            return None
        return next(
            ((vid, ident) for vid, ident in known.items() if ident.is_same_vehicle(found)), None
        )

    async def _probe(
        self, connection: str, sysid: int | None, signing: Signing | None
    ) -> VehicleIdentity | None:
        if self.discovery is not None and self.discovery.serves(connection):
            link = self.discovery.link(sysid)
            return await identify(link) if link is not None else None
        quick = replace(self._settings, connect_timeout_s=PROBE_TIMEOUT_S, request_streams=False)
        try:
            async with asyncio.timeout(PROBE_TIMEOUT_S * 2):
                link = await client.connect(
                    connection, sysid=sysid, settings=quick, signing=signing, opener=self._opener
                )
                try:
                    return await identify(link)
                finally:
                    await link.close()
        except (GcsError, OSError, TimeoutError):
            return None

    async def close(self) -> None:
        entries = list(self._entries.values())
        self._entries.clear()
        await asyncio.gather(*(_close(entry) for entry in entries))

    async def _keep_connected(self, vehicle_id: str, entry: _Entry) -> None:
        attempt = 0
        while True:
            try:
                entry.link = await client.connect(
                    entry.connection, sysid=entry.sysid, settings=self._settings,
                    signing=entry.signing, opener=self._opener,
                )  # fmt: skip
            except (GcsError, OSError) as exc:
                entry.last_error = f"cannot connect to {entry.connection}: {exc}"
                self._metrics.link_up.labels(vehicle_id).set(0)
                await asyncio.sleep(RETRY_S[min(attempt, len(RETRY_S) - 1)])
                attempt += 1
                continue
            log.info("vehicle %s connected: %r", vehicle_id, entry.link)
            break
        entry.link.connection.pinned.add(entry.link.sysid)  # its address moves by the operator
        await self._report(vehicle_id, entry.link)

    async def _follow_discovered(self, vehicle_id: str, entry: _Entry) -> None:
        assert self.discovery is not None
        entry.last_error = f"not heard on {entry.connection} yet"
        while (link := self.discovery.link(entry.sysid)) is None:
            self._metrics.link_up.labels(vehicle_id).set(0)
            await asyncio.sleep(0.2)
        entry.link = link
        link.connection.pinned.add(link.sysid)  # no other sender takes it over after a silence
        await self._report(vehicle_id, link)

    async def _report(self, vehicle_id: str, link: VehicleLink) -> None:
        """The link re-finds a vehicle that went quiet by itself; this only reports it
        (and asks the vehicle which one it is, until it has said)."""
        asks = 0
        while True:
            if link.identity is None and link.state.link_up and asks < IDENTIFY_ASKS:
                asks += 1
                await identify(link)
            self._metrics.link_up.labels(vehicle_id).set(int(link.state.link_up))
            self._metrics.ignored_packets.labels(vehicle_id).set(link.connection.dropped)
            await asyncio.sleep(1.0)


async def _close(entry: _Entry) -> None:
    """Stop connecting and close the link, within CLOSE_TIMEOUT_S whatever happens."""
    if entry.task is not None:
        entry.task.cancel()
        await asyncio.wait({entry.task}, timeout=CLOSE_TIMEOUT_S)
    if entry.link is not None and not entry.shared:
        try:
            async with asyncio.timeout(CLOSE_TIMEOUT_S):
                await entry.link.close()
        except TimeoutError:
            log.warning("closing the link to %s took too long; left to the loop", entry.connection)


def describe(link: VehicleLink) -> dict[str, Any]:
    """A vehicle's live state as the API shows it. With the link down every value is the
    last one heard (`stale`), `seconds_since_heard` ago: an armed vehicle in AUTO that
    nobody hears is not shown as one."""
    state = link.state
    position = state.position
    now = asyncio.get_running_loop().time()
    return {
        "online": state.link_up,
        "stale": not state.link_up,
        "sysid": state.sysid,
        "uid": link.identity.uid if link.identity is not None else None,
        "autopilot": link.autopilot.name.lower(),
        "mode": state.mode,
        "armed": state.armed,
        "airborne": state.airborne,
        "system_status": state.system_status,
        "lat": position.lat if position else None,
        "lon": position.lon if position else None,
        "relative_alt_m": position.relative_alt_m if position else None,
        "groundspeed_m_s": state.groundspeed_m_s,
        "heading_deg": state.heading_deg,
        "mission_seq": state.mission_seq,
        "mission_total": state.mission_total,
        "mission_state": state.mission_state,
        "ignored_packets": link.connection.dropped,
        "claimed_from": _claimant(link, now),
        "seconds_since_heard": round(max(0.0, now - state.last_heard), 3)
        if state.last_heard
        else None,
    }


def _claimant(link: VehicleLink, now: float) -> dict[str, Any] | None:
    """Another address sending as this vehicle's system id, if one did: shown, so that the
    operator sees an impostor (or the vehicle come back elsewhere, to `relock`)."""
    contest = link.connection.contested.get(link.sysid)
    if contest is None:
        return None
    return {
        "address": contest.address,
        "packets": contest.packets,
        "seconds_ago": round(max(0.0, now - contest.last), 3),
    }
