"""The MAVLink client over an in-memory transport: no sockets, no threads.

As httpx's MockTransport answers requests with a function, `Peer` answers what the
ground station sends with a function of the message: each test scripts the autopilot
behaviour it needs (a boot that refuses uploads, refusals with several texts, ArduPilot's
rebuilt items) and drives the real link, command and mission-protocol code against it.
"""

from __future__ import annotations

import asyncio
import itertools
import math
from collections.abc import Callable
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink import client
from gcs.mavlink.actions import FlightActions, is_not_ready
from gcs.mavlink.commands import CommandPolicy, send_command
from gcs.mavlink.connection import MavConnection
from gcs.mavlink.errors import CommandFailedError, CommandTimeoutError, VehicleRebootedError
from gcs.mavlink.link import LinkEvent, LinkSettings, VehicleLink
from gcs.mavlink.mission_item import Autopilot, Command, Frame, Mission, MissionItem
from gcs.mavlink.mission_protocol import MissionClient, TransferPolicy
from gcs.mavlink.mode_history import LATE_COPY_S
from gcs.mavlink.telemetry import TelemetryStreams
from gcs.mavlink.transport import MemoryTransport

Reply = Callable[[Any], list[Any]]
SETTINGS = LinkSettings(connect_timeout_s=2.0, request_streams=False)


class Peer:
    """A scripted autopilot (system 1) on the far end of an in-memory pair."""

    def __init__(self, transport: MemoryTransport, reply: Reply) -> None:
        self.transport, self.reply = transport, reply
        self.codec = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        self.parser = mavlink2.MAVLink(None)
        self.heard: list[Any] = []
        self.status = mavlink2.MAV_STATE_STANDBY
        transport.set_receiver(self._received)

    def _received(self, data: bytes, _peer: object) -> None:
        for msg in self.parser.parse_buffer(data) or ():
            self.heard.append(msg)
            for answer in self.reply(msg):
                self.send(answer)

    def send(self, msg: Any) -> None:
        self.transport.send(msg.pack(self.codec))

    def heartbeat(self) -> None:
        self.send(
            self.codec.heartbeat_encode(
                mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0x51, 0,
                self.status,
            )
        )  # fmt: skip

    def sent(self, kind: str) -> list[Any]:
        return [m for m in self.heard if m.get_type() == kind]


async def linked(reply: Reply) -> tuple[VehicleLink, Peer]:
    ours, theirs = MemoryTransport.pair()
    peer = Peer(theirs, reply)
    connection = MavConnection(ours, heartbeat=False)
    attaching = asyncio.ensure_future(client.attach(connection, settings=SETTINGS, owns=True))
    peer.send(peer.codec.heartbeat_encode(mavlink2.MAV_TYPE_GCS, 8, 0, 0, 4))  # not it
    peer.heartbeat()
    return await attaching, peer


def silent(msg: Any) -> list[Any]:
    return []


async def test_the_link_finds_the_autopilot_not_another_ground_station() -> None:
    link, _ = await linked(silent)
    try:
        assert (link.sysid, link.autopilot) == (1, Autopilot.ARDUPILOT)
    finally:
        await link.close()


async def test_a_refusal_carries_every_text_of_its_attempt() -> None:
    """ArduCopter explains one refused arming with several STATUSTEXTs after its ACK."""
    link, peer = await linked(silent)

    def refuse(msg: Any) -> list[Any]:
        if msg.get_type() != "COMMAND_LONG":
            return []
        texts = ["Arm: Accels inconsistent", "Arm: EKF attitude is bad"]
        ack = peer.codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_FAILED)
        return [ack, *(peer.codec.statustext_encode(3, t.encode()) for t in texts)]

    peer.reply = refuse
    try:
        with pytest.raises(CommandFailedError) as caught:
            await FlightActions(link).arm()
        assert caught.value.statustext == "Arm: Accels inconsistent; Arm: EKF attitude is bad"
        assert is_not_ready(caught.value)
    finally:
        await link.close()


async def test_an_unanswered_command_is_resent_with_its_confirmation_counted() -> None:
    link, peer = await linked(silent)
    policy = CommandPolicy(timeout_s=0.05, retries=2)
    try:
        with pytest.raises(CommandTimeoutError, match="not acknowledged after 3 attempts"):
            await send_command(link, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 1, policy=policy)
        assert [m.confirmation for m in peer.sent("COMMAND_LONG")] == [0, 1, 2]
    finally:
        await link.close()


