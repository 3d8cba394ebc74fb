"""Vehicles that announce themselves: the service listens on a UDP port, as QGroundControl
and MAVProxy do, and keeps a link to every autopilot it hears there.

Real ArduPilot SITL behind MAVProxy, PX4 SITL and `mvo-gcs sitl --out` send to
127.0.0.1:14550; several vehicles share the port, each told apart by its system id (and
held to the address its first HEARTBEAT came from: `MavConnection`). Each is listed,
with its live state, ready to be registered (`udpin:127.0.0.1:14550` with its system id)
and bound to a plan's UAV; a registered one uses the same link. One that is not
registered and falls silent for `forget_after_s` is forgotten: anyone can announce a
vehicle on the port, and a list of everything ever heard would only grow.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import Any

from gcs.mavlink import client
from gcs.mavlink.connection import MavConnection
from gcs.mavlink.endpoint import Endpoint
from gcs.mavlink.errors import GcsError
from gcs.mavlink.link import LinkSettings, VehicleLink
from gcs.mavlink.transport import TransportOpener, open_transport

log = logging.getLogger("mvo_gcs.discovery")
SWEEP_PERIOD_S = 1.0


class Discovery:
    def __init__(
        self,
        url: str,
        settings: LinkSettings | None = None,
        opener: TransportOpener = open_transport,
        forget_after_s: float = 30.0,
    ) -> None:
        self.endpoint = Endpoint.parse(url)
        self.forget_after_s = forget_after_s
        self.settings = settings or LinkSettings()
        self._opener = opener
        self.connection: MavConnection | None = None
        self.links: dict[int, VehicleLink] = {}
        self._attaching: dict[int, asyncio.Task[None]] = {}
        self._sweeper: asyncio.Task[None] | None = None
        self.error = ""

    @property
    def url(self) -> str:
        return str(self.endpoint)

    async def start(self) -> None:
        """Listen; a port another program holds is reported, not fatal."""
        try:
            self.connection = await MavConnection.open(self.endpoint, opener=self._opener)
        except GcsError as exc:
            self.error = f"not listening on {self.url}: {exc}"
            log.warning("vehicle discovery is off: %s", self.error)
            return
        self.connection.listen(self._heard)
        self._sweeper = asyncio.ensure_future(self._forget_the_silent())
        log.info("listening for vehicles on %s", self.url)

    async def _forget_the_silent(self) -> None:
        loop = asyncio.get_running_loop()
        while True:
            await asyncio.sleep(SWEEP_PERIOD_S)
            assert self.connection is not None
            for sysid, link in list(self.links.items()):
                silent = loop.time() - link.state.last_heard > self.forget_after_s
                if silent and sysid not in self.connection.pinned:  # pinned: registered
                    del self.links[sysid]
                    await link.close()

    def _heard(self, msg: Any) -> None:
        if not client.is_autopilot_heartbeat(msg):
            return
        sysid = msg.get_srcSystem()
        if sysid in self.links or sysid in self._attaching:
            return
        self._attaching[sysid] = asyncio.ensure_future(self._attach(sysid))

    async def _attach(self, sysid: int) -> None:
        assert self.connection is not None
        try:
            self.links[sysid] = await client.attach(
                self.connection, sysid=sysid, settings=self.settings
            )
        except GcsError as exc:
            log.warning("vehicle %d on %s: %s", sysid, self.url, exc)
        finally:
            self._attaching.pop(sysid, None)

    def link(self, sysid: int | None) -> VehicleLink | None:
        """The link to `sysid` on the listening port (the first heard if None)."""
        if sysid is None:
            return next(iter(self.links.values()), None)
        return self.links.get(sysid)

    def serves(self, connection: str) -> bool:
        return self.connection is not None and connection == self.url

    async def close(self) -> None:
        if self._sweeper is not None:
            self._sweeper.cancel()
        for task in list(self._attaching.values()):
            task.cancel()
        for link in list(self.links.values()):
            with contextlib.suppress(Exception):
                await link.close()
        if self.connection is not None:
            await self.connection.close()
            self.connection = None
