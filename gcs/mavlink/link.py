"""The ground station's link to one vehicle: identity, live state, subscriptions, waits.

`VehicleLink.connect(url)` opens the connection, waits for the autopilot's HEARTBEAT
(learning its system id and flavour, ignoring cameras, gimbals and other ground
stations), asks for the telemetry streams the GCS needs (a real ArduPilot sends
nothing but HEARTBEAT until asked) and then keeps `state` current. Everything that
waits on the vehicle does so through a bounded subscription; a link loss or a reboot
is delivered to those subscriptions as an exception, so no exchange outlives it.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from gcs.mavlink.connection import GCS_COMPID, GCS_SYSID, MavConnection, Message
from gcs.mavlink.errors import (
    ConnectTimeoutError,
    GcsError,
    LinkLostError,
    VehicleRebootedError,
    WaitTimeoutError,
)
from gcs.mavlink.mission_item import Autopilot
from gcs.mavlink.subscription import Predicate, Subscription
from gcs.mavlink.vehicle_state import MAV_STATE_BOOT, VehicleState

MAV_AUTOPILOT_INVALID = 8
NOT_AUTOPILOT_TYPES = frozenset({6, 18, 26, 27, 30})  # GCS, onboard computer, gimbal, ADSB, camera
BOOT_TIME_JUMP_MS = 2000  # time_boot_ms going back by more than this means a reboot
HEARTBEAT_GAP_FACTOR = 1.8  # one heartbeat missed makes a gap (checked, not trusted)
MIN_GAP_S = 0.05
WATCHDOG_PERIOD_S = 0.2

Callback = Callable[[Message], None]


@dataclass(frozen=True)
class LinkSettings:
    """How the link watches a vehicle. Rates are in the vehicle's own (simulated) time."""

    connect_timeout_s: float = 10.0
    link_timeout_s: float = 4.0  # silence after which the link is down (notes: 3-5 s)
    request_streams: bool = True
    stream_rates_hz: dict[str, float] = field(
        default_factory=lambda: {
            "GLOBAL_POSITION_INT": 5.0,
            "MISSION_CURRENT": 2.0,
            "EXTENDED_SYS_STATE": 1.0,
            "SYS_STATUS": 1.0,
            "GPS_RAW_INT": 1.0,
            "HOME_POSITION": 0.5,
        }
    )


