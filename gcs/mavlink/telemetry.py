"""Asking a vehicle for the telemetry the ground station follows, and asking again.

A real ArduPilot streams nothing but HEARTBEAT until asked. SET_MESSAGE_INTERVAL
(MAVLink 2 era) is tried first, one message at a time; a vehicle that does not
acknowledge it gets the older REQUEST_DATA_STREAM for everything instead. A vehicle
forgets what it was asked when it reboots, so the streams are asked for again after a
reboot and after the link comes back. After a gap in the heartbeats, a position stream
that was flowing before it and does not resume means the vehicle rebooted without the
link noticing; a stream that was not flowing yet proves nothing (ArduPilot's heartbeats
pause while it boots, before it streams anything), so it is only asked for again.

Asking can fail unseen: REQUEST_DATA_STREAM has no answer, and on a lossy uplink the
fallback to it (after three SET_MESSAGE_INTERVALs went unacknowledged) may be lost too.
So after each ask, until the position and the mission's current item arrive, what has
not come is asked for again every few heartbeats: fuzzed flight 19087's uav7, with 20 %
loss towards it, was never asked successfully and its flight could not start ("the
vehicle reports no position" after 100 s).
"""

from __future__ import annotations

import contextlib

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.commands import CommandPolicy, send_command
from gcs.mavlink.errors import CommandError, GcsError, WaitTimeoutError
from gcs.mavlink.link import LinkEvent, VehicleLink

INTERVAL_POLICY = CommandPolicy(timeout_s=0.5, retries=2)
FALLBACK_STREAMS = (
    mavlink2.MAV_DATA_STREAM_EXTENDED_STATUS,  # SYS_STATUS, GPS_RAW_INT, MISSION_CURRENT
    mavlink2.MAV_DATA_STREAM_POSITION,  # GLOBAL_POSITION_INT
    mavlink2.MAV_DATA_STREAM_EXTRA2,  # VFR_HUD
)
FALLBACK_RATE_HZ = 4
FOLLOWED = ("GLOBAL_POSITION_INT", "MISSION_CURRENT")
"""The streams a flight cannot be followed without: where each vehicle is, and which item
it flies (an approach restarts that item). Each is asked for until it flows: with only
the position flowing (the MISSION_CURRENT interval unanswered on a lossy link, and the
fallback lost), the item seen was 5 s old, and an approach sent the vehicle back to a
waypoint it had passed, 1.67 m from the vehicle waiting there (fuzzed flight 20014)."""
GAP_CHECK_PERIODS = 4  # heartbeat periods to wait for the position stream after a gap
MIN_CHECK_S = 0.2


def message_id(name: str) -> int:
    return int(getattr(mavlink2, f"MAVLINK_MSG_ID_{name}"))


class TelemetryStreams:
    """The streams one link needs, kept asked for while the link lives."""

    def __init__(self, link: VehicleLink, rates_hz: dict[str, float]) -> None:
        self.link = link
        self.rates_hz = dict(rates_hz)
        self._checking = False  # a `_until_flowing` runs
        link.on_event(self._on_event)

    async def start(self) -> bool:
        """Ask for every stream; True if SET_MESSAGE_INTERVAL was accepted. Until a
        position arrives, they are asked for again in the background."""
        accepted = await request_telemetry(self.link, self.rates_hz)
        if not self._checking:
            self._checking = True
            self.link.spawn(self._until_flowing())
        return accepted

    def _on_event(self, event: LinkEvent) -> None:
        if event in (LinkEvent.REGAINED, LinkEvent.REBOOTED):
            self.link.spawn(self._ask_again())
        elif event == LinkEvent.GAP:
            check = self._check_after_gap() if self._was_streaming() else self._ask_again()
            self.link.spawn(check)

    def _was_streaming(self) -> bool:
        """A position came within GAP_CHECK_PERIODS heartbeat periods before the gap."""
        heard, began = self.link.state.position_heard, self.link.gap_began
        if heard is None or began is None:
            return False
        period = self.link.heartbeat_period_s or 1.0
        return heard >= began - GAP_CHECK_PERIODS * period

    async def _ask_again(self) -> None:
        with contextlib.suppress(GcsError):
            await self.start()

    def _check_s(self) -> float:
        return max(GAP_CHECK_PERIODS * (self.link.heartbeat_period_s or 1.0), MIN_CHECK_S)

    async def _until_flowing(self) -> None:
        """Ask again, every few heartbeats, until every stream a flight is followed by
        (`FOLLOWED`) comes."""
        try:
            while missing := await self._not_flowing():
                with contextlib.suppress(GcsError):
                    await request_telemetry(self.link, missing)
        except GcsError:
            pass  # the link is lost (asked for again once regained) or closed
        finally:
            self._checking = False

    async def _not_flowing(self) -> dict[str, float]:
        """The followed streams that did not come within a few heartbeats, at their rates."""
        missing = {}
        for name in FOLLOWED:
            if name not in self.rates_hz:
                continue
            try:
                await self.link.wait_for(name, timeout=self._check_s())
            except WaitTimeoutError:
                missing[name] = self.rates_hz[name]
        return missing

    async def _check_after_gap(self) -> None:
        try:
            await self.link.wait_for("GLOBAL_POSITION_INT", timeout=self._check_s())
        except WaitTimeoutError:
            self.link.declare_rebooted()
        except GcsError:
            pass


async def request_telemetry(link: VehicleLink, rates_hz: dict[str, float]) -> bool:
    """Ask for each message at its rate; True if SET_MESSAGE_INTERVAL was accepted."""
    try:
        for name, rate in rates_hz.items():
            await set_message_interval(link, name, rate)
    except CommandError:
        request_data_streams(link)
        return False
    return True


async def set_message_interval(link: VehicleLink, name: str, rate_hz: float) -> None:
    interval_us = int(1e6 / rate_hz) if rate_hz > 0 else -1
    await send_command(
        link,
        mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL,
        message_id(name),
        interval_us,
        policy=INTERVAL_POLICY,
    )


def request_data_streams(link: VehicleLink, rate_hz: int = FALLBACK_RATE_HZ) -> None:
    """The pre-MAVLink-2 way: no acknowledgement, so sent once per stream group."""
    for stream in FALLBACK_STREAMS:
        link.send(
            link.codec.request_data_stream_encode(link.sysid, link.compid, stream, rate_hz, 1)
        )
