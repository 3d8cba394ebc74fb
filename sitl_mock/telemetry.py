"""Which messages stream at what rate (simulated time), and the requests that change it:
SET_MESSAGE_INTERVAL (per message) and REQUEST_DATA_STREAM (ArduPilot's stream groups)."""

from __future__ import annotations

import math

from .codec import mavlink as S

HEARTBEAT_INTERVAL_S = 1.0
TIME_EPSILON_S = 1e-6
"""Due times are sums of floats; this keeps a 0.1 s stream on 0.1 s and not 0.12 s."""

DEFAULT_RATES_HZ: dict[int, float] = {
    S.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    S.MAVLINK_MSG_ID_GPS_RAW_INT: 1.0,
    S.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 5.0,
    S.MAVLINK_MSG_ID_ATTITUDE: 10.0,
    S.MAVLINK_MSG_ID_VFR_HUD: 4.0,
    S.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
    S.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 1.0,
    S.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,
}
"""Rates when streaming by default (PX4) or once asked for ALL streams at their defaults."""

STREAM_GROUPS: dict[int, tuple[int, ...]] = {
    S.MAV_DATA_STREAM_EXTENDED_STATUS: (
        S.MAVLINK_MSG_ID_SYS_STATUS,
        S.MAVLINK_MSG_ID_GPS_RAW_INT,
        S.MAVLINK_MSG_ID_MISSION_CURRENT,
        S.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
    ),
    S.MAV_DATA_STREAM_POSITION: (S.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,),
    S.MAV_DATA_STREAM_EXTRA1: (S.MAVLINK_MSG_ID_ATTITUDE,),
    S.MAV_DATA_STREAM_EXTRA2: (S.MAVLINK_MSG_ID_VFR_HUD,),
    S.MAV_DATA_STREAM_EXTRA3: (S.MAVLINK_MSG_ID_HOME_POSITION,),
}
"""ArduCopter's REQUEST_DATA_STREAM groups, restricted to the messages simulated here."""


UNASKED_ARDUPILOT_S: dict[int, float] = {S.MAVLINK_MSG_ID_TIMESYNC: 10.0}
"""What ArduCopter sends besides HEARTBEAT before anyone asks, every so many seconds (its
first after one interval). HOME_POSITION and GPS_GLOBAL_ORIGIN come on events instead."""


class TelemetrySchedule:
    """Per-message intervals and next due times; `due` returns what to send now."""

    def __init__(
        self,
        stream_by_default: bool,
        streamable: frozenset[int],
        unasked_s: dict[int, float] | None = None,
    ) -> None:
        self._streamable = streamable
        self._unasked = dict(unasked_s or {})
        self._intervals: dict[int, float] = {}
        self._next: dict[int, float] = {}
        self._next_any = math.inf
        self.reset(stream_by_default, now=0.0)

    def reset(self, stream_by_default: bool, now: float) -> None:
        self._intervals.clear()
        self._next.clear()
        self._next_any = math.inf
        self.set_interval(S.MAVLINK_MSG_ID_HEARTBEAT, HEARTBEAT_INTERVAL_S, now)
        for msg_id, seconds in self._unasked.items():
            self.set_interval(msg_id, seconds, now + seconds)
        if stream_by_default:
            for msg_id, rate in DEFAULT_RATES_HZ.items():
                self.set_interval(msg_id, 1.0 / rate, now)

    def interval(self, msg_id: int) -> float | None:
        return self._intervals.get(msg_id)

    def can_stream(self, msg_id: int) -> bool:
        return msg_id in self._streamable

    def set_interval(self, msg_id: int, seconds: float | None, now: float) -> None:
        """Stream `msg_id` every `seconds` (None stops it)."""
        if seconds is None or seconds <= 0:
            self._intervals.pop(msg_id, None)
            self._next.pop(msg_id, None)
            return
        self._intervals[msg_id] = seconds
        self._next[msg_id] = now
        self._next_any = min(self._next_any, now)

    def set_message_interval(self, msg_id: int, interval_us: float, now: float) -> bool:
        """SET_MESSAGE_INTERVAL semantics: -1 off, 0 default rate, else microseconds."""
        if not self.can_stream(msg_id):
            return False
        if interval_us < 0:
            self.set_interval(msg_id, None, now)
        elif interval_us == 0:
            default = DEFAULT_RATES_HZ.get(msg_id, 1.0)
            self.set_interval(msg_id, 1.0 / default, now)
        else:
            self.set_interval(msg_id, interval_us / 1e6, now)
        return True

    def request_data_stream(self, stream_id: int, rate_hz: float, start: bool, now: float) -> None:
        groups = (
            STREAM_GROUPS.values()
            if stream_id == S.MAV_DATA_STREAM_ALL
            else ([STREAM_GROUPS[stream_id]] if stream_id in STREAM_GROUPS else [])
        )
        for group in groups:
            for msg_id in group:
                on = start and rate_hz > 0
                self.set_interval(msg_id, 1.0 / rate_hz if on else None, now)

    def due(self, now: float) -> list[int]:
        """What to send now. After its first, a stream falls on multiples of its interval
        (of simulated time), so a fleet's vehicles send the same streams on the same steps
        (and the simulator converts their positions once for all of them)."""
        now += TIME_EPSILON_S
        if now < self._next_any:
            return []
        sending = [msg_id for msg_id, at in self._next.items() if at <= now]
        for msg_id in sending:
            interval = self._intervals[msg_id]
            self._next[msg_id] = (math.floor(now / interval) + 1) * interval
        self._next_any = min(self._next.values(), default=math.inf)
        return sending
