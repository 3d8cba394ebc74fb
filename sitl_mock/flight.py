"""The flight controller: arming, modes, take-off, landing and idle disarm, as ArduCopter
(or PX4) decides them. Motion itself is delegated to manoeuvres and the mission runner."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

from .codec import mavlink
from .flavour import Flavour
from .kinematics import Body, NavLimits
from .manoeuvres import TAKEOFF, Climb, Hold, Land, Manoeuvre, return_home
from .mission_runner import ItemPlacer, MissionEvents, MissionRunner
from .mission_store import MissionStore
from .modes import REQUIRES_POSITION, FlightMode
from .params import ParameterSet

ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
FAILED = mavlink.MAV_RESULT_FAILED
DENIED = mavlink.MAV_RESULT_DENIED

AIRBORNE_ABOVE_M = 0.5
NOT_ARMABLE = frozenset({FlightMode.AUTO, FlightMode.RTL, FlightMode.LAND})
USER_TAKEOFF_MODES = frozenset({FlightMode.GUIDED, FlightMode.LOITER})
"""ArduCopter modes in which a NAV_TAKEOFF command is obeyed."""


@dataclass(frozen=True)
class Home:
    lat: float
    lon: float
    alt_amsl: float
    east: float
    north: float


class FlightController:
    """One vehicle's flight state and the decisions a real autopilot takes about it."""

    def __init__(self, flavour: Flavour, body: Body, params: ParameterSet, store: MissionStore,
                 home: Home, to_local: Callable[[float, float], tuple[float, float]],
                 events: MissionEvents, say: Callable[[int, str], None],
                 estimate_delay_s: float) -> None:
        self.flavour = flavour
        self.body = body
        self.params = params
        self.home = home
        self.estimate_delay_s = estimate_delay_s
        self._say = say
        self._boot_time = 0.0
        self._cruise_override: float | None = None
        placer = ItemPlacer(to_local, lambda: self.home.alt_amsl)
        implicit_takeoff = None if flavour.needs_mission_start else self._px4_takeoff_alt()
        self.runner = MissionRunner(
            store, body, placer, self.limits, lambda: (self.home.east, self.home.north),
            lambda: flavour.rtl_alt_m(params), events, takeoff_alt_if_missing=implicit_takeoff,
        )
        self._reset_state()

    def _reset_state(self) -> None:
        self.mode = self.flavour.boot_mode
        self.armed = False
        self._manoeuvre: Manoeuvre | None = None
        self._mission_start_given = False
        self._airborne = False
        self._idle_since: float | None = None
        self.runner.stop()

    # -- state ------------------------------------------------------------------------------

    def estimate_ready(self, now: float) -> bool:
        return now - self._boot_time >= self.estimate_delay_s

    @property
    def airborne(self) -> bool:
        return self._airborne

    @property
    def landed_state(self) -> int:
        phase = self.runner.phase if self.mode == FlightMode.AUTO else (
            None if self._manoeuvre is None else self._manoeuvre.phase)
        if not self._airborne:
            climbing = self.armed and phase == TAKEOFF
            return mavlink.MAV_LANDED_STATE_TAKEOFF if climbing else (
                mavlink.MAV_LANDED_STATE_ON_GROUND)
        return phase if phase is not None else mavlink.MAV_LANDED_STATE_IN_AIR

    def limits(self) -> NavLimits:
        limits = self.flavour.limits(self.params)
        if self._cruise_override is not None:
            limits = replace(limits, cruise_speed=self._cruise_override)
        return limits

    def apply_limits(self) -> None:
        """Parameters or speed changed: tell the kinematics."""
        self.body.apply_limits(self.limits())

    # -- commands ---------------------------------------------------------------------------

    def arm(self, now: float, force: bool = False) -> int:
        if self.armed:
            return ACCEPTED
        if not force:
            refusal = self._arming_refusal(now)
            if refusal is not None:
                self._say(mavlink.MAV_SEVERITY_CRITICAL, refusal)
                return self.flavour.arm_rejected_result
        self.armed = True
        self._idle_since = now
        self.apply_limits()
        if self.mode == FlightMode.AUTO:
            self._start_auto(now)
        return ACCEPTED

    def _arming_refusal(self, now: float) -> str | None:
        px4 = not self.flavour.needs_mission_start
        if not self.estimate_ready(now):
            return "Arming denied: no position estimate" if px4 else "Arm: Need Position Estimate"
        if self.mode in NOT_ARMABLE and not (px4 and self.mode == FlightMode.AUTO):
            return f"Arming denied: {self.mode.value} mode" if px4 else (
                f"Arm: {self.mode.value} mode not armable")
        return None

    def prearm_text(self, now: float) -> str | None:
        """The periodic pre-arm complaint while the estimate is not ready (ArduPilot)."""
        if self.armed or self.estimate_ready(now) or not self.flavour.needs_mission_start:
            return None
        return "PreArm: Need Position Estimate"

    def disarm(self, now: float, force: bool = False) -> int:
        if not self.armed:
            return ACCEPTED
        if self._airborne and not force:
            self._say(mavlink.MAV_SEVERITY_CRITICAL, "Disarm: vehicle is flying")
            return FAILED
        self._disarm()
        return ACCEPTED

    def set_mode(self, mode: FlightMode, now: float) -> int:
        if not self.flavour.modes.supports(mode):
            return DENIED
        if mode == self.mode:
            return ACCEPTED
        if mode in REQUIRES_POSITION and not self.estimate_ready(now):
            self._say(mavlink.MAV_SEVERITY_WARNING,
                      f"Mode change to {mode.value} failed: requires position")
            return FAILED
        if (mode == FlightMode.AUTO and self.flavour.needs_mission_start and self.armed
                and not self._airborne and not self.runner.starts_with_takeoff()):
            self._say(mavlink.MAV_SEVERITY_CRITICAL, "Auto: Missing Takeoff Cmd")
            return FAILED
        self._enter(mode, now)
        return ACCEPTED

    def takeoff(self, alt: float, now: float) -> int:
        """NAV_TAKEOFF command: climb to `alt` metres above home and hold there."""
        if not self.armed or self._airborne or not self.estimate_ready(now):
            return FAILED
        if self.flavour.needs_mission_start:
            if self.mode not in USER_TAKEOFF_MODES:
                return FAILED
            self._run(Climb(alt), now)
        else:
            self._enter(FlightMode.TAKEOFF, now, takeoff_alt=alt)
        self._idle_since = None
        return ACCEPTED

    def start_mission(self, now: float) -> int:
        """MISSION_START: AUTO, and (ArduCopter) permission to climb from the ground."""
        result = self.set_mode(FlightMode.AUTO, now)
        if result != ACCEPTED:
            return result
        self._mission_start_given = True
        if self.armed and not self.runner.running:
            self._start_auto(now)
        return ACCEPTED

    def pause(self, now: float) -> int:
        if self.mode == FlightMode.AUTO and self.runner.running:
            self.runner.pause(now)
            return ACCEPTED
        if self._airborne:
            self._run(Hold(), now)
            return ACCEPTED
        return FAILED

    def resume(self, now: float) -> int:
        if self.mode == FlightMode.AUTO and self.runner.running:
            self.runner.resume(now)
        return ACCEPTED

    def change_speed(self, speed: float) -> int:
        if not speed > 0 or not math.isfinite(speed):
            return FAILED
        self._cruise_override = speed
        self.apply_limits()
        return ACCEPTED

    # -- time -------------------------------------------------------------------------------

    def update(self, now: float) -> None:
        self.body.set_active(self.armed)
        if not self.armed:
            return
        if self.mode == FlightMode.AUTO:
            self.runner.update(now)
        elif self._manoeuvre is not None and self._manoeuvre.update(self.body, now):
            self._manoeuvre_done(now)
        self._watch_ground(now)

    def reboot(self, now: float) -> None:
        """Power-cycle: disarmed on the ground at home, estimate not ready again."""
        self._reset_state()
        self._boot_time = now
        self._cruise_override = None
        self.body.place(self.home.east, self.home.north, 0.0)
        self.body.set_active(False)

    def _watch_ground(self, now: float) -> None:
        alt = self.body.alt
        if alt > AIRBORNE_ABOVE_M:
            self._airborne = True
            self._idle_since = None
        elif self._airborne and alt <= 0.0:
            self._airborne = False
            self._say(mavlink.MAV_SEVERITY_INFO, "Land complete")
            self._disarm()
        elif not self._airborne and self.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND:
            if self._idle_since is None:
                self._idle_since = now
            elif now - self._idle_since >= self._disarm_delay():
                self._say(mavlink.MAV_SEVERITY_INFO, "Disarming motors")
                self._disarm()

    def _disarm_delay(self) -> float:
        for name in ("DISARM_DELAY", "COM_DISARM_PRFLT"):
            if name in self.params:
                return self.params.get(name)
        return 10.0

    # -- internals --------------------------------------------------------------------------

    def _enter(self, mode: FlightMode, now: float, takeoff_alt: float | None = None) -> None:
        self.mode = mode
        self._manoeuvre = None
        if mode != FlightMode.AUTO:
            self.runner.stop()
        if mode == FlightMode.AUTO:
            if self.armed and (self._airborne or not self.flavour.needs_mission_start
                               or self._mission_start_given):
                self._start_auto(now)
        elif mode == FlightMode.TAKEOFF:
            if self.armed:
                self._run(Climb(takeoff_alt or self._px4_takeoff_alt()), now)
        elif not self._airborne:
            return
        elif mode == FlightMode.RTL:
            self._run(return_home(self.body, (self.home.east, self.home.north),
                                  self.flavour.rtl_alt_m(self.params), self.limits()), now)
        elif mode == FlightMode.LAND:
            self._run(Land(self.limits()), now)
        else:
            self._run(Hold(), now)

    def _start_auto(self, now: float) -> None:
        self._idle_since = None
        self.runner.start(now)

    def _run(self, manoeuvre: Manoeuvre, now: float) -> None:
        self._manoeuvre = manoeuvre
        manoeuvre.start(self.body, now)

    def _manoeuvre_done(self, now: float) -> None:
        if self.mode == FlightMode.TAKEOFF:
            self._enter(self.flavour.after_takeoff_mode, now)
        elif self._airborne:
            self._run(Hold(), now)
        else:
            self._manoeuvre = None

    def _disarm(self) -> None:
        self.armed = False
        self._manoeuvre = None
        self._mission_start_given = False
        self._idle_since = None
        self.runner.stop()
        self.body.set_active(False)
        if self.body.alt > 0:
            east, north, _ = self.body.position
            self.body.place(east, north, 0.0)  # a forced disarm in flight: it falls
        self._airborne = False

    def _px4_takeoff_alt(self) -> float:
        return self.params.get("MIS_TAKEOFF_ALT") if "MIS_TAKEOFF_ALT" in self.params else 2.5
