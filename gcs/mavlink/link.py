"""The ground station's link to one vehicle: identity, live state, subscriptions, waits.

A link is made from the autopilot's first HEARTBEAT on a connection (`gcs.mavlink.client`
finds it, ignoring cameras, gimbals and other ground stations) and then keeps `state`
current. Everything that waits on the vehicle does so through a bounded subscription; a
link loss or a reboot is delivered to those subscriptions as an exception, so no
exchange outlives it. What happens to the link itself (regained after a loss, a reboot,
a gap in the heartbeats) is told to `on_event` listeners, such as the telemetry streams
that must then be asked for again: the link itself sends no commands.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Coroutine, Iterable
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.connection import GCS_COMPID, GCS_SYSID, MavConnection, Message
from gcs.mavlink.errors import LinkLostError, VehicleRebootedError
from gcs.mavlink.identity import VehicleIdentity
from gcs.mavlink.mission_item import Autopilot
from gcs.mavlink.mode_history import ModeHistory
from gcs.mavlink.subscription import Predicate, Subscription
from gcs.mavlink.vehicle_state import MAV_STATE_BOOT, VehicleState

BOOT_TIME_JUMP_MS = 2000  # time_boot_ms going back by more than this means a reboot
HEARTBEAT_GAP_FACTOR = 1.8  # one heartbeat missed makes a gap (checked, not trusted)
MIN_GAP_S = 0.05
WATCHDOG_PERIOD_S = 0.2
CLOSE_TIMEOUT_S = 2.0

Callback = Callable[[Message], None]


class LinkEvent(Enum):
    REGAINED = "regained"  # heard again after the link was down
    REBOOTED = "rebooted"  # the vehicle restarted: whatever it was asked is forgotten
    GAP = "gap"  # a silence of several heartbeats: it may have rebooted unseen


@dataclass(frozen=True)
class LinkSettings:
    """How the link watches a vehicle. Rates are in the vehicle's own (simulated) time."""

    connect_timeout_s: float = 10.0
    link_timeout_s: float = 4.0  # silence after which the link is down (notes: 3-5 s)
    request_streams: bool = True
    boot_timeout_s: float = 30.0  # how long an exchange waits for a booting vehicle
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


@dataclass
class CommandTurn:
    """The turn of the commands of one number on a link (`VehicleLink.command_turn`), and
    the answers owed to an earlier one whose wait for them ran out: the next command of
    the number takes that many of its number's answers as theirs, not its own."""

    lock: asyncio.Lock = field(default_factory=asyncio.Lock)
    owed: int = 0
    owed_until: float = 0.0

    def take_owed(self, now: float) -> int:
        """Answers still owed by earlier commands (none once `owed_until` has passed)."""
        owed, self.owed = (self.owed if now < self.owed_until else 0), 0
        return owed


