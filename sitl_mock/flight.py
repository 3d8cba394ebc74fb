"""The flight controller: arming, modes, take-off, landing and idle disarm, as ArduCopter
(or PX4) decides them. Motion itself is delegated to manoeuvres and the mission runner."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

from . import fence
from .codec import mavlink
from .fence import FenceMonitor, Zones
from .flavour import Flavour
from .kinematics import Body, NavLimits
from .manoeuvres import (
    IN_AIR,
    LANDING,
    ON_GROUND,
    TAKEOFF,
    Climb,
    FlyTo,
    Hold,
    Land,
    Manoeuvre,
    Stop,
    return_home,
)
from .mission_runner import ItemPlacer, MissionEvents, MissionRunner, MissionState
from .mission_store import MissionStore
from .modes import ARDUCOPTER_NAMES, REQUIRES_POSITION, FlightMode
from .params import ParameterSet
from .readiness import Timeline, arducopter_arming_failures, arducopter_mandatory_failures

ACCEPTED: int = mavlink.MAV_RESULT_ACCEPTED
FAILED: int = mavlink.MAV_RESULT_FAILED
DENIED: int = mavlink.MAV_RESULT_DENIED

AIRBORNE_ABOVE_M = 0.5
LAND_DETECT_S = 2.1
"""Seconds from touching the ground to "Land complete" and disarming: ArduCopter's land
detector waits for its motors to sit at their lower limit for a second, then spools them
down before it disarms (SITL 4.8.0-dev: 2.1 s after each of six landings touched down;
the mock disarmed at the touch, and a vehicle waiting for the landing went 2 s early)."""
NOT_ARMABLE = frozenset({FlightMode.AUTO, FlightMode.RTL, FlightMode.LAND})
RALLY_LIMIT_M = 300.0
"""ArduCopter's RALLY_LIMIT_KM default: a nearest rally point further away is not used."""
SPEED_MODES = frozenset({FlightMode.AUTO, FlightMode.GUIDED, FlightMode.RTL})
"""ArduCopter modes that take a DO_CHANGE_SPEED."""
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

    def __init__(
        self,
        flavour: Flavour,
        body: Body,
        params: ParameterSet,
        store: MissionStore,
        home: Home,
        to_local: Callable[[float, float], tuple[float, float]],
        events: MissionEvents,
        say: Callable[[int, str], None],
        timeline: Timeline,
    ) -> None:
        self.flavour = flavour
        self.body = body
        self.params = params
        self.home = home
        self.timeline = timeline
        self._say = say
        self._to_local = to_local
        self.fence = FenceMonitor()
        self._recovery_until = -math.inf
        self._zones = Zones()
        self._zones_version = -1
        self._boot_time = 0.0
        self._cruise_override: float | None = None
        placer = ItemPlacer(to_local, lambda: self.home.alt_amsl)
        implicit_takeoff = None if flavour.needs_mission_start else self._px4_takeoff_alt()
        self.store = store
        self.runner = MissionRunner(
            store,
            body,
            placer,
            self.limits,
            lambda: (self.home.east, self.home.north),
            lambda: flavour.rtl_alt_m(params),
            events,
            takeoff_alt_if_missing=implicit_takeoff,
        )
        self._reset_state()

    def _reset_state(self) -> None:
        self.mode = self.flavour.boot_mode
        self.armed = False
        self._manoeuvre: Manoeuvre | None = None
        self._mission_start_given = False
        self._airborne = False
        self._idle_since: float | None = None
        self._touched_at: float | None = None
        self.runner.stop()

    # -- state ------------------------------------------------------------------------------

    def uptime(self, now: float) -> float:
        return now - self._boot_time

    def booted(self, now: float) -> bool:
        """Initialisation is over ("ArduPilot Ready")."""
        return self.uptime(now) >= self.timeline.ready_s

    def position_known(self, now: float) -> bool:
        """The GPS has a fix: telemetry reports a position."""
        return self.uptime(now) >= self.timeline.gps_fix_s

    def home_set(self, now: float) -> bool:
        """The EKF origin and home exist (HOME_POSITION, GPS_GLOBAL_ORIGIN)."""
        return self.uptime(now) >= self.timeline.origin_s

    def estimate_ready(self, now: float) -> bool:
        """The position estimate is good enough to arm and fly in modes that need it."""
        return self.uptime(now) >= self.timeline.estimate_s

    def finish_boot(self) -> None:
        """ArduCopter sets its boot mode when initialisation ends, whatever was asked before."""
        if not self.armed:
            self._enter(self.flavour.boot_mode, self._boot_time)

    @property
    def airborne(self) -> bool:
        return self._airborne

    @property
    def holding(self) -> bool:
        """Told to stop where it is: a paused mission, a paused GUIDED or BRAKE (whether
        still slowing down or hovering already)."""
        if self.mode == FlightMode.AUTO:
            return self.runner.state == MissionState.PAUSED
        return isinstance(self._manoeuvre, (Hold, Stop))

    @property
    def landed_state(self) -> int:
        phase = (
            self.runner.phase
            if self.mode == FlightMode.AUTO
            else (None if self._manoeuvre is None else self._manoeuvre.phase)
        )
        if not self._airborne:
            climbing = self.armed and phase == TAKEOFF
            return TAKEOFF if climbing else ON_GROUND
        if self._touched_at is not None:  # down, until the land detector is sure
            return LANDING
        return phase if phase is not None else IN_AIR

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
        failures = self.arming_failures(now, force)
        if failures:
            for text in failures:  # one STATUSTEXT per failed check, as ArduPilot reports
                self._say(mavlink.MAV_SEVERITY_CRITICAL, text)
            return self.flavour.arm_rejected_result
        self.armed = True
        self._idle_since = now
        self.apply_limits()
        if self.mode == FlightMode.AUTO:
            self._start_auto(now)
        return ACCEPTED

    def arming_failures(self, now: float, force: bool = False) -> list[str]:
        """The texts an arming attempt fails with now (none: it arms)."""
        if not self.flavour.needs_mission_start:
            return self._px4_arming_failures(now, force)
        needs_position = self.mode in REQUIRES_POSITION
        uptime = self.uptime(now)
        failures = arducopter_mandatory_failures(self.timeline, uptime, needs_position)
        if force and failures:  # then the full checks run too (AP_Arming::arm), as SITL said
            extra = arducopter_arming_failures(self.timeline, uptime, needs_position)
            failures += [text for text in extra if text not in failures]
        elif not force:
            failures = arducopter_arming_failures(self.timeline, uptime, needs_position)
        if not failures and not force and self.fence.breaches:
            failures = [f"Vehicle breaching {fence.fence_names(self.fence.breaches)}"]
        if not failures and not force and self.mode in NOT_ARMABLE:
            failures = [f"{ARDUCOPTER_NAMES[self.mode]} mode not armable"]
        return [f"Arm: {text}" for text in failures]

    def _px4_arming_failures(self, now: float, force: bool) -> list[str]:
        if force:
            return []
        if not self.estimate_ready(now):
            return ["Arming denied: no position estimate"]
        if self.mode in NOT_ARMABLE and self.mode != FlightMode.AUTO:
            return [f"Arming denied: {self.mode.value} mode"]
        return []

    def prearm_texts(self, now: float) -> list[str]:
        """The periodic pre-arm report of a disarmed ArduCopter: every check failing now."""
        if self.armed or not self.flavour.needs_mission_start:
            return []
        failures = arducopter_arming_failures(
            self.timeline, self.uptime(now), self.mode in REQUIRES_POSITION
        )
        return [f"PreArm: {text}" for text in failures]

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
        if self._needs_position_for(mode) and not self.estimate_ready(now):
            self._say(
                mavlink.MAV_SEVERITY_WARNING,
                f"Mode change to {self._mode_name(mode)} failed: requires position",
            )
            return FAILED
        if (
            mode == FlightMode.AUTO
            and self.flavour.needs_mission_start
            and self.armed
            and not self._airborne
            and not self.runner.starts_with_takeoff()
        ):
            self._say(mavlink.MAV_SEVERITY_CRITICAL, "Auto: Missing Takeoff Cmd")
            return FAILED
        self._enter(mode, now)
        return ACCEPTED

    def _mode_name(self, mode: FlightMode) -> str:
        if self.flavour.needs_mission_start:
            return ARDUCOPTER_NAMES.get(mode, mode.value)
        return mode.value

    def _needs_position_for(self, mode: FlightMode) -> bool:
        """ArduCopter checks a mode's position needs only when armed (disarmed, the arming
        checks do it); PX4 refuses such modes outright."""
        if mode not in REQUIRES_POSITION:
            return False
        return self.armed or not self.flavour.needs_mission_start

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

    def guided_target(self, lat: float, lon: float, alt: float, now: float) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT (a position, `alt` above home): ArduCopter flies
        to it in GUIDED (a take-off under way included: the climb becomes the flight to
        the point) and holds there; outside GUIDED, on the ground or disarmed it is
        ignored, with no answer (the message has no ACK)."""
        if not self.flavour.needs_mission_start or self.mode != FlightMode.GUIDED:
            return
        if not self.armed or not self._airborne:
            return
        east, north = self._to_local(lat, lon)
        if not self._within_fence(east, north, alt):
            return  # ModeGuided::set_pos_NED_m refuses a destination the fence excludes
        flying = self._manoeuvre
        if isinstance(flying, FlyTo) and (flying.east, flying.north, flying.alt) == (
            east,
            north,
            alt,
        ):
            return  # the same target again: the flight to it goes on
        self._run(FlyTo(east, north, alt, radius=0.0, hold_s=math.inf), now)
        self._idle_since = None

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
        """DO_PAUSE_CONTINUE 0. ArduCopter pauses AUTO only on the way to a place and
        GUIDED anywhere, and answers everything else FAILED with "Failed to pause"; PX4
        holds whatever it is flying."""
        strict = self.flavour.pauses_only_on_the_way
        if self.mode == FlightMode.AUTO and self.runner.running:
            if not strict or self.runner.on_the_way_to_a_place():
                self.runner.pause(now, self.flavour.pauses_on_the_track)
                return ACCEPTED
        elif self._airborne and (not strict or self.mode == FlightMode.GUIDED):
            self._run(Hold(), now)
            return ACCEPTED
        if strict:
            self._say(mavlink.MAV_SEVERITY_INFO, "Failed to pause")
        return FAILED

    def resume(self, now: float) -> int:
        """DO_PAUSE_CONTINUE 1: ArduCopter resumes only in AUTO and GUIDED."""
        if self.mode == FlightMode.AUTO and self.runner.running:
            self.runner.resume(now)
        elif self.flavour.pauses_only_on_the_way and self.mode != FlightMode.GUIDED:
            self._say(mavlink.MAV_SEVERITY_INFO, "Failed to resume")
            return FAILED
        return ACCEPTED

    def change_speed(self, speed: float) -> int:
        """DO_CHANGE_SPEED: the leg being flown changes speed at once (AC_WPNav::
        set_speed_NE re-plans it), and so do the legs after it. ArduCopter takes it in
        AUTO, GUIDED and RTL only (`Mode::set_speed_NE_ms`): FAILED in BRAKE, LAND, ...
        (SITL 4.8.0-dev, a vehicle braked by its GCS failsafe)."""
        if not speed > 0 or not math.isfinite(speed):
            return FAILED
        if self.flavour.needs_mission_start and self.mode not in SPEED_MODES:
            return FAILED
        self._cruise_override = speed
        self.apply_limits()
        self.body.set_cruise(
            self.limits().cruise_speed, self.flavour.slows_a_speed_up_only_by_its_plateau
        )
        return ACCEPTED

    # -- time -------------------------------------------------------------------------------

    def update(self, now: float) -> None:
        self.body.set_active(self.armed)
        if self.armed:
            if self.mode == FlightMode.AUTO:
                self.runner.update(now)
            elif self._manoeuvre is not None and self._manoeuvre.update(self.body, now):
                self._manoeuvre_done(now)
            self._watch_ground(now)
        if self.flavour.needs_mission_start:
            self._check_fence(now)

    # -- the geofence (ArduCopter) ------------------------------------------------------------

    @property
    def fence_enabled(self) -> bool:
        return "FENCE_ENABLE" in self.params and self.params.get("FENCE_ENABLE") == 1

    def fence_types(self) -> int:
        """The fences in force: FENCE_TYPE's bits, polygons only when some are stored."""
        if not self.fence_enabled:
            return 0
        types = int(self.params.get("FENCE_TYPE")) & (fence.ALT_MAX | fence.CIRCLE | fence.POLYGON)
        if self.zones().empty:
            types &= ~fence.POLYGON
        return types

    def zones(self) -> Zones:
        if self._zones_version != self.store.fence_version:
            self._zones = Zones.of(self.store.items(mavlink.MAV_MISSION_TYPE_FENCE), self._to_local)
            self._zones_version = self.store.fence_version
        return self._zones

    def _check_fence(self, now: float) -> None:
        """Copter::fence_check: checked armed or not; acted on only when armed."""
        had, types = self.fence.breaches, self.fence_types()
        if not had and not types:
            return  # nothing enabled and nothing to clear: a check would find nothing
        east, north, up = self.body.position
        breach = self.fence.check(
            types,
            self.zones(),
            (float(east), float(north), float(up)),
            (self.home.east, self.home.north),
            (self.params.get("FENCE_ALT_MAX"), self.params.get("FENCE_RADIUS")),
            int(self.uptime(now) * 1000),
            recovering=now < self._recovery_until,
        )
        if breach is None:
            if had and not self.fence.breaches and self._airborne:
                self._say(mavlink.MAV_SEVERITY_NOTICE, "Fence breach cleared")
            return
        if not self.armed:
            return
        if self._airborne:
            self._say(mavlink.MAV_SEVERITY_NOTICE, f"{fence.fence_names(breach.new)} breached")
        action = int(self.params.get("FENCE_ACTION"))
        if action == 0:
            return
        if not self._airborne:
            self._disarm()
            return
        if breach.distance_m > fence.GIVE_UP_DISTANCE_M:
            self._enter(FlightMode.LAND, now)
            return
        tries = {
            2: [FlightMode.LAND],
            3: [FlightMode.RTL, FlightMode.LAND],  # SmartRTL is not simulated
            4: [FlightMode.BRAKE, FlightMode.LAND],
            5: [FlightMode.LAND],  # SmartRTL, else LAND
        }.get(action, [FlightMode.RTL, FlightMode.LAND])
        for mode in tries:
            if self.set_mode(mode, now) == ACCEPTED:
                return

    def reboot(self, now: float) -> None:
        """Power-cycle: disarmed on the ground at home, estimate not ready again."""
        self._reset_state()
        self.fence.reset()
        self._recovery_until = -math.inf
        self._boot_time = now
        self._cruise_override = None
        self.body.place(self.home.east, self.home.north, 0.0)
        self.body.set_active(False)

    def _watch_ground(self, now: float) -> None:
        alt = self.body.alt
        if alt > AIRBORNE_ABOVE_M:
            self._airborne = True
            self._idle_since = self._touched_at = None
        elif self._airborne and alt <= 0.0:
            if self._touched_at is None:
                self._touched_at = now
            if now - self._touched_at < LAND_DETECT_S:
                return
            self._airborne, self._touched_at = False, None
            self._say(mavlink.MAV_SEVERITY_INFO, "Land complete")
            self._disarm()
        elif not self._airborne and self.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND:
            if self._idle_since is None:
                self._idle_since = now
            elif 0 < self._disarm_delay() <= now - self._idle_since:
                self._say(mavlink.MAV_SEVERITY_INFO, "Disarming motors")
                self._disarm()

    def _disarm_delay(self) -> float:
        """Seconds an armed vehicle may idle on the ground; 0 or less: never disarms."""
        for name in ("DISARM_DELAY", "COM_DISARM_PRFLT"):
            if name in self.params:
                return self.params.get(name)
        return 10.0

    # -- internals --------------------------------------------------------------------------

    def _enter(self, mode: FlightMode, now: float, takeoff_alt: float | None = None) -> None:
        self.mode = mode
        self._manoeuvre = None
        if self.fence.breaches and self.flavour.needs_mission_start:
            self._manual_recovery(now)
        if mode != FlightMode.AUTO:
            self.runner.stop()
        if mode == FlightMode.AUTO:
            if self.flavour.forgets_speed_in_auto and self._cruise_override is not None:
                self._cruise_override = None  # ArduCopter: ModeAuto::init clears it
                self.apply_limits()
            if self.armed and (
                self._airborne or not self.flavour.needs_mission_start or self._mission_start_given
            ):
                self._start_auto(now)
        elif mode == FlightMode.TAKEOFF:
            if self.armed:
                self._run(Climb(takeoff_alt or self._px4_takeoff_alt()), now)
        elif not self._airborne:
            if self.armed and (mode == FlightMode.LAND or self.body.alt > 0):
                self._run(Land(self.limits()), now)  # lifting off: back down, not on up
            return
        elif mode == FlightMode.RTL:
            self._run(
                return_home(
                    self.body,
                    self._return_point(),
                    self.flavour.rtl_alt_m(self.params),
                    self.limits(),
                ),
                now,
            )
        elif mode == FlightMode.LAND:
            self._run(Land(self.limits()), now)
        elif mode == FlightMode.BRAKE:
            self._run(Stop(brake=True), now)
        else:
            self._run(Hold(), now)

    def _within_fence(self, east: float, north: float, alt: float) -> bool:
        """AC_Fence::check_destination_within_fence, for the fences in force."""
        types = self.fence_types()
        if types & fence.ALT_MAX and alt > self.params.get("FENCE_ALT_MAX"):
            return False
        home = (self.home.east, self.home.north)
        if types & fence.CIRCLE and math.dist((east, north), home) > self.params.get(
            "FENCE_RADIUS"
        ):
            return False
        return not (types & fence.POLYGON and self.zones().breach_distance(east, north) is not None)

    def _manual_recovery(self, now: float) -> None:
        """Copter::set_mode during a breach (any mode change, the fence's own included):
        AC_Fence::manual_recovery_start ignores new breaches for 10 s."""
        if self.params.get("FENCE_ACTION") != 0:
            self._recovery_until = now + fence.MANUAL_RECOVERY_S
            self._say(mavlink.MAV_SEVERITY_INFO, "Manual recovery started")

    def _return_point(self) -> tuple[float, float]:
        """ArduCopter's RTL target (AP_Rally::calc_best_rally_or_home_location): the
        nearest rally point inside the enabled fences, unless it is beyond RALLY_LIMIT_KM
        (0.3) or home is nearer (RALLY_INCL_HOME 1); home without one."""
        here = tuple(float(v) for v in self.body.position[:2])
        home = (self.home.east, self.home.north)
        if not self.flavour.needs_mission_start:
            return home
        best: tuple[float, float] | None = None
        for item in self.store.items(mavlink.MAV_MISSION_TYPE_RALLY):
            point = self._to_local(item.lat, item.lon)
            if not self._within_fence(*point, 0.0):
                continue  # AP_Rally_Copter::is_valid: not outside the fence
            if best is None or math.dist(point, here) < math.dist(best, here):
                best = point
        if best is None or math.dist(best, here) > RALLY_LIMIT_M:
            return home
        return best if math.dist(best, here) < math.dist(home, here) else home

    def _start_auto(self, now: float) -> None:
        self._idle_since = None
        self.runner.start(now)

    def _run(self, manoeuvre: Manoeuvre, now: float) -> None:
        self._manoeuvre = manoeuvre
        manoeuvre.start(self.body, now)

    def _manoeuvre_done(self, now: float) -> None:
        if self.mode == FlightMode.TAKEOFF:
            self._enter(self.flavour.after_takeoff_mode, now)
        elif self._airborne and self.body.alt > 0.0:
            self._run(Hold(), now)
        else:  # on the ground (a landing waits for its land detector there)
            self._manoeuvre = None

    def _disarm(self) -> None:
        self.armed = False
        self._manoeuvre = None
        self._mission_start_given = False
        self._idle_since = None
        if self.flavour.needs_mission_start:
            self.runner.rewind(active=self.mode == FlightMode.AUTO)  # ArduCopter resets it
        else:
            self.runner.stop()
        self.body.set_active(False)
        if self.body.alt > 0:
            east, north, _ = self.body.position
            self.body.place(east, north, 0.0)  # a forced disarm in flight: it falls
        self._airborne, self._touched_at = False, None

    def _px4_takeoff_alt(self) -> float:
        return self.params.get("MIS_TAKEOFF_ALT") if "MIS_TAKEOFF_ALT" in self.params else 2.5
