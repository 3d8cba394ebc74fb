"""One simulated vehicle: decodes what arrives on its links, routes it to the parameter,
mission and command handlers, and sends heartbeats and telemetry.

Two clocks drive it. Vehicle behaviour (physics, boot and readiness, idle disarm,
telemetry rates) runs on simulated time, `clock`. Link-protocol timers (the mission
protocol's re-requests and cancel, the command retry window) run on the loop's clock,
`wall`, as a real autopilot's run on its wall clock: a ground station's step timeouts run
on its own clock too, so a speed-up must not shrink them. (On a virtual-time loop both
clocks are the one virtual clock.)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable
from typing import Any, ClassVar, TypeVar

import numpy as np

from . import messages
from .boot import BootSequence
from .clock import loop_time
from .codec import Decoder, Encoder, Message, Sender, mavlink
from .commands import Command, CommandHandler
from .faults import Faults, FaultyLink
from .flight import FlightController, Home
from .gcs_failsafe import GcsFailsafe
from .kinematics import Body
from .mission_item import MissionItem
from .mission_store import MissionStore
from .notices import Notices
from .snapshot import VehicleState
from .telemetry import UNASKED_ARDUPILOT_S, TelemetrySchedule
from .transport import Endpoint
from .vehicle_config import DEFAULT_HOME, VehicleConfig

__all__ = ["DEFAULT_HOME", "Vehicle", "VehicleConfig"]

T = TypeVar("T")

POSITION_IGNORED = (
    mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE
)
REBOOT_SILENCE_S = 1.0  # shorter than the BOOT status, so a ground station sees it

Geodetic = Callable[[int], tuple[float, float]]
"""Vehicle index → current (lat, lon)."""


class Vehicle:
    """Ties one vehicle's protocol handlers, flight controller and links together."""

    def __init__(
        self,
        config: VehicleConfig,
        body: Body,
        home_en: tuple[float, float],
        to_local: Callable[[float, float], tuple[float, float]],
        geodetic: Geodetic,
        clock: Callable[[], float],
        rng: np.random.Generator,
        stream_by_default: bool,
        wall: Callable[[], float] = loop_time,
    ) -> None:
        self.config = config
        self.sysid = config.sysid
        self.flavour = config.flavour
        self.endpoint: Endpoint | None = None
        """The vehicle's own server (UDP or TCP)."""
        self.outputs: list[Endpoint] = []
        """Ground stations it sends to (`--out`), shared with other vehicles."""
        self._body = body
        self._geodetic = geodetic
        self._now = clock
        self._wall = wall
        self._stream_by_default = stream_by_default or self.flavour.streams_by_default
        self._encoder = Encoder(self.sysid, key=config.signing_key)
        self._decoders: dict[Hashable, Decoder] = {}
        self._rejected_before = 0
        # inbound (message, link) pairs, outbound encoded bytes
        self.link: FaultyLink[Any] = FaultyLink(config.faults, rng)
        self.faults = config.faults
        self.params = self.flavour.new_params(self.sysid)
        lat, lon, alt = config.home
        home = Home(lat, lon, alt, *home_en)
        self.store = MissionStore(self.flavour, self, self._home_item, config.mission_capacity)
        self.notices = Notices(self.flavour, self.send, self.say)
        self.flight = FlightController(
            self.flavour,
            body,
            self.params,
            self.store,
            home,
            to_local,
            self,
            self.say,
            config.timeline(),
        )
        self.schedule = TelemetrySchedule(
            self._stream_by_default,
            messages.streamable(self.flavour),
            UNASKED_ARDUPILOT_S if self.flavour.sends_unasked else None,
        )
        self.commands = CommandHandler(
            self.flight,
            self.store,
            self.schedule,
            self._jumped,
            lambda: self.faults,
            self.say,
        )
        self.failsafe = GcsFailsafe(self.flight, self.params, self.say)
        self.boot = BootSequence(self.flight, self.store, self.say, self._send_home)
        self.store.on_mission_changed = self._mission_changed
        self.store.on_current_changed = self._jumped
        self._gcs_heard = False
        self._was_armed = False
        self._held_texts: list[Message] | None = None
        self.set_faults(config.faults)
        self.flight.apply_limits()
        self.boot.start(0.0)

    # -- control from the simulator -------------------------------------------------------

    def set_faults(self, faults: Faults) -> None:
        self.faults = faults
        self.link.set_faults(faults)
        self.store.reject_at = faults.reject_at if faults.reject_missions else None

    def silence(self, seconds: float) -> None:
        self.link.silence(self._now() + seconds)

    def reboot(self) -> None:
        """Silent for a second, then booting again: disarmed at home with no mission."""
        now = self._now()
        self.link.silence(now + REBOOT_SILENCE_S)
        self._rejected_before = self.rejected_packets
        self._decoders.clear()
        self._gcs_heard = False
        self._was_armed = False
        self.failsafe.reset()
        self.flight.reboot(now)
        self.store.reset()
        self.schedule.reset(self._stream_by_default, now)
        self.flight.apply_limits()
        self.boot.start(now)
        self.notices.reset(now)

    def mission(self, mission_type: int = 0) -> list[MissionItem]:
        return self.store.items(mission_type)

    @property
    def rejected_packets(self) -> int:
        """Packets dropped for a missing or wrong signature, since the simulator started."""
        return self._rejected_before + sum(d.rejected for d in self._decoders.values())

    # -- the links ------------------------------------------------------------------------

    def on_packet(self, data: bytes, link: Hashable) -> None:
        """Bytes from a transport: decode (checking signatures), pass the faults, handle."""
        decoder = self._decoders.get(link)
        if decoder is None:
            decoder = self._decoders[link] = Decoder(self.config.signing_key)
        now = self._now()
        for msg in decoder.decode(data):
            for delivered, via in self.link.inbound((msg, link), now):
                self._handle(delivered, via, now)

    def send(self, msg: Message) -> None:
        """Outbox: encode and send through the faults to every peer and output."""
        for data in self.link.outbound(self._encoder.encode(msg), self._now()):
            self._transmit(data)

    def say(self, severity: int, text: str) -> None:
        msg = messages.statustext(severity, text)
        if self._held_texts is not None:
            self._held_texts.append(msg)  # said while answering a command: after its ACK
        else:
            self.send(msg)

    def _transmit(self, data: bytes) -> None:
        if self.endpoint is not None:
            self.endpoint.send(data)
        for output in self.outputs:
            output.send(data)

    # -- mission events -------------------------------------------------------------------

    def item_started(self, item: MissionItem) -> None:
        self.notices.item_started(item)

    def item_reached(self, item: MissionItem) -> None:
        self.notices.item_reached(item)

    def current_changed(self) -> None:
        self.send(messages.mission_current(self.state(), self.flavour))

    def _jumped(self) -> None:
        """MISSION_SET_CURRENT: say so, and fly the new item now."""
        self.flight.runner.jump(self._now())
        self.current_changed()

    def speed_changed(self, speed: float) -> None:
        self.flight.change_speed(speed)

    def _mission_changed(self) -> None:
        self.flight.runner.reset()

    # -- time -----------------------------------------------------------------------------

    def step(self, now: float) -> None:
        self.boot.step(now)
        self.flight.update(now)
        self.failsafe.check(now)
        inbound, outbound = self.link.release(now)
        for msg, via in inbound:
            self._handle(msg, via, now)
        for data in outbound:
            self._transmit(data)
        if self.store.uploading:  # the clock read only then: this runs at every step
            self.store.tick(self._wall())
        self.notices.flush(now)
        self._watch_arming()
        self._send_due_telemetry(now)
        if self._gcs_heard:
            self.notices.prearm(now, lambda: self.flight.prearm_texts(now))

    def _watch_arming(self) -> None:
        """ArduCopter sets home where it arms, and says so (HOME_POSITION, GPS_GLOBAL_ORIGIN)."""
        armed = self.flight.armed
        if armed and not self._was_armed and self.flavour.sends_unasked:
            self._send_home()
        self._was_armed = armed

    def _send_home(self) -> None:
        state = self.state()
        self.send(messages.gps_global_origin(state, self.flavour))
        self.send(messages.home_position(state, self.flavour))

    def _send_due_telemetry(self, now: float) -> None:
        due = self.schedule.due(now)
        if not due or self.link.silent(now):
            return
        state = self.state()
        for msg_id in due:
            if msg_id in messages.NEEDS_HOME and not state.home_set:
                continue
            self.send(messages.BUILDERS[msg_id](state, self.flavour))
            if msg_id == mavlink.MAVLINK_MSG_ID_SYS_STATUS and self.flight.fence_enabled:
                self.send(self._fence_status())  # ArduPilot's EXTENDED_STATUS stream has it

    def _fence_status(self) -> Message:
        """FENCE_STATUS as ArduCopter sends it while its fence is enabled."""
        monitor = self.flight.fence
        return mavlink.MAVLink_fence_status_message(
            int(monitor.breaches != 0),
            monitor.breach_count,
            monitor.breach_type,
            monitor.breach_time_ms,
            mavlink.FENCE_MITIGATE_NONE,  # no avoidance is simulated to limit anything
        )

    # -- state ----------------------------------------------------------------------------

    def state(self) -> VehicleState:
        now = self._now()
        flight, flavour = self.flight, self.flavour
        lat, lon = self._geodetic(self._body.index)
        v_east, v_north, v_up = self._body.velocity
        heading = (
            math.degrees(math.atan2(v_east, v_north)) % 360
            if math.hypot(v_east, v_north) > 0.5
            else 0.0
        )
        home = flight.home
        return VehicleState(
            sysid=self.sysid,
            t=now,
            uptime=flight.uptime(now),
            lat=lat,
            lon=lon,
            alt=self._body.alt,
            alt_amsl=home.alt_amsl + self._body.alt,
            velocity_ned=(v_north, v_east, -v_up),
            heading_deg=heading,
            armed=flight.armed,
            mode=flight.mode.value,
            custom_mode=flavour.modes.custom_mode(flight.mode),
            base_mode=flavour.modes.base_mode(flight.mode, flight.armed),
            system_status=self._system_status(now),
            landed_state=flight.landed_state,
            mission_seq=self.store.reported_current,
            mission_total=self.store.total,
            mission_state=int(flight.runner.state),
            home=(home.lat, home.lon, home.alt_amsl),
            estimate_ready=flight.estimate_ready(now),
            position_known=flight.position_known(now),
            home_set=flight.home_set(now),
            sensors=self.boot.sensors(now),
            rejected_packets=self.rejected_packets,
            holding=flight.holding,
        )

    def _system_status(self, now: float) -> int:
        if self.flight.uptime(now) < self.flight.timeline.boot_status_s:
            return int(mavlink.MAV_STATE_BOOT)
        flying = self.flight.armed and (
            self.flight.landed_state != mavlink.MAV_LANDED_STATE_ON_GROUND
        )
        return int(mavlink.MAV_STATE_ACTIVE if flying else mavlink.MAV_STATE_STANDBY)

    def _home_item(self) -> MissionItem:
        home = self.flight.home
        return MissionItem(
            seq=0,
            frame=mavlink.MAV_FRAME_GLOBAL,
            command=mavlink.MAV_CMD_NAV_WAYPOINT,
            x=round(home.lat * 1e7),
            y=round(home.lon * 1e7),
            z=home.alt_amsl,
        )

    # -- inbound messages -----------------------------------------------------------------

    def _handle(self, msg: Message, link: Hashable, now: float) -> None:
        target = getattr(msg, "target_system", 0)
        if target not in (0, self.sysid):
            return  # for another vehicle on a shared link
        self._gcs_heard = True
        sender = Sender(msg.get_srcSystem(), msg.get_srcComponent(), link)
        kind = msg.get_type()
        if kind == "HEARTBEAT":
            self.failsafe.heard(sender.sysid, now)
            return
        if kind.startswith("MISSION_"):
            self.store.handle(msg, sender, self._wall())
            return
        handler = self._handlers.get(kind)
        if handler is not None:
            handler(self, msg, sender, now)

    def _on_command(self, msg: Message, sender: Sender, now: float) -> None:
        command = Command.from_message(msg, sender)
        outcome = self._texts_after_ack(
            lambda: self.commands.handle(command, now),
            lambda outcome: messages.command_ack(
                command.id, outcome.result, sender.sysid, sender.compid
            ),
        )
        for msg_id in outcome.then:
            self._send_by_id(msg_id)
        if outcome.reboot:
            self.reboot()

    def _on_set_mode(self, msg: Message, sender: Sender, now: float) -> None:
        self._texts_after_ack(
            lambda: self.commands.set_mode(msg.base_mode, msg.custom_mode, now),
            lambda result: messages.command_ack(
                mavlink.MAVLINK_MSG_ID_SET_MODE, result, sender.sysid, sender.compid
            ),
        )

    def _texts_after_ack(self, answer: Callable[[], T], ack: Callable[[T], Message]) -> T:
        """Carry out a command, send its ACK, then what was said meanwhile: ArduPilot's
        STATUSTEXTs about a command (arming checks, mode failures) follow its COMMAND_ACK."""
        self._held_texts = []
        try:
            result = answer()
        finally:
            texts, self._held_texts = self._held_texts, None
        self.send(ack(result))
        for text in texts:
            self.send(text)
        return result

    def _on_request_data_stream(self, msg: Message, sender: Sender, now: float) -> None:
        self.schedule.request_data_stream(
            msg.req_stream_id, msg.req_message_rate, bool(msg.start_stop), now
        )

    def _on_timesync(self, msg: Message, sender: Sender, now: float) -> None:
        """Answer a ground station's TIMESYNC request (tc1 0) with our clock in tc1."""
        if msg.tc1 == 0:
            self.send(mavlink.MAVLink_timesync_message(messages.nanoseconds(self.state()), msg.ts1))

    def _on_param_request_list(self, msg: Message, sender: Sender, now: float) -> None:
        for value in self.params.all_messages():
            self.send(value)

    def _on_param_request_read(self, msg: Message, sender: Sender, now: float) -> None:
        name = _param_name(msg.param_id)
        if msg.param_index >= 0:
            value = self.params.message_at(msg.param_index)
        else:
            value = self.params.value_message(name) if name in self.params else None
        if value is not None:
            self.send(value)

    def _on_param_set(self, msg: Message, sender: Sender, now: float) -> None:
        name = _param_name(msg.param_id)
        if name not in self.params:
            return  # ArduPilot and PX4 stay silent about unknown names
        self.params.set(name, self.params.decode(name, msg.param_value))
        self.flight.apply_limits()
        self.send(self.params.value_message(name))

    def _on_position_target(self, msg: Message, sender: Sender, now: float) -> None:
        if msg.coordinate_frame != mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT:
            return  # the only frame the ground station sends
        if msg.type_mask & POSITION_IGNORED:
            return  # a velocity or acceleration target: not simulated
        self.flight.guided_target(msg.lat_int / 1e7, msg.lon_int / 1e7, msg.alt, now)

    def _send_by_id(self, msg_id: int) -> None:
        if msg_id == mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            self.send(messages.autopilot_version(self.sysid, self.flavour, self.config.board_id))
        else:
            self.send(messages.BUILDERS[msg_id](self.state(), self.flavour))

    _handlers: ClassVar[dict[str, Callable[[Vehicle, Message, Sender, float], None]]] = {
        "COMMAND_LONG": _on_command,
        "COMMAND_INT": _on_command,
        "SET_MODE": _on_set_mode,
        "REQUEST_DATA_STREAM": _on_request_data_stream,
        "TIMESYNC": _on_timesync,
        "PARAM_REQUEST_LIST": _on_param_request_list,
        "PARAM_REQUEST_READ": _on_param_request_read,
        "PARAM_SET": _on_param_set,
        "SET_POSITION_TARGET_GLOBAL_INT": _on_position_target,
    }


def _param_name(raw: str | bytes) -> str:
    text = raw.decode(errors="replace") if isinstance(raw, bytes) else raw
    return text.split("\x00", 1)[0]