class SlowModeChanges:
    """Answers a DO_SET_MODE's first attempt after `first_s` and a re-sent one after
    `again_s`, and loses the first attempt of a LAND."""

    def __init__(self, first_s: float, again_s: float) -> None:
        self.peer: Peer | None = None
        self.first_s, self.again_s = first_s, again_s
        self.answered: list[tuple[int, int]] = []  # (mode, confirmation)

    def __call__(self, msg: Any) -> list[Any]:
        if msg.get_type() != "COMMAND_LONG" or msg.command != mavlink2.MAV_CMD_DO_SET_MODE:
            return []
        mode = int(msg.param2)
        if mode == LAND and msg.confirmation == 0:
            return []
        delay = self.again_s if msg.confirmation else self.first_s
        asyncio.get_running_loop().call_later(delay, self._answer, mode, msg.confirmation)
        return []

    def _answer(self, mode: int, confirmation: int) -> None:
        assert self.peer is not None
        self.answered.append((mode, confirmation))
        ack = self.peer.codec.command_ack_encode(
            mavlink2.MAV_CMD_DO_SET_MODE, mavlink2.MAV_RESULT_ACCEPTED
        )
        self.peer.send(ack)


RTL, LAND = 6, 9  # ArduCopter's custom modes


@pytest.mark.virtual_clock
async def test_a_late_answer_to_a_resent_command_does_not_end_the_next_of_its_number() -> None:
    """An operator's RTL is re-sent (the first ACK is slow), the first ACK ends it, and the
    abort's LAND goes out and is lost. The re-sent RTL's ACK, still on its way, must not
    be taken for the LAND's: a COMMAND_ACK names only the command's number (DO_SET_MODE
    for both). Found by fuzzed flight 2140, where the vehicle stayed in RTL through the
    abort."""
    autopilot = SlowModeChanges(first_s=0.25, again_s=0.1)
    link, peer = await linked(autopilot)
    autopilot.peer = peer
    actions = FlightActions(link, CommandPolicy(timeout_s=0.2, retries=3))
    try:
        await actions.return_to_launch()
        await actions.land()
        assert (LAND, 1) in autopilot.answered  # the LAND was answered, not taken as done
        lands = [m.confirmation for m in peer.sent("COMMAND_LONG") if m.param2 == LAND]
        assert lands == [0, 1]
    finally:
        await link.close()


class SlowPauses:
    """Answers a DO_PAUSE_CONTINUE's continue after `continue_s` and loses the first
    pause sent to it."""

    def __init__(self, continue_s: float) -> None:
        self.peer: Peer | None = None
        self.continue_s = continue_s
        self.heard_pauses = 0
        self.answered: list[int] = []  # 1: a continue, 0: a pause

    def __call__(self, msg: Any) -> list[Any]:
        if msg.get_type() != "COMMAND_LONG" or msg.command != PAUSE_CONTINUE:
            return []
        go = int(msg.param1)
        if go == 0:
            self.heard_pauses += 1
            if self.heard_pauses == 1:
                return []  # lost
        delay = self.continue_s if go else 0.0
        asyncio.get_running_loop().call_later(delay, self._answer, go)
        return []

    def _answer(self, go: int) -> None:
        assert self.peer is not None
        self.answered.append(go)
        self.peer.send(self.peer.codec.command_ack_encode(PAUSE_CONTINUE, 0))


PAUSE_CONTINUE = mavlink2.MAV_CMD_DO_PAUSE_CONTINUE


@pytest.mark.virtual_clock
async def test_an_answer_owed_to_a_given_up_command_does_not_end_the_next_of_its_number() -> None:
    """The passing order's continue is cancelled on its way (the operator holds the
    fleet); its ACK comes after the wait for it has run out, while the operator's pause,
    lost, waits for its own. The pause must not take that ACK: it is sent again (fuzzed
    flight 14852: the vehicle crept on through the hold, 3.04 m from another)."""
    autopilot = SlowPauses(continue_s=0.35)
    link, peer = await linked(autopilot)
    autopilot.peer = peer
    actions = FlightActions(link, CommandPolicy(timeout_s=0.2, retries=3))
    try:
        going = asyncio.ensure_future(actions.resume())
        await asyncio.sleep(0.05)  # the continue is out
        going.cancel()
        await asyncio.sleep(0.2)  # its wait has run out: the next of its number may go
        await actions.pause()
        assert autopilot.heard_pauses == 2  # the lost one sent again
        assert autopilot.answered == [1, 0]  # the continue's late, then the pause's
    finally:
        await link.close()


class ModeSwitches:
    """ArduCopter's mode switches, accepted at once; its mode goes out in a HEARTBEAT when
    the test says so (a late copy of an earlier switch is the test setting `mode`)."""

    def __init__(self) -> None:
        self.peer: Peer | None = None
        self.mode = 0
        self.speeds: list[float] = []

    def __call__(self, msg: Any) -> list[Any]:
        assert self.peer is not None
        if msg.get_type() != "COMMAND_LONG":
            return []
        if msg.command == mavlink2.MAV_CMD_DO_SET_MODE:
            self.mode = int(msg.param2)
        elif msg.command == mavlink2.MAV_CMD_DO_CHANGE_SPEED:
            self.speeds.append(msg.param2)
        return [self.peer.codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_ACCEPTED)]

    def heartbeat(self) -> None:
        assert self.peer is not None
        self.peer.send(
            self.peer.codec.heartbeat_encode(
                mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
                mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink2.MAV_MODE_FLAG_SAFETY_ARMED,
                self.mode, mavlink2.MAV_STATE_ACTIVE,
            )
        )  # fmt: skip


