"""The vehicle side of the MAVLink mission protocol: upload, download, clear, set current.

Uploads are staged and swapped in only when complete, so a failed, timed-out or
interrupted upload leaves the previous mission intact. Every time here (`now` of `handle`
and `tick`) is the protocol clock, which the vehicle feeds with WALL-clock seconds: a real
autopilot's re-request and cancel timers count real milliseconds, whatever the speed-up,
so a ground station's step timeouts meet them as on a real link. Messages go out through
an `Outbox`; nothing here touches a socket.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar, Protocol

from . import fence
from .codec import Message, Sender, mavlink
from .flavour import Flavour
from .mission_item import NAV_COMMANDS, SUPPORTED_FRAMES, MissionItem, same_item

MISSION, FENCE, RALLY, ALL = (
    mavlink.MAV_MISSION_TYPE_MISSION,
    mavlink.MAV_MISSION_TYPE_FENCE,
    mavlink.MAV_MISSION_TYPE_RALLY,
    mavlink.MAV_MISSION_TYPE_ALL,
)

SUPPORTED_COMMANDS: dict[int, frozenset[int]] = {
    MISSION: NAV_COMMANDS | {mavlink.MAV_CMD_DO_CHANGE_SPEED},
    FENCE: frozenset(
        {
            mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
            mavlink.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
            mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
        }
    ),
    RALLY: frozenset({mavlink.MAV_CMD_NAV_RALLY_POINT}),
}

DEFAULT_CAPACITY = 700


class Outbox(Protocol):
    def send(self, msg: Message) -> None: ...

    def say(self, severity: int, text: str) -> None: ...


@dataclass
class _Upload:
    sender: Sender
    mission_type: int
    count: int
    staged: list[MissionItem] = field(default_factory=list)
    last_heard: float = 0.0
    last_request: float = 0.0

    @property
    def expected(self) -> int:
        return len(self.staged)


@dataclass(frozen=True)
class _Completed:
    """The last finished upload, so a re-sent final item (lost ACK) can be re-acknowledged."""

    sender: Sender
    mission_type: int
    last_item: MissionItem


class MissionStore:
    """Mission, fence and rally lists and the transfer state machine over them."""

    def __init__(
        self,
        flavour: Flavour,
        out: Outbox,
        home_item: Callable[[], MissionItem],
        capacity: int = DEFAULT_CAPACITY,
    ) -> None:
        self.flavour = flavour
        self.capacity = capacity
        self.reject_at: str | None = None
        """Fault: "count" or "last_item" makes uploads fail there with MAV_MISSION_ERROR."""
        self.started = False
        """A mission has run (or a current item was set) since it was stored: ArduPilot
        reports MISSION_CURRENT seq 0 before that."""
        self._legacy_warned = False
        self.storage_ready = True
        """False while booting: ArduPilot's mission storage then holds 0 items (NO_SPACE)."""
        self.on_mission_changed: Callable[[], None] = lambda: None
        self.on_current_changed: Callable[[], None] = lambda: None
        self._out = out
        self._home_item = home_item
        self._lists: dict[int, list[MissionItem]] = {MISSION: [], FENCE: [], RALLY: []}
        self.fence_version = 0
        """Counts the fences stored: the flight controller re-reads the zones when it changes."""
        self._upload: _Upload | None = None
        self._completed: _Completed | None = None
        self.current = self.first_item

    # -- what the vehicle holds -------------------------------------------------------------

    @property
    def first_item(self) -> int:
        """Index of the first flyable item (1 after ArduPilot's home item)."""
        return 1 if self.flavour.home_is_item_zero else 0

    def items(self, mission_type: int = MISSION) -> list[MissionItem]:
        """The stored list as a download returns it (ArduPilot: current home as item 0)."""
        stored = self._lists[mission_type]
        if mission_type == MISSION and self.flavour.home_is_item_zero:
            return [self._home_item(), *stored[1:]]
        return list(stored)

    @property
    def total(self) -> int:
        """Flyable items (MISSION_CURRENT.total excludes ArduPilot's home)."""
        return max(0, len(self._lists[MISSION]) - self.first_item)

    @property
    def reported_current(self) -> int:
        """MISSION_CURRENT.seq: 0 without a mission and (ArduPilot) until one has run."""
        if not self.total or (self.flavour.home_is_item_zero and not self.started):
            return 0
        return self.current

    @property
    def uploading(self) -> bool:
        return self._upload is not None

    def set_current(self, seq: int) -> bool:
        if not self.first_item <= seq < len(self._lists[MISSION]):
            return False
        self.current = seq
        self.started = True
        return True

    def load(self, items: list[MissionItem], mission_type: int = MISSION) -> None:
        """Replace a list directly, as if uploaded (for tests and scripted set-ups)."""
        self._replace(mission_type, [item.with_seq(seq) for seq, item in enumerate(items)])

    def reset(self) -> None:
        """Forget everything (a reboot)."""
        for items in self._lists.values():
            items.clear()
        self._upload = None
        self._completed = None
        self.current = self.first_item
        self.started = False
        self.on_mission_changed()

    # -- the protocol -----------------------------------------------------------------------

    def handle(self, msg: Message, sender: Sender, now: float) -> None:
        handler = self._handlers.get(msg.get_type())
        if handler is not None:
            handler(self, msg, sender, now)

    def tick(self, now: float) -> None:
        """Re-request a missing item, or give up after the flavour's timeout."""
        upload = self._upload
        if upload is None:
            return
        if now - upload.last_heard >= self.flavour.upload_timeout_s:
            self._upload = None
            self._ack(upload.sender, upload.mission_type, mavlink.MAV_MISSION_OPERATION_CANCELLED)
            name = {FENCE: "Fence", RALLY: "Rally"}.get(upload.mission_type, "Mission")
            self._out.say(mavlink.MAV_SEVERITY_WARNING, f"{name} upload timeout")
        elif now - upload.last_request >= self.flavour.rerequest_s:
            self._request(upload, now)

    @property
    def room(self) -> int:
        """How many items an upload may have now (0 until the storage is ready)."""
        return self.capacity if self.storage_ready else 0

    def _on_count(self, msg: Message, sender: Sender, now: float) -> None:
        mission_type = msg.mission_type
        if mission_type not in self._lists:
            self._ack(sender, mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
            return
        if self._upload is not None:
            if self._upload.sender != sender:
                self._ack(sender, mission_type, mavlink.MAV_MISSION_DENIED)
                return
            self._upload = None  # the same GCS restarts its upload
        if self.reject_at == "count":
            self._ack(sender, mission_type, mavlink.MAV_MISSION_ERROR)
        elif msg.count > self.room:
            self._ack(sender, mission_type, mavlink.MAV_MISSION_NO_SPACE)
            self._out.say(mavlink.MAV_SEVERITY_WARNING, f"Only {self.room} items are supported")
        elif msg.count == 0:
            self._replace(mission_type, [])
            self._ack(sender, mission_type, mavlink.MAV_MISSION_ACCEPTED)
        else:
            self._upload = _Upload(sender, mission_type, msg.count, last_heard=now)
            self._legacy_warned = False
            self._request(self._upload, now)

    def _on_item(self, msg: Message, sender: Sender, now: float) -> None:
        upload = self._upload
        mission_type = msg.mission_type
        if upload is None:
            self._answer_stray_item(MissionItem.from_message(msg), sender)
            return
        if upload.sender != sender or upload.mission_type != mission_type:
            self._ack(sender, mission_type, mavlink.MAV_MISSION_DENIED)
            return
        if msg.seq != upload.expected:
            self._ack(sender, mission_type, mavlink.MAV_MISSION_INVALID_SEQUENCE)
            return
        item = MissionItem.from_message(msg)
        problem = self._problem_with(item, upload)
        if problem is not None:
            self._upload = None
            self._ack(sender, mission_type, problem)
            return
        upload.staged.append(item)
        upload.last_heard = now
        if upload.expected < upload.count:
            self._request(upload, now)
        else:
            self._finish(upload)

    def _answer_stray_item(self, item: MissionItem, sender: Sender) -> None:
        done = self._completed
        if (
            done is not None
            and done.sender == sender
            and done.mission_type == item.mission_type
            and same_item(done.last_item, item)
        ):
            self._ack(sender, item.mission_type, mavlink.MAV_MISSION_ACCEPTED)
        else:
            self._ack(sender, item.mission_type, mavlink.MAV_MISSION_ERROR)

    def _problem_with(self, item: MissionItem, upload: _Upload) -> int | None:
        """The MAV_MISSION_RESULT that rejects this item, or None."""
        if upload.mission_type == MISSION and item.seq < self.first_item:
            return None  # ArduPilot overwrites item 0 with home
        if self._ardupilot and upload.mission_type == FENCE:
            return fence.fence_item_refusal(item)
        if self._ardupilot and upload.mission_type == RALLY:
            return fence.rally_item_refusal(item)
        if item.frame not in SUPPORTED_FRAMES:
            return int(mavlink.MAV_MISSION_UNSUPPORTED_FRAME)
        if item.command not in SUPPORTED_COMMANDS[upload.mission_type]:
            return int(mavlink.MAV_MISSION_UNSUPPORTED)
        if upload.mission_type == MISSION:
            return self.flavour.item_refusal(item)
        return None

    def _finish(self, upload: _Upload) -> None:
        self._upload = None
        if self.reject_at == "last_item":
            self._ack(upload.sender, upload.mission_type, mavlink.MAV_MISSION_ERROR)
            return
        if (
            self._ardupilot
            and upload.mission_type == FENCE
            and not fence.fence_list_valid(upload.staged)
        ):
            self._ack(upload.sender, upload.mission_type, mavlink.MAV_MISSION_ERROR)
            return  # AC_PolyFence_loader::write_fence refuses it; the old fence stays
        self._replace(upload.mission_type, upload.staged)
        self._completed = _Completed(upload.sender, upload.mission_type, upload.staged[-1])
        self._ack(upload.sender, upload.mission_type, mavlink.MAV_MISSION_ACCEPTED)
        if upload.mission_type == MISSION:
            self._out.say(mavlink.MAV_SEVERITY_INFO, "Flight plan received")

    @property
    def _ardupilot(self) -> bool:
        return self.flavour.home_is_item_zero

    def _replace(self, mission_type: int, items: list[MissionItem]) -> None:
        if mission_type == MISSION:
            items = [self.flavour.store_item(item) for item in items]
        elif self._ardupilot:
            keep = fence.stored_fence_item if mission_type == FENCE else fence.stored_rally_item
            items = [keep(item) for item in items]
        if mission_type == FENCE:
            self.fence_version += 1
        if mission_type == MISSION and items and self.flavour.home_is_item_zero:
            items = [self._home_item(), *items[1:]]
        self._lists[mission_type] = list(items)
        if mission_type == MISSION:
            self.current = self.first_item
            self.started = False
            self.on_mission_changed()

    def _on_request_list(self, msg: Message, sender: Sender, now: float) -> None:
        if msg.mission_type not in self._lists:
            self._ack(sender, msg.mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
        elif self._upload is not None:
            self._ack(sender, msg.mission_type, mavlink.MAV_MISSION_DENIED)
        else:
            count = len(self.items(msg.mission_type))
            self._out.send(
                mavlink.MAVLink_mission_count_message(
                    sender.sysid, sender.compid, count, msg.mission_type
                )
            )

    def _on_request(self, msg: Message, sender: Sender, now: float) -> None:
        """Download of one item. ArduPilot refuses MISSION_REQUEST_INT (not the legacy
        request) while an upload is open, and warns once per upload about the legacy one."""
        legacy = msg.get_type() == "MISSION_REQUEST"
        if msg.mission_type not in self._lists:
            self._ack(sender, msg.mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
            return
        if self._upload is not None and not legacy and self.flavour.home_is_item_zero:
            self._ack(sender, msg.mission_type, mavlink.MAV_MISSION_DENIED)
            return
        items = self.items(msg.mission_type)
        if not 0 <= msg.seq < len(items):
            self._ack(sender, msg.mission_type, mavlink.MAV_MISSION_INVALID_SEQUENCE)
            return
        item = items[msg.seq]
        if not legacy:
            self._out.send(item.to_item_int(sender.sysid, sender.compid))
            return
        self._out.send(item.to_item(sender.sysid, sender.compid))
        if self.flavour.home_is_item_zero and not self._legacy_warned:
            self._legacy_warned = True
            self._out.say(
                mavlink.MAV_SEVERITY_WARNING, "got MISSION_REQUEST; use MISSION_REQUEST_INT!"
            )

    def _on_clear_all(self, msg: Message, sender: Sender, now: float) -> None:
        if self._upload is not None:
            self._ack(sender, msg.mission_type, mavlink.MAV_MISSION_DENIED)
            return
        if msg.mission_type != ALL and msg.mission_type not in self._lists:
            self._ack(sender, msg.mission_type, mavlink.MAV_MISSION_UNSUPPORTED)
            return
        for mission_type in self._lists:
            if msg.mission_type in (ALL, mission_type):
                self._replace(mission_type, [])
        self._ack(sender, msg.mission_type, mavlink.MAV_MISSION_ACCEPTED)

    def _on_set_current(self, msg: Message, sender: Sender, now: float) -> None:
        if self.set_current(msg.seq):
            self.on_current_changed()

    _handlers: ClassVar[dict[str, Callable[[MissionStore, Message, Sender, float], None]]] = {
        "MISSION_COUNT": _on_count,
        "MISSION_ITEM_INT": _on_item,
        "MISSION_ITEM": _on_item,
        "MISSION_REQUEST_LIST": _on_request_list,
        "MISSION_REQUEST_INT": _on_request,
        "MISSION_REQUEST": _on_request,
        "MISSION_CLEAR_ALL": _on_clear_all,
        "MISSION_SET_CURRENT": _on_set_current,
    }

    # -- replies ----------------------------------------------------------------------------

    def _request(self, upload: _Upload, now: float) -> None:
        upload.last_request = now
        target = upload.sender
        if self.flavour.item_request_id == mavlink.MAVLINK_MSG_ID_MISSION_REQUEST:
            msg = mavlink.MAVLink_mission_request_message(
                target.sysid, target.compid, upload.expected, upload.mission_type
            )
        else:
            msg = mavlink.MAVLink_mission_request_int_message(
                target.sysid, target.compid, upload.expected, upload.mission_type
            )
        self._out.send(msg)

    def _ack(self, target: Sender, mission_type: int, result: int) -> None:
        self._out.send(
            mavlink.MAVLink_mission_ack_message(target.sysid, target.compid, result, mission_type)
        )
