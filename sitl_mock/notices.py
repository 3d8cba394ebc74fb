"""What a vehicle tells its ground station unasked about its mission and its readiness:
MISSION_ITEM_REACHED, the STATUSTEXTs that go with items, and the periodic pre-arm report.

ArduPilot queues MISSION_ITEM_REACHED in one slot per link, so items finished in the same
loop are reported once, by the last of them (`GCS::send_mission_item_reached_message`):
the take-off is usually never reported because the DO item after it completes at once.
It reports DO items, and never NAV_LAND (landing disarms, and disarming resets the
mission). PX4 reports each navigation item and repeats the report a second later.
"""

from __future__ import annotations

from collections.abc import Callable

from .codec import Message, mavlink
from .flavour import Flavour
from .mission_item import NAV_COMMANDS, MissionItem
from .readiness import PREARM_PERIOD_S

PX4_REACHED_REPEAT_S = 1.0
ITEM_NAMES = {
    mavlink.MAV_CMD_NAV_WAYPOINT: "WP",
    mavlink.MAV_CMD_NAV_LOITER_UNLIM: "LoitUnlim",
    mavlink.MAV_CMD_NAV_LOITER_TIME: "LoitTime",
    mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH: "RTL",
    mavlink.MAV_CMD_NAV_LAND: "Land",
    mavlink.MAV_CMD_NAV_TAKEOFF: "Takeoff",
    mavlink.MAV_CMD_DO_CHANGE_SPEED: "ChangeSpeed",
}
"""`AP_Mission::Mission_Command::type()` names, as in "Mission: 3 WP"."""
REACHED_TEXT_FOR = frozenset({mavlink.MAV_CMD_NAV_WAYPOINT})
"""Items whose completion ArduCopter also announces ("Reached command #3")."""

Send = Callable[[Message], None]
Say = Callable[[int, str], None]


class Notices:
    """Collects one vehicle's mission events during a step and reports them as its autopilot."""

    def __init__(self, flavour: Flavour, send: Send, say: Say) -> None:
        self._flavour = flavour
        self._send = send
        self._say = say
        self._reached: list[int] = []
        self._repeat: tuple[int, float] | None = None
        self._next_prearm = PREARM_PERIOD_S

    def reset(self, boot_time: float) -> None:
        self._reached.clear()
        self._repeat = None
        self._next_prearm = boot_time + PREARM_PERIOD_S

    def item_started(self, item: MissionItem) -> None:
        if self._flavour.announces_items:
            name = ITEM_NAMES.get(item.command, str(item.command))
            self._say(mavlink.MAV_SEVERITY_INFO, f"Mission: {item.seq} {name}")

    def item_reached(self, item: MissionItem) -> None:
        if self._flavour.merges_item_reached:
            if item.command == mavlink.MAV_CMD_NAV_LAND:
                return
            if item.command in REACHED_TEXT_FOR and self._flavour.announces_items:
                self._say(mavlink.MAV_SEVERITY_INFO, f"Reached command #{item.seq}")
        elif item.command not in NAV_COMMANDS:
            return
        self._reached.append(item.seq)

    def flush(self, now: float) -> None:
        """End of a step: send what was reached in it (ArduPilot: only the last)."""
        reached, self._reached = self._reached, []
        if self._flavour.merges_item_reached:
            reached = reached[-1:]
        for seq in reached:
            self._send(mavlink.MAVLink_mission_item_reached_message(seq))
        if self._flavour.repeats_item_reached and reached:
            self._repeat = (reached[-1], now + PX4_REACHED_REPEAT_S)
        if self._repeat is not None and now >= self._repeat[1]:
            self._send(mavlink.MAVLink_mission_item_reached_message(self._repeat[0]))
            self._repeat = None

    def prearm(self, now: float, texts: Callable[[], list[str]]) -> None:
        """Every 30 s: each pre-arm check failing now, as "PreArm: ..." (nothing if none)."""
        if now < self._next_prearm:
            return
        self._next_prearm = now + PREARM_PERIOD_S
        for text in texts():
            self._say(mavlink.MAV_SEVERITY_CRITICAL, text)
