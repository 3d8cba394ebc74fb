"""One simulated vehicle: decodes what arrives on its link, routes it to the parameter,
mission and command handlers, and sends heartbeats and telemetry on simulated time."""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from . import messages
from .codec import Decoder, Encoder, Message, Sender, mavlink
from .commands import Command, CommandHandler
from .faults import Faults, FaultyLink
from .flavour import FLAVOURS
from .flight import FlightController, Home
from .kinematics import Body
from .mission_item import MissionItem
from .mission_store import DEFAULT_CAPACITY, MissionStore
from .snapshot import VehicleState
from .telemetry import TelemetrySchedule
from .transport import Endpoint

DEFAULT_HOME = (47.3977, 8.5456, 488.0)
REBOOT_SILENCE_S = 1.0  # shorter than the BOOT status, so a ground station sees it
PREARM_REPEAT_S = 30.0
PX4_REACHED_REPEAT_S = 1.0

Geodetic = Callable[[int], tuple[float, float]]
"""Vehicle index → current (lat, lon)."""


@dataclass
class VehicleConfig:
    """How to start one vehicle. `port=0` lets the OS pick a free port."""

    sysid: int
    port: int = 0
    home: tuple[float, float, float] = DEFAULT_HOME
    """lat, lon (degrees), alt (metres AMSL)."""
    autopilot: str = "ardupilot"
    transport: str = "udp"
    faults: Faults = field(default_factory=Faults)
    mission_capacity: int = DEFAULT_CAPACITY
    estimate_delay_s: float = 5.0
    """Simulated seconds after boot before the position estimate (and arming) is ready."""

    def __post_init__(self) -> None:
        if not 1 <= self.sysid <= 255:
            raise ValueError(f"sysid must be in 1..255, got {self.sysid}")
        if self.autopilot not in FLAVOURS:
            raise ValueError(f"autopilot must be one of {sorted(FLAVOURS)}, got {self.autopilot!r}")
        if self.transport not in ("udp", "tcp"):
            raise ValueError(f"transport must be 'udp' or 'tcp', got {self.transport!r}")


