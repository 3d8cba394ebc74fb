"""Flies the stored mission in AUTO: one manoeuvre per navigation item, DO items at once.

Reports progress through `MissionEvents`: every item started and every item completed
(DO items too); the vehicle decides, per autopilot, which of those it tells the ground
station and how (ArduCopter merges and skips some, see vehicle.py).
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from typing import Protocol

import numpy as np

from .codec import mavlink
from .kinematics import Body, NavLimits
from .manoeuvres import Climb, FlyTo, Hold, Land, Manoeuvre, Sequence, Stop, land_at, return_home
from .mission_item import AMSL_FRAMES, GLOBAL_FRAMES, NAV_COMMANDS, MissionItem
from .mission_store import MissionStore

SETTLED_M_S = 0.05
"""At rest enough to start a new item after a jump."""
NAV_WAYPOINT = mavlink.MAV_CMD_NAV_WAYPOINT
NAV_LOITER_UNLIM = mavlink.MAV_CMD_NAV_LOITER_UNLIM
NAV_LOITER_TIME = mavlink.MAV_CMD_NAV_LOITER_TIME
NAV_RTL = mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH
NAV_LAND = mavlink.MAV_CMD_NAV_LAND
NAV_TAKEOFF = mavlink.MAV_CMD_NAV_TAKEOFF
DO_CHANGE_SPEED = mavlink.MAV_CMD_DO_CHANGE_SPEED
PASS_THROUGH_TARGETS = frozenset({NAV_WAYPOINT, NAV_LOITER_UNLIM, NAV_LOITER_TIME})


class MissionState(enum.IntEnum):
    """MISSION_CURRENT.mission_state (MISSION_STATE enum)."""

    NO_MISSION = 1
    NOT_STARTED = 2
    ACTIVE = 3
    PAUSED = 4
    COMPLETE = 5


class MissionEvents(Protocol):
    def item_started(self, item: MissionItem) -> None: ...

    def item_reached(self, item: MissionItem) -> None: ...

    def current_changed(self) -> None: ...

    def speed_changed(self, speed: float) -> None: ...


class ItemPlacer:
    """Turns an item's coordinates into the fleet's local metres and home-relative altitude."""

    def __init__(
        self,
        to_local: Callable[[float, float], tuple[float, float]],
        home_alt_amsl: Callable[[], float],
    ) -> None:
        self._to_local = to_local
        self._home_alt = home_alt_amsl

    def position(self, item: MissionItem, body: Body) -> tuple[float, float]:
        if item.has_position:
            return self._to_local(item.lat, item.lon)
        east, north, _ = body.position
        return east, north

    def altitude(self, item: MissionItem, body: Body) -> float:
        if item.frame not in GLOBAL_FRAMES:
            return body.alt
        if item.frame in AMSL_FRAMES:
            return max(0.0, item.z - self._home_alt())
        return max(0.0, item.z)


class MissionRunner:
    """Executes items from `store.current` on; the flight controller calls `update` in AUTO."""

    def __init__(
        self,
        store: MissionStore,
        body: Body,
        placer: ItemPlacer,
        limits: Callable[[], NavLimits],
        home_en: Callable[[], tuple[float, float]],
        rtl_alt: Callable[[], float],
        events: MissionEvents,
        takeoff_alt_if_missing: float | None = None,
    ) -> None:
        self.store = store
        self._body = body
        self._placer = placer
        self._limits = limits
        self._home_en = home_en
        self._rtl_alt = rtl_alt
        self._events = events
        self._implicit_takeoff = takeoff_alt_if_missing
        self._running = False
        self._paused = False
        self._complete = False
        self._manoeuvre: Manoeuvre | None = None
        self._settling = False

    @property
    def state(self) -> MissionState:
        if self.store.total == 0:
            return MissionState.NO_MISSION
        if self._complete:
            return MissionState.COMPLETE
        if self._paused:
            return MissionState.PAUSED
        return MissionState.ACTIVE if self._running else MissionState.NOT_STARTED

    @property
    def running(self) -> bool:
        return self._running

    @property
    def phase(self) -> int | None:
        return None if self._manoeuvre is None else self._manoeuvre.phase

    def starts_with_takeoff(self) -> bool:
        items = self.store.items()
        first = self.store.first_item
        return len(items) > first and items[first].command == NAV_TAKEOFF

    def start(self, now: float) -> None:
        """Run from the current item (a completed mission starts over)."""
        if self._complete:
            self.store.set_current(self.store.first_item)
            self._complete = False
        self._running, self._paused = True, False
        self.store.started = True
        self._begin_item(now)

    def rewind(self, active: bool) -> None:
        """ArduCopter on disarming: the mission goes back to its first item; still in AUTO, it
        is loaded again at once (MISSION_CURRENT seq 1, ACTIVE) and waits for the motors."""
        self._complete, self._paused, self._manoeuvre = False, False, None
        self.store.current = self.store.first_item
        self._running = active and self.store.total > 0
        if self._running:
            self.store.started = True
            self._events.item_started(self.store.items()[self.store.current])
        self._events.current_changed()

    def stop(self) -> None:
        """Leave AUTO: remember the current item, drop its manoeuvre."""
        self._running, self._paused, self._manoeuvre = False, False, None

    def reset(self) -> None:
        """The mission changed underneath: start over when next started."""
        self._complete = False
        self._manoeuvre = None

    def on_the_way_to_a_place(self) -> bool:
        """Flying to a place not reached yet (a waypoint, a loiter's place, the place of a
        landing before it descends), or paused on the way: ArduCopter's WP submode, the
        only part of a mission it pauses (not a take-off, a descent, or a stop at a
        reached place)."""
        if self._paused:
            return True
        manoeuvre = self._manoeuvre
        if isinstance(manoeuvre, Sequence):
            manoeuvre = manoeuvre.current
        return (
            self._running
            and not self._complete
            and isinstance(manoeuvre, FlyTo)
            and not manoeuvre.arrived
        )

    def pause(self, now: float, on_the_track: bool) -> None:
        """Stop and hover: ArduCopter `on_the_track` (AC_WPNav runs the track's clock down,
        the item goes on: a waypoint passed meanwhile is reached and the next one flown
        to, still paused, as `ModeAuto::run` updates the mission throughout; the mock
        once kept the item, and an approach's MISSION_SET_CURRENT sent the vehicle 16 m
        back to it: fuzzed flight 7548), PX4 by slowing along the velocity."""
        self._paused = True
        if on_the_track:
            self._body.pause_track()
            return
        self._manoeuvre = Stop()
        self._manoeuvre.start(self._body, now)

    def resume(self, now: float) -> None:
        """Go on from a pause (nothing to do if not paused): on the track's clock running
        up again if it was paused on it, else the same leg afresh, its speed picked up at
        the stopping jerk."""
        if not self._paused:
            return
        self._paused = False
        if not isinstance(self._manoeuvre, Stop):
            self._body.resume_track()
            return
        self._body.pick_up()
        self._begin_item(now)

    def jump(self, now: float) -> None:
        """The current item was changed in flight (MISSION_SET_CURRENT): ArduCopter gives
        up the leg it flies (its target jumps to its stopping point) and starts the new
        item from rest there (AC_WPNav::set_wp_destination after wp_and_spline_init). A
        pause is given up with it: SITL 4.8, paused, flew 13.2 m in the next 10 s (up to
        4.67 m/s) towards the item it was sent to."""
        if self._running and self._body.alt > 0:
            self._paused = False
            self._manoeuvre = Stop()
            self._manoeuvre.start(self._body, now)
            self._settling = True

    def update(self, now: float) -> None:
        if not self._running or self._complete:
            return
        if self._settling:  # after a jump: the new item begins once at rest
            if np.hypot(*self._body.velocity[:2]) > SETTLED_M_S:
                return
            self._settling = False
            self._manoeuvre = None
        if self._manoeuvre is None:
            self._begin_item(now)
            return
        if self._paused and isinstance(self._manoeuvre, Stop):
            return  # stopped out of its track (PX4): nothing reached meanwhile
        if not self._manoeuvre.update(self._body, now):
            return
        self._finish_item(now)

    def _begin_item(self, now: float) -> None:
        """Start the current item; DO items and satisfied items complete immediately."""
        items = self.store.items()
        while self.store.current < len(items):
            item = items[self.store.current]
            self._events.item_started(item)
            manoeuvre = self._manoeuvre_for(item, items)
            if manoeuvre is not None:
                self._manoeuvre = manoeuvre
                manoeuvre.start(self._body, now)
                self._events.current_changed()
                return
            self._complete_item(item)
            if not self._advance(items):
                return

    def _finish_item(self, now: float) -> None:
        items = self.store.items()
        self._complete_item(items[self.store.current])
        self._manoeuvre = None
        if self._advance(items):
            self._begin_item(now)

    def _complete_item(self, item: MissionItem) -> None:
        self._events.item_reached(item)

    def _advance(self, items: list[MissionItem]) -> bool:
        if self.store.current + 1 >= len(items):
            self._complete = True
            self._manoeuvre = Hold() if self._body.alt > 0 else None
            if self._manoeuvre is not None:
                self._manoeuvre.start(self._body, 0.0)
            self._events.current_changed()
            return False
        self.store.current += 1
        return True

    def _manoeuvre_for(self, item: MissionItem, items: list[MissionItem]) -> Manoeuvre | None:
        body, limits = self._body, self._limits()
        command = item.command
        if command == DO_CHANGE_SPEED:
            if item.param2 > 0:
                self._events.speed_changed(item.param2)
            return None
        if command == NAV_TAKEOFF:
            return self._takeoff(self._placer.altitude(item, body))
        east, north = self._placer.position(item, body)
        alt = self._placer.altitude(item, body)
        climb_first = self._implicit_climb(alt)
        if command == NAV_LAND:
            landing = land_at(east, north, body, limits) if item.has_position else Land(limits)
            return landing
        if command == NAV_RTL:
            return return_home(body, self._home_en(), self._rtl_alt(), limits)
        own_radius = command == NAV_WAYPOINT and item.param2 > 0
        radius = item.param2 if own_radius else limits.accept_radius
        hold_s = item.param1 if command in (NAV_WAYPOINT, NAV_LOITER_TIME) else 0.0
        then = self._next_corner(item, items) if hold_s <= 0 else None
        fly: Manoeuvre = FlyTo(east, north, alt, radius, then, hold_s)
        if command == NAV_LOITER_UNLIM:
            fly = Sequence(fly, Hold())
        return fly if climb_first is None else Sequence(climb_first, fly)

    def _next_corner(
        self, item: MissionItem, items: list[MissionItem]
    ) -> tuple[float, float] | None:
        """Where the leg after this waypoint goes, if the vehicle flies on into it without
        stopping (ArduCopter's fast waypoint: the next navigation item is a place to fly to)."""
        following = _next_nav(items, item.seq)
        if following is None or following.command not in PASS_THROUGH_TARGETS:
            return None
        if not following.has_position or item.command != NAV_WAYPOINT:
            return None
        return self._placer.position(following, self._body)

    def _takeoff(self, alt: float) -> Manoeuvre | None:
        if self._body.alt >= alt - 0.5:
            return None  # already there: a take-off item completes at once
        return Climb(alt)

    def _implicit_climb(self, alt: float) -> Manoeuvre | None:
        """PX4 takes off by itself when a mission starts on the ground."""
        if self._implicit_takeoff is None or self._body.alt > 0.5:
            return None
        return Climb(max(self._implicit_takeoff, alt))


def _next_nav(items: list[MissionItem], seq: int) -> MissionItem | None:
    return next((item for item in items[seq + 1 :] if item.command in NAV_COMMANDS), None)