BRAKE, AUTO = 17, 3


async def linked_switches() -> tuple[ModeSwitches, VehicleLink, Peer]:
    autopilot = ModeSwitches()
    link, peer = await linked(autopilot)
    autopilot.peer = peer
    return autopilot, link, peer


@pytest.mark.virtual_clock
@pytest.mark.parametrize(
    ("seen", "after_s", "undone"),
    [(RTL, 0.3, True), (RTL, LATE_COPY_S + 0.1, False), (BRAKE, 0.3, False)],
    ids=["late-copy", "long-after", "never-asked"],
)
async def test_a_late_copy_of_an_earlier_mode_switch_is_switched_back(
    seen: int, after_s: float, undone: bool
) -> None:
    """RTL, then LAND, which is sent once more at once (a copy of the RTL held up on the
    way comes in right behind the packet that overtook it); a HEARTBEAT then shows RTL
    again: a re-sent RTL arrived after the LAND (fuzzed flight 3621). The LAND is made
    again. Much later, or a mode not asked for (the autopilot's own, a failsafe's), is
    left as it is."""
    autopilot, link, peer = await linked_switches()
    actions = FlightActions(link)
    try:
        await actions.return_to_launch()
        await actions.land()
        await asyncio.sleep(after_s)
        autopilot.mode = seen
        autopilot.heartbeat()
        await asyncio.sleep(0.5)
        assert autopilot.mode == (LAND if undone else seen)
        switches = [m.param2 for m in peer.sent("COMMAND_LONG") if m.param2 in (RTL, LAND)]
        assert switches == [RTL, LAND, LAND] + [LAND] * undone  # once more at once, then seen
    finally:
        await link.close()


@pytest.mark.virtual_clock
async def test_auto_made_again_after_a_late_brake_gets_its_speed_again() -> None:
    """The order's brake, then its go (AUTO at 3 m/s); a late copy of the brake is undone
    with AUTO and, since ArduCopter forgets a speed on entering AUTO, the speed again."""
    autopilot, link, _ = await linked_switches()
    actions = FlightActions(link)
    try:
        await actions.brake_in_mission()
        await actions.approach(3.0)
        await asyncio.sleep(0.1)
        given = len(autopilot.speeds)
        autopilot.mode = BRAKE
        autopilot.heartbeat()
        await asyncio.sleep(0.5)
        assert autopilot.mode == AUTO
        assert autopilot.speeds[given:] == [3.0]
    finally:
        await link.close()


class PauseContinue:
    """ArduCopter's DO_PAUSE_CONTINUE: accepted, except a pause where it already stopped
    (at its waypoint: FAILED)."""

    def __init__(self) -> None:
        self.peer: Peer | None = None
        self.paused = False

    def __call__(self, msg: Any) -> list[Any]:
        assert self.peer is not None
        if msg.get_type() != "COMMAND_LONG":
            return []
        result = mavlink2.MAV_RESULT_ACCEPTED
        if msg.param1 == 0 and self.paused:
            result = mavlink2.MAV_RESULT_FAILED
        self.paused = msg.param1 == 0
        return [self.peer.codec.command_ack_encode(msg.command, result)]


@pytest.mark.virtual_clock
@pytest.mark.parametrize(
    ("between_s", "again"), [(0.3, True), (LATE_COPY_S + 0.1, False)], ids=["soon", "long-after"]
)
async def test_a_pause_right_after_a_continue_is_sent_once_more(
    between_s: float, again: bool
) -> None:
    """A continue, then a pause: a re-sent copy of the continue held up on the way would
    come in right behind the pause and send the vehicle on, so the pause goes once more
    at once (its FAILED, already stopped, is no error); the same for a continue after a
    pause. Long after, once is enough."""
    autopilot = PauseContinue()
    link, peer = await linked(autopilot)
    autopilot.peer = peer
    actions = FlightActions(link)
    try:
        await actions.resume()
        await asyncio.sleep(between_s)
        await actions.pause()
        await asyncio.sleep(between_s)
        await actions.resume()
        sent = [int(m.param1) for m in peer.sent("COMMAND_LONG")]
        assert sent == ([1, 0, 0, 1, 1] if again else [1, 0, 1])
    finally:
        await link.close()


class CurrentItem:
    """An autopilot flying item 4, which it says in every MISSION_CURRENT it streams; it
    loses the first DO_SET_MISSION_CURRENT (or answers UNSUPPORTED, as one without the
    command would) and counts the times it was made to fly an item afresh."""

    def __init__(self, supported: bool) -> None:
        self.peer: Peer | None = None
        self.supported = supported
        self.jumps = 0

    def __call__(self, msg: Any) -> list[Any]:
        assert self.peer is not None
        codec = self.peer.codec
        if msg.get_type() == "MISSION_SET_CURRENT":
            self.jumps += 1
            return [codec.mission_current_encode(msg.seq)]
        if msg.get_type() != "COMMAND_LONG":
            return []
        if not self.supported:
            return [codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_UNSUPPORTED)]
        if msg.confirmation == 0:
            return [codec.mission_current_encode(4)]  # the stream goes on; the command is lost
        self.jumps += 1
        return [
            codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_ACCEPTED),
            codec.mission_current_encode(int(msg.param1)),
        ]


