"""What differs between an ArduCopter and a PX4 vehicle on the wire, in one record each."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from . import ardupilot_storage
from .codec import mavlink
from .kinematics import NavLimits
from .mission_item import MissionItem
from .modes import ARDUCOPTER_MODES, PX4_MODES, FlightMode, ModeTable
from .params import (
    ARDUCOPTER_DEFAULTS,
    PX4_DEFAULTS,
    ParameterSet,
    arducopter_limits,
    px4_limits,
)


@dataclass(frozen=True)
class Flavour:
    name: str
    autopilot: int
    """HEARTBEAT.autopilot (MAV_AUTOPILOT)."""
    modes: ModeTable
    boot_mode: FlightMode
    home_is_item_zero: bool
    """ArduPilot keeps home as mission item 0."""
    item_request_id: int
    """How the vehicle asks for an item on upload: MISSION_REQUEST (40) or _INT (51)."""
    rerequest_s: float
    """Wall seconds without an item before the vehicle asks again (a protocol timer)."""
    upload_timeout_s: float
    """Wall seconds without an item before the vehicle cancels the upload."""
    item_refusal: Callable[[MissionItem], int | None]
    """The MAV_MISSION_RESULT with which the autopilot refuses an uploaded item, or None."""
    store_item: Callable[[MissionItem], MissionItem]
    """The item as the autopilot stores it (and a download returns it)."""
    streams_by_default: bool
    repeats_item_reached: bool
    needs_mission_start: bool
    """ArduCopter on the ground in AUTO waits for MISSION_START before it climbs."""
    arm_in_auto: bool
    arm_rejected_result: int
    sysid_param: str
    param_defaults: tuple[tuple[str, float, int], ...]
    params_bytewise: bool
    limits: Callable[[ParameterSet], NavLimits]
    rtl_alt_m: Callable[[ParameterSet], float]
    takeoff_mode: FlightMode
    """Mode a NAV_TAKEOFF command leaves the vehicle in (GUIDED; PX4 TAKEOFF)."""
    after_takeoff_mode: FlightMode
    mission_end_mode: FlightMode
    merges_item_reached: bool
    """ArduPilot queues one MISSION_ITEM_REACHED per loop: items done together report only the
    last; it reports DO items and never NAV_LAND (the landing disarms first). PX4 reports
    each navigation item, landing included, and repeats it."""
    announces_items: bool
    """ArduPilot says "Mission: N Name" as each item starts and "Reached command #N"."""
    sends_unasked: bool
    """ArduPilot sends TIMESYNC, and GPS_GLOBAL_ORIGIN and HOME_POSITION when home is set,
    to a ground station that asked for nothing."""
    pauses_only_on_the_way: bool
    """ArduCopter pauses (DO_PAUSE_CONTINUE) an AUTO mission only while flying to a place
    it has not reached (its WP submode: a waypoint, a loiter, a landing's place), and
    GUIDED; anything else (a take-off, a descent, a stop at a waypoint, other modes) it
    answers FAILED. PX4 holds from any flying state."""
    forgets_speed_in_auto: bool
    """ArduCopter drops a DO_CHANGE_SPEED given as a command whenever it enters AUTO (after
    a BRAKE, say) and flies at WP_SPD until the mission's next speed item; PX4 keeps it."""
    pauses_on_the_track: bool
    """ArduCopter pauses a mission (DO_PAUSE_CONTINUE 0) by running the clock of its
    S-curve down (AC_WPNav), not by braking: the curve goes on meanwhile, so a pause while
    speeding up out of a corner on a 10 m/s track took 14.1 m from 3.8 m/s on SITL 4.8,
    and a resume (1) runs the clock up again on the speed the track had when paused, even
    when a DO_CHANGE_SPEED asked for less meanwhile (paused at 5 m/s, given 1 m/s,
    resumed: 4.9 m/s 2 s later, 1.0 m/s after 6 s; `bench/approach_vs_sitl.py`). PX4
    slows along its velocity and goes on at the speed asked."""
    slows_a_speed_up_only_by_its_plateau: bool
    """ArduCopter's S-curve cannot lower the speed of a leg that is speeding up except by
    cutting short the part at constant acceleration (SCurve::set_speed_max): its jerk
    ramps run on. A leg from rest at 10 m/s told 1 m/s (DO_CHANGE_SPEED) 0.1 s after it
    began went on up to 6.5 m/s on SITL 4.8, the speed its ramps alone give (WP_ACC²/
    WP_JERK); one with no such part, or past it, keeps its speed (`bench/approach_vs_sitl.py
    --variant restart-then-speed`). PX4 follows the new speed."""

    def new_params(self, sysid: int) -> ParameterSet:
        params = ParameterSet(self.param_defaults, bytewise=self.params_bytewise)
        params.set(self.sysid_param, sysid)
        return params


ARDUPILOT = Flavour(
    name="ardupilot",
    autopilot=mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
    modes=ARDUCOPTER_MODES,
    boot_mode=FlightMode.STABILIZE,
    home_is_item_zero=True,
    item_request_id=mavlink.MAVLINK_MSG_ID_MISSION_REQUEST,
    rerequest_s=1.0,
    upload_timeout_s=8.0,
    item_refusal=ardupilot_storage.refusal,
    store_item=ardupilot_storage.stored,
    streams_by_default=False,
    repeats_item_reached=False,
    needs_mission_start=True,
    arm_in_auto=False,
    arm_rejected_result=mavlink.MAV_RESULT_FAILED,
    sysid_param="MAV_SYSID",
    param_defaults=ARDUCOPTER_DEFAULTS,
    params_bytewise=False,
    limits=arducopter_limits,
    rtl_alt_m=lambda params: params.get("RTL_ALT_M"),
    takeoff_mode=FlightMode.GUIDED,
    after_takeoff_mode=FlightMode.GUIDED,
    mission_end_mode=FlightMode.AUTO,
    merges_item_reached=True,
    announces_items=True,
    sends_unasked=True,
    pauses_only_on_the_way=True,
    forgets_speed_in_auto=True,
    pauses_on_the_track=True,
    slows_a_speed_up_only_by_its_plateau=True,
)

PX4 = Flavour(
    name="px4",
    autopilot=mavlink.MAV_AUTOPILOT_PX4,
    modes=PX4_MODES,
    boot_mode=FlightMode.POSCTL,
    home_is_item_zero=False,
    item_request_id=mavlink.MAVLINK_MSG_ID_MISSION_REQUEST_INT,
    rerequest_s=0.25,
    upload_timeout_s=5.0,
    item_refusal=lambda item: None,
    store_item=lambda item: item,
    streams_by_default=True,
    repeats_item_reached=True,
    needs_mission_start=False,
    arm_in_auto=True,
    arm_rejected_result=mavlink.MAV_RESULT_TEMPORARILY_REJECTED,
    sysid_param="MAV_SYS_ID",
    param_defaults=PX4_DEFAULTS,
    params_bytewise=True,
    limits=px4_limits,
    rtl_alt_m=lambda params: params.get("RTL_RETURN_ALT"),
    takeoff_mode=FlightMode.TAKEOFF,
    after_takeoff_mode=FlightMode.LOITER,
    mission_end_mode=FlightMode.LOITER,
    merges_item_reached=False,
    announces_items=False,
    sends_unasked=False,
    pauses_only_on_the_way=False,
    forgets_speed_in_auto=False,
    pauses_on_the_track=False,
    slows_a_speed_up_only_by_its_plateau=False,
)

FLAVOURS = {flavour.name: flavour for flavour in (ARDUPILOT, PX4)}