class VehicleLink:
    """One vehicle (one autopilot system id) on a MAVLink connection."""

    def __init__(
        self,
        connection: MavConnection,
        heartbeat: Message,
        settings: LinkSettings,
        owns_connection: bool,
    ) -> None:
        self.connection = connection
        self.settings = settings
        self.sysid: int = heartbeat.get_srcSystem()
        self.compid: int = heartbeat.get_srcComponent()
        self.autopilot = (
            Autopilot(heartbeat.autopilot)
            if heartbeat.autopilot in (3, 12)
            else (Autopilot.ARDUPILOT)
        )
        self.state = VehicleState(self.sysid, int(self.autopilot))
        self._owns_connection = owns_connection
        self._subscriptions: list[Subscription] = []
        self._callbacks: list[tuple[frozenset[str] | None, Callback]] = []
        self._loop = asyncio.get_running_loop()
        self._tasks: set[asyncio.Task[Any]] = set()
        self._ever_lost = False
        self._last_heartbeat: float | None = None
        self._heartbeat_period_s: float | None = None
        self._received(heartbeat)
        connection.attach(self.sysid, self._received)
        self._spawn(self._watchdog())

    # --- opening -----------------------------------------------------------------------

    @classmethod
    async def connect(
        cls, url: str, *, sysid: int | None = None, settings: LinkSettings | None = None
    ) -> VehicleLink:
        """Open `url` and the link to the autopilot `sysid` (the first one heard if None)."""
        connection = await MavConnection.open(url)
        try:
            return await cls.attach(connection, sysid=sysid, settings=settings, owns=True)
        except BaseException:
            await connection.close()
            raise

    @classmethod
    async def attach(
        cls,
        connection: MavConnection,
        *,
        sysid: int | None = None,
        settings: LinkSettings | None = None,
        owns: bool = False,
    ) -> VehicleLink:
        """A link on an already open connection (several vehicles on one port)."""
        settings = settings or LinkSettings()
        heartbeat = await _first_autopilot_heartbeat(connection, sysid, settings.connect_timeout_s)
        link = cls(connection, heartbeat, settings, owns)
        if settings.request_streams:
            await link.request_streams()
        return link

    async def request_streams(self) -> None:
        from gcs.mavlink.telemetry import request_telemetry  # uses commands, which use us

        await request_telemetry(self, self.settings.stream_rates_hz)

    # --- sending -----------------------------------------------------------------------

    @property
    def codec(self) -> Any:
        """pymavlink's MAVLink 2 encoder: `link.send(link.codec.xxx_encode(...))`."""
        return self.connection.codec

    def send(self, msg: Message) -> None:
        self.connection.send(msg, self.sysid)

    # --- receiving ---------------------------------------------------------------------

    def subscribe(
        self, types: Iterable[str] | None = None, *, maxsize: int = 256, fail_on_fault: bool = True
    ) -> Subscription:
        """Messages of `types` (all if None) from now on; use as a context manager."""
        sub = Subscription(
            types, self._subscriptions.remove, maxsize=maxsize, fail_on_fault=fail_on_fault
        )
        self._subscriptions.append(sub)
        return sub

    def on_message(
        self, callback: Callback, types: Iterable[str] | None = None
    ) -> Callable[[], None]:
        """Call `callback(msg)` for each message of `types`; returns the function that stops it."""
        entry = (frozenset(types) if types else None, callback)
        self._callbacks.append(entry)
        return lambda: self._callbacks.remove(entry)

    async def wait_for(
        self, msg_type: str, predicate: Predicate | None = None, timeout: float = 1.5
    ) -> Message:
        """The next `msg_type` message `predicate` accepts, or WaitTimeoutError."""
        with self.subscribe([msg_type]) as sub:
            return await sub.next_matching(predicate, timeout)

    def _received(self, msg: Message) -> None:
        if msg.get_srcComponent() != self.compid or not _addressed_to_us(msg):
            return
        now = self._loop.time()
        if self._is_reboot(msg):
            self._rebooted()
        gap = msg.get_type() == "HEARTBEAT" and self._after_gap(now)
        if not self.state.link_up:
            self._link_regained()
        elif gap:
            self._spawn(self._check_streams_after_gap())
        self.state.apply(msg, now)
        msg_type = msg.get_type()
        for sub in list(self._subscriptions):
            if sub.wants(msg_type):
                sub.put(msg)
        for types, callback in list(self._callbacks):
            if types is None or msg_type in types:
                callback(msg)

    # --- link health -------------------------------------------------------------------

    def _is_reboot(self, msg: Message) -> bool:
        boot = getattr(msg, "time_boot_ms", None)
        if boot is not None and boot + BOOT_TIME_JUMP_MS < self.state.time_boot_ms:
            return True
        return (
            msg.get_type() == "HEARTBEAT"
            and msg.system_status == MAV_STATE_BOOT
            and self.state.system_status not in (0, MAV_STATE_BOOT)
        )

    def _after_gap(self, now: float) -> bool:
        """True for a heartbeat that ends a silence of several heartbeat periods."""
        last, self._last_heartbeat = self._last_heartbeat, now
        if last is None:
            return False
        interval, period = now - last, self._heartbeat_period_s
        self._heartbeat_period_s = interval if period is None else 0.9 * period + 0.1 * interval
        return period is not None and interval > max(HEARTBEAT_GAP_FACTOR * period, MIN_GAP_S)

    def _rebooted(self) -> None:
        self.state.reboots += 1
        self.state.reached.clear()
        self.state.time_boot_ms = 0
        self._fault(VehicleRebootedError(f"vehicle {self.sysid} rebooted"))
        if self.settings.request_streams:
            self._spawn(self._rerequest_streams())

    def _link_regained(self) -> None:
        self.state.link_up = True
        if self._ever_lost and self.settings.request_streams:
            self._spawn(self._rerequest_streams())

    async def _check_streams_after_gap(self) -> None:
        """A vehicle that forgot the streams we asked for has rebooted (its uptime, status
        BOOT or mission count may say so too, but not every autopilot shows them)."""
        if not self.settings.request_streams:
            return
        period = self._heartbeat_period_s or 1.0
        try:
            await self.wait_for("GLOBAL_POSITION_INT", timeout=max(4 * period, 0.2))
        except WaitTimeoutError:
            self._rebooted()
        except GcsError:
            pass

    async def _rerequest_streams(self) -> None:
        with contextlib.suppress(Exception):
            await self.request_streams()

    async def _watchdog(self) -> None:
        while True:
            await asyncio.sleep(WATCHDOG_PERIOD_S)
            silent = self._loop.time() - self.state.last_heard
            if self.state.link_up and silent > self.settings.link_timeout_s:
                self.state.link_up = False
                self._ever_lost = True
                self._fault(LinkLostError(f"vehicle {self.sysid} silent for {silent:.1f} s"))

    def _fault(self, exc: Exception) -> None:
        for sub in list(self._subscriptions):
            if sub.fail_on_fault:
                sub.fail(exc)

    def ensure_up(self) -> None:
        """Raise LinkLostError now rather than wait on a link that is down."""
        if not self.state.link_up:
            raise LinkLostError(f"vehicle {self.sysid}: link is down")

    def _spawn(self, coro: Any) -> None:
        task = asyncio.ensure_future(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def close(self) -> None:
        self.connection.detach(self.sysid)
        for task in list(self._tasks):
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        if self._owns_connection:
            await self.connection.close()

    def __repr__(self) -> str:
        return f"VehicleLink({self.connection.url!r}, sysid={self.sysid}, {self.autopilot.name})"


def _addressed_to_us(msg: Message) -> bool:
    """False for replies a vehicle sends to another ground station on the same link."""
    target = getattr(msg, "target_system", 0)
    component = getattr(msg, "target_component", 0)
    return target in (0, GCS_SYSID) and component in (0, GCS_COMPID)


def _is_autopilot_heartbeat(msg: Message, sysid: int | None) -> bool:
    return (
        msg.get_type() == "HEARTBEAT"
        and msg.autopilot != MAV_AUTOPILOT_INVALID
        and msg.type not in NOT_AUTOPILOT_TYPES
        and (sysid is None or msg.get_srcSystem() == sysid)
    )


async def _first_autopilot_heartbeat(
    connection: MavConnection, sysid: int | None, timeout: float
) -> Message:
    found: asyncio.Future[Message] = asyncio.get_running_loop().create_future()

    def look(msg: Message) -> None:
        if not found.done() and _is_autopilot_heartbeat(msg, sysid):
            found.set_result(msg)

    stop = connection.listen(look)
    try:
        return await asyncio.wait_for(found, timeout)
    except TimeoutError:
        who = f"autopilot {sysid}" if sysid is not None else "an autopilot"
        raise ConnectTimeoutError(
            f"no HEARTBEAT from {who} on {connection.url} within {timeout:.1f} s"
        ) from None
    finally:
        stop()