@pytest.mark.virtual_clock
@pytest.mark.parametrize("supported", [True, False], ids=["command", "message"])
async def test_the_current_item_is_set_by_an_acknowledged_command(supported: bool) -> None:
    """The vehicle flies item 4 and streams MISSION_CURRENT 4; making 4 current again
    (an approach flies it afresh) is done only once the vehicle says so: its ACK. The
    stream answered the message even when the message was lost (fuzzed flights 3569 and
    3790). Without the command, the message is sent."""
    autopilot = CurrentItem(supported)
    link, peer = await linked(autopilot)
    autopilot.peer = peer
    try:
        await MissionClient(link).set_current(4)
        assert autopilot.jumps == 1
        commands = [m.confirmation for m in peer.sent("COMMAND_LONG")]
        assert commands == ([0, 1] if supported else [0])
        assert len(peer.sent("MISSION_SET_CURRENT")) == (0 if supported else 1)
    finally:
        await link.close()


class FallsSilent:
    """ArduCopter paused in its mission: it takes the first command of an approach, and
    then its link falls silent."""

    def __init__(self) -> None:
        self.peer: Peer | None = None
        self.taken: list[int] = []

    def __call__(self, msg: Any) -> list[Any]:
        assert self.peer is not None
        if self.taken or msg.get_type() != "COMMAND_LONG":
            return []
        self.taken.append(msg.command)
        codec = self.peer.codec
        replies = [codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_ACCEPTED)]
        if msg.command == mavlink2.MAV_CMD_DO_SET_MISSION_CURRENT:
            replies.append(codec.mission_current_encode(int(msg.param1)))
        return replies


@pytest.mark.virtual_clock
@pytest.mark.parametrize(
    ("speed_first", "taken"),
    [(False, mavlink2.MAV_CMD_DO_SET_MISSION_CURRENT), (True, mavlink2.MAV_CMD_DO_CHANGE_SPEED)],
    ids=["item-first", "speed-first"],
)
async def test_an_approach_cut_off_after_its_first_command(speed_first: bool, taken: int) -> None:
    """An approach from a stop makes the vehicle's item current and gives it its speed.
    Cut off after the item, the vehicle flies it afresh at its mission's speed until its
    failsafe brakes it (fuzzed flight 20276: 4.4 m, 1.3 m past its limit); given its speed
    first, what it took leaves it standing."""
    autopilot = FallsSilent()
    link, peer = await linked(autopilot)
    autopilot.peer = peer
    actions = FlightActions(link, mission=MissionClient(link))
    try:
        with pytest.raises(TimeoutError):
            await actions.approach(0.5, speed_first)
        assert autopilot.taken == [taken]
    finally:
        await link.close()


class StoringAutopilot:
    """ArduPilot's side of the mission protocol, booting first: NO_SPACE until booted,
    items stored and given back as ArduPilot rebuilds them (frame 3, DO items frame 0,
    NaN as 0)."""

    def __init__(self) -> None:
        self.peer: Peer | None = None
        self.count = 0
        self.items: dict[int, Any] = {}

    def __call__(self, msg: Any) -> list[Any]:
        assert self.peer is not None
        codec, kind = self.peer.codec, msg.get_type()
        if kind == "MISSION_COUNT":
            if self.peer.status == mavlink2.MAV_STATE_BOOT:
                return [codec.mission_ack_encode(255, 190, mavlink2.MAV_MISSION_NO_SPACE, 0)]
            self.count = msg.count
            return [codec.mission_request_encode(255, 190, 0, 0)]
        if kind == "MISSION_ITEM_INT":
            self.items[msg.seq] = msg
            if msg.seq + 1 < self.count:
                return [codec.mission_request_encode(255, 190, msg.seq + 1, 0)]
            return [codec.mission_ack_encode(255, 190, mavlink2.MAV_MISSION_ACCEPTED, 0)]
        if kind == "MISSION_REQUEST_LIST":
            return [codec.mission_count_encode(255, 190, self.count, 0)]
        if kind == "MISSION_REQUEST_INT":
            return [self._stored(msg.seq)]
        return []

    def _stored(self, seq: int) -> Any:
        assert self.peer is not None
        item = self.items[seq]
        positioned = item.command != mavlink2.MAV_CMD_DO_CHANGE_SPEED
        frame = (3 if item.frame == 6 else item.frame) if positioned else 0
        params = [0.0 if math.isnan(p) else p for p in (item.param1, item.param2, 0.0, 0.0)]
        if item.command == mavlink2.MAV_CMD_NAV_WAYPOINT:
            params[1] = 0.0  # Copter drops the acceptance radius
        x, y = (item.x, item.y) if positioned else (0, 0)
        return self.peer.codec.mission_item_int_encode(
            255, 190, seq, frame, item.command, 0, 1, *params, x, y, item.z, 0
        )