class VehicleLink:
    """One vehicle (one autopilot system id) on a MAVLink connection."""

    def __init__(
        self,
        connection: MavConnection,
        heartbeat: Message,
        settings: LinkSettings | None = None,
        *,
        owns_connection: bool = False,
    ) -> None:
        self.connection = connection
        self.settings = settings or LinkSettings()
        self.sysid: int = heartbeat.get_srcSystem()
        self.compid: int = heartbeat.get_srcComponent()
        self.autopilot = Autopilot.of(heartbeat.autopilot)
        self.state = VehicleState(self.sysid, int(self.autopilot))
        self._owns_connection = owns_connection
        self._subscriptions: list[Subscription] = []
        self._callbacks: list[tuple[frozenset[str] | None, Callback]] = []
        self._event_listeners: list[Callable[[LinkEvent], None]] = []
        self._loop = asyncio.get_running_loop()
        self._tasks: set[asyncio.Task[Any]] = set()
        self._ever_lost = False
        self._closed = False
        self._last_heartbeat: float | None = None
        self.heartbeat_period_s: float | None = None
        self.gap_began: float | None = None  # loop time the latest heartbeat gap began
        self._clock_origin: tuple[float, int] | None = None  # (loop time, its time_boot_ms)
        self._clock_heard_at = 0.0  # loop time its latest time_boot_ms came
        self.last_sent: float | None = None  # loop time we last sent the vehicle anything
        self.identity: VehicleIdentity | None = None  # what it reported (gcs.mavlink.identity)
        self._command_turns: dict[int, CommandTurn] = {}
        self.modes = ModeHistory()  # what it was asked for lately, by every command sender
        self._received(heartbeat)
        connection.attach(self.sysid, self._received)
        self.spawn(self._watchdog())

    # --- sending -----------------------------------------------------------------------

    @property
    def codec(self) -> Any:
        """pymavlink's MAVLink 2 encoder: `link.send(link.codec.xxx_encode(...))`."""
        return self.connection.codec

    def send(self, msg: Message) -> None:
        self.last_sent = self._loop.time()
        if _is_arm(msg):
            self.state.arm_sent = self.last_sent
        self.connection.send(msg, self.sysid)

    def command_turn(self, command: int) -> CommandTurn:
        """Held while a command of this number is under way: a COMMAND_ACK names only the
        command's number, so two of one number at once (an operator's RTL still being
        re-sent when the abort's LAND goes out, both DO_SET_MODE) would take each other's
        ACK, and the lost one would never be sent again."""
        return self._command_turns.setdefault(command, CommandTurn())

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

        def remove() -> None:
            if entry in self._callbacks:
                self._callbacks.remove(entry)

        return remove

    @property
    def callback_count(self) -> int:
        """How many message callbacks are registered (a flight that ended leaves none)."""
        return len(self._callbacks)

    def on_event(self, listener: Callable[[LinkEvent], None]) -> None:
        self._event_listeners.append(listener)

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
            self.declare_rebooted()
        gap = msg.get_type() == "HEARTBEAT" and self._after_gap(now)
        if not self.state.link_up:
            self._link_regained()
        elif gap:
            self._tell(LinkEvent.GAP)
        self.state.apply(msg, now)
        if getattr(msg, "time_boot_ms", None):
            self._clock_heard_at = now
            if self._clock_origin is None:
                self._clock_origin = (now, self.state.time_boot_ms)
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
        interval, period = now - last, self.heartbeat_period_s
        self.heartbeat_period_s = interval if period is None else 0.9 * period + 0.1 * interval
        if period is None or interval <= max(HEARTBEAT_GAP_FACTOR * period, MIN_GAP_S):
            return False
        self.gap_began = last
        return True

    def declare_rebooted(self) -> None:
        """The vehicle restarted (seen here, or by a listener that knows what it forgot)."""
        self.state.reboots += 1
        self.state.reached.clear()
        self.state.time_boot_ms = 0
        self._clock_origin = None
        self._fault(VehicleRebootedError(f"vehicle {self.sysid} rebooted"))
        self._tell(LinkEvent.REBOOTED)

    def clock_rate(self) -> float | None:
        """The vehicle's seconds to one of ours (a simulator's speed-up; 1 in the air),
        from its own clock's reports since we first heard it (or since it rebooted);
        None until a second of ours has passed."""
        if self._clock_origin is None:
            return None
        then, boot_then = self._clock_origin
        elapsed = self._clock_heard_at - then
        if elapsed < 1.0:
            return None
        return (self.state.time_boot_ms - boot_then) / 1000.0 / elapsed

    def _link_regained(self) -> None:
        self.state.link_up = True
        if self._ever_lost:
            self._tell(LinkEvent.REGAINED)

    def _tell(self, event: LinkEvent) -> None:
        for listener in list(self._event_listeners):
            listener(event)

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

    @property
    def closed(self) -> bool:
        return self._closed

    def spawn(self, coro: Coroutine[Any, Any, Any]) -> None:
        """Run `coro` for as long as the link lives (cancelled by `close`)."""
        if self._closed:
            coro.close()
            return
        task = asyncio.ensure_future(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def close(self) -> None:
        """Stop everything this link runs; bounded, even if a task ignores cancellation."""
        self._closed = True
        self.connection.detach(self.sysid)
        self._fault(LinkLostError(f"vehicle {self.sysid}: link closed"))
        tasks = list(self._tasks)
        for task in tasks:
            task.cancel()
        if tasks:
            await asyncio.wait(tasks, timeout=CLOSE_TIMEOUT_S)
        if self._owns_connection:
            await self.connection.close()

    def __repr__(self) -> str:
        return f"VehicleLink({self.connection.name!r}, sysid={self.sysid}, {self.autopilot.name})"


def _addressed_to_us(msg: Message) -> bool:
    """False for replies a vehicle sends to another ground station on the same link."""
    target = getattr(msg, "target_system", 0)
    component = getattr(msg, "target_component", 0)
    return target in (0, GCS_SYSID) and component in (0, GCS_COMPID)


def _is_arm(msg: Message) -> bool:
    """A COMMAND_LONG that arms (the vehicle's state then waits for news of it)."""
    return (
        getattr(msg, "command", None) == mavlink2.MAV_CMD_COMPONENT_ARM_DISARM
        and msg.get_type() == "COMMAND_LONG"
        and round(getattr(msg, "param1", 0)) == 1
    )