class Vehicle:
    """Ties one vehicle's protocol handlers, flight controller and link together."""

    def __init__(self, config: VehicleConfig, body: Body, home_en: tuple[float, float],
                 to_local: Callable[[float, float], tuple[float, float]], geodetic: Geodetic,
                 clock: Callable[[], float], rng: np.random.Generator,
                 stream_by_default: bool) -> None:
        self.config = config
        self.sysid = config.sysid
        self.flavour = FLAVOURS[config.autopilot]
        self.endpoint: Endpoint | None = None
        self._body = body
        self._geodetic = geodetic
        self._now = clock
        self._stream_by_default = stream_by_default or self.flavour.streams_by_default
        self._encoder = Encoder(self.sysid)
        self._decoders: dict[Hashable, Decoder] = {}
        self.link: FaultyLink = FaultyLink(config.faults, rng)
        self.params = self.flavour.new_params(self.sysid)
        lat, lon, alt = config.home
        home = Home(lat, lon, alt, *home_en)
        self.store = MissionStore(self.flavour, self, self._home_item, config.mission_capacity)
        self.flight = FlightController(self.flavour, body, self.params, self.store, home,
                                       to_local, self, self.say, config.estimate_delay_s)
        self.schedule = TelemetrySchedule(self._stream_by_default,
                                          messages.streamable(self.flavour))
        self.commands = CommandHandler(self.flight, self.store, self.schedule,
                                       self.current_changed)
        self.store.on_mission_changed = self._mission_changed
        self.store.on_current_changed = self.current_changed
        self._boot_time = 0.0
        self._gcs_heard = False
        self._next_prearm = 0.0
        self._reached_repeat: tuple[int, float] | None = None
        self.set_faults(config.faults)
        self.flight.apply_limits()

    # -- control from the simulator -------------------------------------------------------

    def set_faults(self, faults: Faults) -> None:
        self.link.set_faults(faults)
        self.store.reject_at = faults.reject_at if faults.reject_missions else None

    def silence(self, seconds: float) -> None:
        self.link.silence(self._now() + seconds)

    def reboot(self) -> None:
        """Silent for a couple of seconds, then back disarmed at home with no mission."""
        now = self._now()
        self.link.silence(now + REBOOT_SILENCE_S)
        self._boot_time = now
        self._decoders.clear()
        self._gcs_heard = False
        self._reached_repeat = None
        self.flight.reboot(now)
        self.store.reset()
        self.schedule.reset(self._stream_by_default, now)
        self.flight.apply_limits()

    def mission(self, mission_type: int = 0) -> list[MissionItem]:
        return self.store.items(mission_type)

    # -- the link -------------------------------------------------------------------------

    def on_packet(self, data: bytes, link: Hashable) -> None:
        """Bytes from the transport: decode, pass through the faults, handle."""
        decoder = self._decoders.get(link)
        if decoder is None:
            decoder = self._decoders[link] = Decoder()
        now = self._now()
        for msg in decoder.decode(data):
            for delivered, via in self.link.inbound((msg, link), now):
                self._handle(delivered, via, now)

    def send(self, msg: Message) -> None:
        """Outbox: encode and send through the faults to every peer."""
        if self.endpoint is None:
            return
        for data in self.link.outbound(self._encoder.encode(msg), self._now()):
            self.endpoint.send(data)

    def say(self, severity: int, text: str) -> None:
        self.send(messages.statustext(severity, text))

    # -- mission events -------------------------------------------------------------------

    def item_reached(self, seq: int) -> None:
        self.send(mavlink.MAVLink_mission_item_reached_message(seq))
        if self.flavour.repeats_item_reached:
            self._reached_repeat = (seq, self._now() + PX4_REACHED_REPEAT_S)

    def current_changed(self) -> None:
        self.send(messages.mission_current(self.state(), self.flavour))

    def speed_changed(self, speed: float) -> None:
        self.flight.change_speed(speed)

    def _mission_changed(self) -> None:
        self.flight.runner.reset()

    # -- time -----------------------------------------------------------------------------

    def step(self, now: float) -> None:
        self.flight.update(now)
        inbound, outbound = self.link.release(now)
        for msg, via in inbound:
            self._handle(msg, via, now)
        for data in outbound:
            if self.endpoint is not None:
                self.endpoint.send(data)
        self.store.tick(now)
        self._send_due_telemetry(now)
        self._repeat_notices(now)

    def _send_due_telemetry(self, now: float) -> None:
        due = self.schedule.due(now)
        if not due or self.link.silent(now):
            return
        state = self.state()
        for msg_id in due:
            if msg_id == mavlink.MAVLINK_MSG_ID_HOME_POSITION and not state.estimate_ready:
                continue
            self.send(messages.BUILDERS[msg_id](state, self.flavour))

    def _repeat_notices(self, now: float) -> None:
        if self._gcs_heard and now >= self._next_prearm:
            text = self.flight.prearm_text(now)
            if text is not None:
                self.say(mavlink.MAV_SEVERITY_CRITICAL, text)
            self._next_prearm = now + PREARM_REPEAT_S
        if self._reached_repeat is not None and now >= self._reached_repeat[1]:
            self.send(mavlink.MAVLink_mission_item_reached_message(self._reached_repeat[0]))
            self._reached_repeat = None

    # -- state ----------------------------------------------------------------------------

    def state(self) -> VehicleState:
        now = self._now()
        flight, flavour = self.flight, self.flavour
        lat, lon = self._geodetic(self._body.index)
        alt = self._body.alt
        v_east, v_north, v_up = self._body.velocity
        heading = math.degrees(math.atan2(v_east, v_north)) % 360 if math.hypot(
            v_east, v_north) > 0.5 else 0.0
        home = flight.home
        return VehicleState(
            sysid=self.sysid, t=now, uptime=now - self._boot_time, lat=lat, lon=lon, alt=alt,
            alt_amsl=home.alt_amsl + alt,
            velocity_ned=(v_north, v_east, -v_up), heading_deg=heading, armed=flight.armed,
            mode=flight.mode.value, custom_mode=flavour.modes.custom_mode(flight.mode),
            base_mode=flavour.modes.base_mode(flight.mode, flight.armed),
            system_status=self._system_status(now), landed_state=flight.landed_state,
            mission_seq=self.store.current if self.store.total else 0,
            mission_total=self.store.total, mission_state=int(flight.runner.state),
            home=(home.lat, home.lon, home.alt_amsl), estimate_ready=flight.estimate_ready(now),
        )

    def _system_status(self, now: float) -> int:
        if now - self._boot_time < self.flavour.boot_status_s:
            return mavlink.MAV_STATE_BOOT
        return mavlink.MAV_STATE_ACTIVE if self.flight.armed else mavlink.MAV_STATE_STANDBY

    def _home_item(self) -> MissionItem:
        home = self.flight.home
        return MissionItem(seq=0, frame=mavlink.MAV_FRAME_GLOBAL,
                           command=mavlink.MAV_CMD_NAV_WAYPOINT, x=round(home.lat * 1e7),
                           y=round(home.lon * 1e7), z=home.alt_amsl)

    # -- inbound messages -----------------------------------------------------------------

    def _handle(self, msg: Message, link: Hashable, now: float) -> None:
        target = getattr(msg, "target_system", 0)
        if target not in (0, self.sysid):
            return  # for another vehicle on a shared link
        self._gcs_heard = True
        sender = Sender(msg.get_srcSystem(), msg.get_srcComponent(), link)
        kind = msg.get_type()
        if kind.startswith("MISSION_"):
            self.store.handle(msg, sender, now)
            return
        handler = self._handlers.get(kind)
        if handler is not None:
            handler(self, msg, sender, now)

    def _on_command(self, msg: Message, sender: Sender, now: float) -> None:
        command = Command.from_message(msg, sender)
        outcome = self.commands.handle(command, now)
        self.send(messages.command_ack(command.id, outcome.result, sender.sysid, sender.compid))
        for msg_id in outcome.then:
            self._send_by_id(msg_id)

    def _on_set_mode(self, msg: Message, sender: Sender, now: float) -> None:
        result = self.commands.set_mode(msg.base_mode, msg.custom_mode, now)
        self.send(messages.command_ack(mavlink.MAVLINK_MSG_ID_SET_MODE, result, sender.sysid,
                                       sender.compid))

    def _on_request_data_stream(self, msg: Message, sender: Sender, now: float) -> None:
        self.schedule.request_data_stream(msg.req_stream_id, msg.req_message_rate,
                                          bool(msg.start_stop), now)

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

    def _send_by_id(self, msg_id: int) -> None:
        if msg_id == mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            self.send(messages.autopilot_version(self.sysid, self.flavour))
        else:
            self.send(messages.BUILDERS[msg_id](self.state(), self.flavour))

    _handlers: ClassVar[dict[str, Callable[[Vehicle, Message, Sender, float], None]]] = {
        "COMMAND_LONG": _on_command,
        "COMMAND_INT": _on_command,
        "SET_MODE": _on_set_mode,
        "REQUEST_DATA_STREAM": _on_request_data_stream,
        "PARAM_REQUEST_LIST": _on_param_request_list,
        "PARAM_REQUEST_READ": _on_param_request_read,
        "PARAM_SET": _on_param_set,
    }


def _param_name(raw: str | bytes) -> str:
    text = raw.decode(errors="replace") if isinstance(raw, bytes) else raw
    return text.split("\x00", 1)[0]