async def test_an_upload_waits_for_the_boot_and_accepts_what_arducopter_rebuilds() -> None:
    autopilot = StoringAutopilot()
    link, peer = await linked(autopilot)
    autopilot.peer = peer
    peer.status = mavlink2.MAV_STATE_BOOT
    peer.heartbeat()
    lat, lon = -353632620, 1491652370
    mission = Mission(
        (
            MissionItem(Command.NAV_WAYPOINT, Frame.GLOBAL, x=lat, y=lon, z=584.0),
            MissionItem(Command.NAV_TAKEOFF, params=(0, 0, 0, math.nan), x=lat, y=lon, z=20.0),
            MissionItem(Command.DO_CHANGE_SPEED, Frame.MISSION, params=(1, 1.0, 0, 0)),
            MissionItem(Command.NAV_WAYPOINT, params=(2, 0.5, 0, math.nan), x=lat + 9, y=lon),
        ),
        Autopilot.ARDUPILOT,
    )
    try:
        await asyncio.sleep(0)  # the BOOT heartbeat arrives
        assert link.state.booting
        upload = asyncio.ensure_future(MissionClient(link).upload(mission))
        await asyncio.sleep(0.05)
        assert not peer.sent("MISSION_COUNT")  # it waits for the boot to end
        peer.status = mavlink2.MAV_STATE_STANDBY
        peer.heartbeat()
        assert (await upload).verified
    finally:
        await link.close()


async def test_an_upload_whose_opening_went_unanswered_starts_again_while_the_vehicle_is_heard():
    """Every MISSION_COUNT of a first opening lost (a noisy link, failure mode 5): the
    upload starts again from MISSION_COUNT instead of failing a vehicle that is there."""
    autopilot = StoringAutopilot()
    policy = TransferPolicy(step_timeout_s=0.05, item_timeout_s=0.02, retries=1)
    lost = policy.retries + 1  # every try of the first opening

    def lossy(msg: Any) -> list[Any]:
        nonlocal lost
        if msg.get_type() == "MISSION_COUNT" and lost > 0:
            lost -= 1
            return []
        return autopilot(msg)

    link, peer = await linked(lossy)
    autopilot.peer = peer
    try:
        home = MissionItem(Command.NAV_WAYPOINT, Frame.GLOBAL, x=-353632620, y=1491652370, z=584.0)
        waypoint = MissionItem(Command.NAV_WAYPOINT, x=-353632600, y=1491652370, z=20.0)
        mission = Mission((home, waypoint), Autopilot.ARDUPILOT)
        assert (await MissionClient(link, policy).upload(mission)).verified
        assert len(peer.sent("MISSION_COUNT")) == policy.retries + 2
    finally:
        await link.close()


async def test_a_reboot_ends_what_was_waiting_on_the_vehicle() -> None:
    link, peer = await linked(silent)
    try:
        waiting = asyncio.ensure_future(link.wait_for("COMMAND_ACK", timeout=5.0))
        await asyncio.sleep(0)
        peer.status = mavlink2.MAV_STATE_BOOT  # booting again: it restarted
        peer.heartbeat()
        with pytest.raises(VehicleRebootedError):
            await waiting
        assert link.state.reboots == 1
    finally:
        await link.close()


def accept_commands(msg: Any) -> list[Any]:
    if msg.get_type() != "COMMAND_LONG":
        return []
    return [
        mavlink2.MAVLink_command_ack_message(msg.command, mavlink2.MAV_RESULT_ACCEPTED, 0, 0, 0, 0)
    ]


async def gap_in_heartbeats(link: VehicleLink, peer: Peer, *, streaming: bool) -> None:
    """Heartbeats 0.01 s apart as far as the link knows, then at least 0.1 s of silence.

    Sleeps only lengthen, so the silence is a gap however slow the machine is; then
    wait for whatever the gap set off to end (never for the link's own watchdog).
    """
    gap: asyncio.Future[None] = asyncio.get_running_loop().create_future()

    def on_gap(event: LinkEvent) -> None:
        if event == LinkEvent.GAP:
            gap.set_result(None)

    link.on_event(on_gap)
    link.heartbeat_period_s = 0.01
    if streaming:
        peer.send(peer.codec.global_position_int_encode(1000, 0, 0, 0, 0, 0, 0, 0, 65535))
    await asyncio.sleep(0.1)
    peer.heartbeat()
    await asyncio.wait_for(gap, timeout=5.0)
    set_off = [t for t in asyncio.all_tasks() if "_watchdog" not in repr(t.get_coro())]
    await asyncio.wait([t for t in set_off if t is not asyncio.current_task()])


async def test_a_gap_before_any_position_asks_again_rather_than_calls_it_a_reboot() -> None:
    """ArduCopter's heartbeats pause while it boots, before it streams anything: a gap then
    proves no reboot (the likely cause of an upload to real SITL that once failed with
    'vehicle 6 rebooted', ten vehicles on a busy machine)."""
    link, peer = await linked(accept_commands)
    TelemetryStreams(link, {"GLOBAL_POSITION_INT": 5.0})
    try:
        await gap_in_heartbeats(link, peer, streaming=False)
        assert link.state.reboots == 0
        assert peer.sent("COMMAND_LONG"), "the streams are asked for again"
    finally:
        await link.close()


async def test_a_position_stream_that_stops_at_a_gap_means_a_reboot() -> None:
    link, peer = await linked(accept_commands)
    TelemetryStreams(link, {"GLOBAL_POSITION_INT": 5.0})
    try:
        await gap_in_heartbeats(link, peer, streaming=True)
        assert link.state.reboots == 1
    finally:
        await link.close()


@pytest.mark.virtual_clock
async def test_streams_asked_for_while_every_ask_is_lost_are_asked_for_until_they_flow() -> None:
    """With 20 % loss towards it, a vehicle may miss all three SET_MESSAGE_INTERVALs and
    then the fallback REQUEST_DATA_STREAM, which has no answer to miss: it streamed
    nothing, and fuzzed flight 19087 could not start ("reports no position" after 100 s).
    The streams are asked for again until a position comes."""
    link, peer = await linked(silent)
    lost = 8  # three unanswered tries of the first interval, the fallback's three, and two

    def lossy_arducopter(msg: Any) -> list[Any]:
        nonlocal lost
        if msg.get_type() not in ("COMMAND_LONG", "REQUEST_DATA_STREAM"):
            return []
        if lost:
            lost -= 1
            return []
        position = peer.codec.global_position_int_encode(0, 1, 2, 3, 4, 0, 0, 0, 0)
        if msg.get_type() == "REQUEST_DATA_STREAM":
            return [position]
        return [peer.codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_ACCEPTED), position]

    async def heartbeats() -> None:  # steady at 1 Hz from `linked`'s: no gap to ask after
        while True:
            await asyncio.sleep(1.0)
            peer.heartbeat()

    peer.reply = lossy_arducopter
    beating = asyncio.ensure_future(heartbeats())
    streams = TelemetryStreams(link, {"GLOBAL_POSITION_INT": 5.0})
    try:
        assert not await streams.start(), "three unanswered tries: the fallback"
        assert link.state.position is None
        position = await link.wait_for("GLOBAL_POSITION_INT", timeout=30.0)
        assert position.lat == 1
        asks = peer.sent("COMMAND_LONG") + peer.sent("REQUEST_DATA_STREAM")
        assert len(asks) == 9, "asked again until the ninth ask was answered, not beyond"
    finally:
        beating.cancel()
        await link.close()


@pytest.mark.virtual_clock
async def test_a_mission_current_stream_never_set_up_is_asked_for_until_it_flows() -> None:
    """The position stream set up, MISSION_CURRENT's three SET_MESSAGE_INTERVALs and the
    fallback REQUEST_DATA_STREAM lost: positions flowed, the item did not, and an approach
    restarted the item seen 5 s before, sending the vehicle back to a waypoint it had
    passed (fuzzed flight 20014, 1.67 m). MISSION_CURRENT is asked for until it flows,
    and nothing that flows is asked for again."""
    link, peer = await linked(silent)
    position_id, current_id = (
        mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        mavlink2.MAVLINK_MSG_ID_MISSION_CURRENT,
    )
    lost = {current_id: 3}
    streaming: set[int] = set()

    def lossy_towards_it(msg: Any) -> list[Any]:
        if msg.get_type() != "COMMAND_LONG":
            return []  # the fallback REQUEST_DATA_STREAMs are lost too
        wanted = int(msg.param1)
        if lost.get(wanted):
            lost[wanted] -= 1
            return []
        streaming.add(wanted)
        return [peer.codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_ACCEPTED)]

    async def streams() -> None:
        for tick in itertools.count():
            await asyncio.sleep(0.2)
            if tick % 5 == 0:
                peer.heartbeat()
            if position_id in streaming:
                peer.send(peer.codec.global_position_int_encode(0, 1, 2, 3, 4, 0, 0, 0, 0))
            if current_id in streaming:
                peer.send(peer.codec.mission_current_encode(4))

    peer.reply = lossy_towards_it
    flowing = asyncio.ensure_future(streams())
    try:
        assert not await TelemetryStreams(
            link, {"GLOBAL_POSITION_INT": 5.0, "MISSION_CURRENT": 2.0}
        ).start()
        current = await link.wait_for("MISSION_CURRENT", timeout=30.0)
        assert current.seq == 4
        asked = [int(m.param1) for m in peer.sent("COMMAND_LONG")]
        assert asked.count(current_id) == 4 and asked.count(position_id) == 1, asked
    finally:
        flowing.cancel()
        await link.close()


async def test_a_mission_arducopter_will_not_pause_is_braked_and_resumed_in_auto() -> None:
    """ArduCopter pauses AUTO only on the way to a place; taking off, coming down or
    standing at a waypoint it answers FAILED "Failed to pause". The vehicle then brakes,
    and resuming switches back to AUTO even while its last HEARTBEAT still says AUTO (a
    continue would be refused in BRAKE: "Failed to resume")."""
    link, peer = await linked(silent)

    def arducopter(msg: Any) -> list[Any]:
        if msg.get_type() != "COMMAND_LONG":
            return []
        if msg.command == mavlink2.MAV_CMD_DO_PAUSE_CONTINUE:
            ack = peer.codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_FAILED)
            return [ack, peer.codec.statustext_encode(6, b"Failed to pause")]
        return [peer.codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_ACCEPTED)]

    peer.reply = arducopter
    auto, armed = 3, mavlink2.MAV_MODE_FLAG_SAFETY_ARMED | 0x01
    peer.send(peer.codec.heartbeat_encode(2, 3, armed, auto, mavlink2.MAV_STATE_ACTIVE))
    try:

        async def in_auto() -> None:
            while link.state.mode != "AUTO":
                await asyncio.sleep(0.01)

        await asyncio.wait_for(in_auto(), 10)
        actions = FlightActions(link)
        how = await actions.pause_mission()
        assert how == "holding in BRAKE (the mission would not pause: Failed to pause)"
        await actions.resume_mission()
        commands = [(m.command, m.param1, m.param2) for m in peer.sent("COMMAND_LONG")]
        pause, set_mode = mavlink2.MAV_CMD_DO_PAUSE_CONTINUE, mavlink2.MAV_CMD_DO_SET_MODE
        brake = mavlink2.COPTER_MODE_BRAKE
        assert commands == [(pause, 0, 0), (set_mode, 1, brake), (set_mode, 1, auto)]
    finally:
        await link.close()


async def test_an_approach_flies_the_item_afresh_on_arducopter_not_its_paused_track() -> None:
    """A paused ArduCopter mission resumed at a lower speed runs back up to the speed it
    was paused at (SITL: 4.9 m/s for a 1 m/s approach); its item made current again
    starts afresh from rest and keeps to the speed. One braked out of its mission goes
    back to AUTO and gets the approach's speed after it, not its mission's."""
    link, peer = await linked(silent)
    current = 5

    def arducopter(msg: Any) -> list[Any]:
        if msg.get_type() == "MISSION_SET_CURRENT":
            return [peer.codec.mission_current_encode(msg.seq)]
        if msg.get_type() != "COMMAND_LONG":
            return []
        if msg.command == mavlink2.MAV_CMD_DO_PAUSE_CONTINUE and msg.param1 == 0 and braking:
            ack = peer.codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_FAILED)
            return [ack, peer.codec.statustext_encode(6, b"Failed to pause")]
        return [peer.codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_ACCEPTED)]

    braking = False
    peer.reply = arducopter
    auto, armed = 3, mavlink2.MAV_MODE_FLAG_SAFETY_ARMED | 0x01
    peer.send(peer.codec.heartbeat_encode(2, 3, armed, auto, mavlink2.MAV_STATE_ACTIVE))
    peer.send(peer.codec.mission_current_encode(current))
    try:
        while link.state.mode != "AUTO" or link.state.mission_seq != current:
            await asyncio.sleep(0.01)
        actions = FlightActions(link, mission=MissionClient(link))
        actions.mission_speed_m_s = 5.0
        await actions.pause_mission()
        await actions.approach(1.0)
        commands = [(m.command, m.param1, m.param2) for m in peer.sent("COMMAND_LONG")]
        pause, speed = mavlink2.MAV_CMD_DO_PAUSE_CONTINUE, mavlink2.MAV_CMD_DO_CHANGE_SPEED
        again = mavlink2.MAV_CMD_DO_SET_MISSION_CURRENT
        resumed = [(pause, 1, 0)] * 2  # right after the pause: once more at once
        assert commands == [(pause, 0, 0), (again, current, 0), (speed, 1, 1.0), *resumed]

        peer.heard.clear()
        braking = True
        await actions.pause_mission()  # "Failed to pause": braked
        await actions.approach(2.0)
        commands = [(m.command, m.param1, m.param2) for m in peer.sent("COMMAND_LONG")]
        set_mode, brake = mavlink2.MAV_CMD_DO_SET_MODE, mavlink2.COPTER_MODE_BRAKE
        assert commands[:4] == [(pause, 0, 0), (set_mode, 1, brake), (set_mode, 1, auto),
                                (speed, 1, 2.0)]  # fmt: skip
        assert set(commands[4:]) <= {(set_mode, 1, auto), (speed, 1, 2.0)}  # AUTO made sure
        assert peer.sent("MISSION_SET_CURRENT") == []
    finally:
        await link.close()


async def test_an_approach_from_the_start_flies_the_first_leg_not_the_take_off() -> None:
    """A vehicle the passing order holds at its start hovers out of its mission (GUIDED,
    NAV_TAKEOFF current). Sent on in AUTO from there, its mission runs the DO_CHANGE_SPEED
    after NAV_TAKEOFF and flies on at cruise speed whatever the approach asked (random
    scatter of 8 at 10 m/s: 1.7 m into the encounter, the flight 1.24x its timing on
    SITL); its first leg is made current before AUTO, and the approach's speed follows."""
    link, peer = await linked(silent)

    def arducopter(msg: Any) -> list[Any]:
        if msg.get_type() == "MISSION_SET_CURRENT":
            return [peer.codec.mission_current_encode(msg.seq)]
        if msg.get_type() != "COMMAND_LONG":
            return []
        return [peer.codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_ACCEPTED)]

    peer.reply = arducopter
    guided, armed = 4, mavlink2.MAV_MODE_FLAG_SAFETY_ARMED | 0x01
    peer.send(peer.codec.heartbeat_encode(2, 3, armed, guided, mavlink2.MAV_STATE_ACTIVE))
    peer.send(peer.codec.mission_current_encode(1))
    try:
        while link.state.mode != "GUIDED" or link.state.mission_seq != 1:
            await asyncio.sleep(0.01)
        actions = FlightActions(link, mission=MissionClient(link))
        actions.first_leg_seq = 3
        actions.found_stopped_out_of_mission()
        await actions.approach(1.0)
        commands = [(m.command, m.param1, m.param2) for m in peer.sent("COMMAND_LONG")]
        current, set_mode = mavlink2.MAV_CMD_DO_SET_MISSION_CURRENT, mavlink2.MAV_CMD_DO_SET_MODE
        speed, auto = mavlink2.MAV_CMD_DO_CHANGE_SPEED, 3
        assert commands[:3] == [(current, 3, 0), (set_mode, 1, auto), (speed, 1, 1.0)]
    finally:
        await link.close()


@pytest.mark.parametrize("climbs", [True, False], ids=["lifting off", "still on the ground"])
async def test_a_resent_take_off_refused_as_already_flying_is_a_take_off(climbs: bool) -> None:
    """20 % loss each way loses one command's ACK in five: the first NAV_TAKEOFF lifts the
    vehicle off, its ACK is lost, and ArduCopter answers the re-sent one FAILED (it is
    flying already). That is a take-off, not a failure; on the ground it is a failure."""
    link, peer = await linked(silent)
    altitude_mm = 1500 if climbs else 0

    def lose_the_first_ack(msg: Any) -> list[Any]:
        if msg.get_type() != "COMMAND_LONG" or msg.command != mavlink2.MAV_CMD_NAV_TAKEOFF:
            return []
        if len(peer.sent("COMMAND_LONG")) == 1:
            return []  # carried out; its ACK lost on the way
        position = peer.codec.global_position_int_encode(
            1000, -353632620, 1491652370, 584000 + altitude_mm, altitude_mm, 0, 0,
            -100 if climbs else 0, 0,
        )  # fmt: skip
        return [peer.codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_FAILED), position]

    peer.reply = lose_the_first_ack
    policy = CommandPolicy(timeout_s=0.05, retries=2)
    try:
        actions = FlightActions(link, command_policy=policy)
        if climbs:
            await actions.takeoff(10.0)
        else:
            with pytest.raises(CommandFailedError):
                await actions.takeoff(10.0)
        assert len(peer.sent("COMMAND_LONG")) == 2
    finally:
        await link.close()


@pytest.mark.virtual_clock
async def test_a_hold_right_after_an_arm_disarms_though_the_last_heartbeat_says_disarmed() -> None:
    """Fuzzed flight 7773: a hold during the start came 0.4 s after the vehicle's ARM was
    acknowledged, before any HEARTBEAT said it was armed. Taken for on the ground, it was
    left alone and climbed on in GUIDED. An ARM sent is news the vehicle has not told of
    yet: the hold disarms it (refused in the air: it brakes), and only a HEARTBEAT heard
    well after the ARM makes it "down" again."""
    link, peer = await linked(silent)
    peer.reply = lambda msg: (
        [peer.codec.command_ack_encode(msg.command, mavlink2.MAV_RESULT_ACCEPTED)]
        if msg.get_type() == "COMMAND_LONG"
        else []
    )
    arm_disarm = mavlink2.MAV_CMD_COMPONENT_ARM_DISARM
    try:
        assert link.state.down
        actions = FlightActions(link)
        await actions.arm()
        peer.heartbeat()  # disarmed: sent before the ARM arrived
        await asyncio.sleep(0.1)
        assert not link.state.down
        assert await actions.hold() == "on the ground: disarmed"
        assert [(m.command, m.param1) for m in peer.sent("COMMAND_LONG")] == [
            (arm_disarm, 1),
            (arm_disarm, 0),
        ]
        await asyncio.sleep(1.0)
        peer.heartbeat()  # disarmed, and heard long enough after the ARM to say so
        await asyncio.sleep(0.1)
        assert link.state.down
        assert await actions.hold() == "on the ground, disarmed: nothing to hold"
    finally:
        await link.close()
