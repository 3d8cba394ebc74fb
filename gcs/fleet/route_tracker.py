"""Where each vehicle is on its plan: the item it flies to, its distance, ETA and lag.

The plan's clock runs on the vehicle's own clock (time_boot_ms, which a simulator
speeds up with everything else) from the moment its mission was started. A vehicle's
plan time is the moment of the ideal flight (`mission_build.fly_ideally`) that matches
its position: along the leg it is flying, or inside the hold it is doing. Lag is the
plan clock minus that plan time: positive when the vehicle is behind its schedule.

A visit is passed when the vehicle says so in any of the ways real autopilots do:
MISSION_ITEM_REACHED for it or for a later item (ArduCopter merges the reports of items
finished in one loop, so the take-off and a waypoint before a DO item may never be
reported), MISSION_CURRENT beyond it, or being disarmed on the ground at the landing
point, which passes every visit (ArduCopter reports no NAV_LAND and resets its mission
to item 1 when it disarms; and a link that was down while the vehicle flew on missed
the reports anyway).
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs.mavlink.vehicle_state import VehicleState
from gcs.mission.build import Visit
from gcs.mission.geodesy import distance_m

ARRIVED_M = 2.5  # within this of a hold waypoint and nearly still: the hold has begun
STILL_M_S = 0.5
LANDED_NEAR_M = 5.0  # disarmed on the ground within this of the landing point: landed there


@dataclass(frozen=True)
class VehicleProgress:
    uav_id: str
    sysid: int
    mode: str
    armed: bool
    airborne: bool
    link_up: bool
    lat: float | None
    lon: float | None
    alt_m: float | None
    current_seq: int
    reached: int  # NAV items of the plan passed so far
    items: int  # NAV items of the plan after take-off
    distance_to_next_m: float | None
    eta_s: float | None  # at the current ground speed
    scheduled_next_s: float | None  # plan time the next item is due
    clock_s: float  # the plan's clock for this vehicle
    plan_time_s: float  # where the vehicle is on its plan
    lag_s: float  # clock_s - plan_time_s: seconds behind schedule
    paused: bool  # stopped, by the operator or to let another vehicle pass
    held: bool  # held by the operator: only the operator's continue moves it
    waits_for: str | None  # the vehicle it waits for (stopped, or edging closer)
    along_m: float  # metres along its path
    withdrawn: bool  # sent home or down by the operator: out of the plan
    holding: bool  # waiting at a waypoint as the plan says
    landing: bool  # over its last place, coming down: out of the plan's picture
    finished: bool


class RouteTracker:
    """Follows one vehicle along its ideal flight."""

    def __init__(self, uav_id: str, visits: list[Visit], origin: tuple[float, float]) -> None:
        self.uav_id = uav_id
        self.visits = visits
        self.origin = origin  # where plan time 0 is: over the take-off point
        self.start_boot_ms: int | None = None
        self._passed_at: dict[int, float] = {}  # visit index -> plan clock when passed
        self._arrived_at: dict[int, float] = {}  # hold visit index -> plan clock on arrival

    def start(self, time_boot_ms: int) -> None:
        self.start_boot_ms = time_boot_ms

    def find(self, state: VehicleState) -> None:
        """Follow a vehicle found on its way (after a restart or a takeover): the items
        before its current one are passed, at their planned times, and its plan clock is
        set to where its position is on the plan (its lag so far is not known: 0)."""
        self.start_boot_ms = state.time_boot_ms
        self.newly_passed(state)
        self._passed_at = {k: self.visits[k].arrive for k in self._passed_at}
        self.start_boot_ms -= round(1000 * self.plan_time(state))

    def places(self, state: VehicleState) -> tuple[Visit | None, Visit | None]:
        """The last item passed and the one flown to, by the vehicle's current item."""
        passed = [v for v in self.visits if v.seq < state.mission_seq]
        ahead = [v for v in self.visits if v.seq >= state.mission_seq]
        return (passed[-1] if passed else None), (ahead[0] if ahead else None)

    def clock(self, state: VehicleState) -> float:
        if self.start_boot_ms is None:
            return 0.0
        return max(0.0, (state.time_boot_ms - self.start_boot_ms) / 1000.0)

    def newly_passed(self, state: VehicleState) -> list[int]:
        """Indices of visits passed since the last call (for ItemReached events)."""
        clock = self.clock(state)
        last_reported = max(state.reached, default=-1)
        if self.visits and self.visits[-1].lands and self._landed_at(self.visits[-1], state):
            last_reported = self.visits[-1].seq  # down at the end: everything before is done
        fresh = []
        for k, visit in enumerate(self.visits):
            if k in self._passed_at:
                continue
            if visit.seq <= last_reported or visit.seq < state.mission_seq:
                self._passed_at[k] = clock
                fresh.append(k)
            else:
                break
        return fresh

    def _landed_at(self, visit: Visit, state: VehicleState) -> bool:
        if not state.down or state.position is None or self.start_boot_ms is None:
            return False
        away = distance_m(state.position.lat, state.position.lon, visit.lat, visit.lon)
        return away <= LANDED_NEAR_M

    def passed_at(self, index: int) -> float:
        return self._passed_at[index]

    def finished(self, state: VehicleState) -> bool:
        """Every visit passed, and disarmed on the ground (after a landing or an RTL)."""
        return len(self._passed_at) == len(self.visits) and state.down

    def landing(self, state: VehicleState) -> bool:
        """Over the last place with only the landing left, or landed (the plan ends there)."""
        done = len(self._passed_at)
        if done == len(self.visits):
            return True
        if done != len(self.visits) - 1 or state.position is None:
            return False
        last = self.visits[-1]
        near = distance_m(state.position.lat, state.position.lon, last.lat, last.lon)
        return near <= ARRIVED_M

    def holding(self, state: VehicleState) -> bool:
        done = len(self._passed_at)
        if done == len(self.visits):
            return False
        last = self.visits[done - 1] if done else None
        return (
            last is not None and last.seq == state.mission_seq and last.leave > last.arrive
        ) or self._has_arrived(done, state)

    def plan_time(self, state: VehicleState) -> float:
        done = len(self._passed_at)
        if not self.visits or self.start_boot_ms is None:
            return 0.0
        if done == len(self.visits):
            return self.visits[-1].leave
        last = self.visits[done - 1] if done else None
        if last is not None and last.seq == state.mission_seq and last.leave > last.arrive:
            # ArduCopter reports a hold waypoint reached on arrival and stays on it
            return self._holding(last, self._passed_at[done - 1], state)
        if self._has_arrived(done, state):
            return self._holding(self.visits[done], self._arrived_at[done], state)
        return self._along_leg(state, done)

    def _has_arrived(self, index: int, state: VehicleState) -> bool:
        """At a hold waypoint not yet reported reached (a vehicle reporting it on leaving)."""
        visit = self.visits[index]
        if index in self._arrived_at:
            return True
        if visit.leave <= visit.arrive or state.position is None:
            return False
        near = distance_m(state.position.lat, state.position.lon, visit.lat, visit.lon)
        if near <= ARRIVED_M and state.groundspeed_m_s <= STILL_M_S:
            self._arrived_at[index] = self.clock(state)
            return True
        return False

    def _holding(self, visit: Visit, since: float, state: VehicleState) -> float:
        held = max(0.0, self.clock(state) - since)
        return min(visit.leave, visit.arrive + held)

    def _along_leg(self, state: VehicleState, index: int) -> float:
        target = self.visits[index]
        if index:
            prev = self.visits[index - 1]
            start, leave = (prev.lat, prev.lon), prev.leave
        else:
            start, leave = self.origin, 0.0
        if state.position is None:
            return leave
        leg = distance_m(*start, target.lat, target.lon)
        left = distance_m(state.position.lat, state.position.lon, target.lat, target.lon)
        fraction = 1.0 if leg <= 0 else min(1.0, max(0.0, 1.0 - left / leg))
        return leave + fraction * (target.arrive - leave)

    def progress(
        self,
        state: VehicleState,
        *,
        paused: bool,
        held: bool = False,
        withdrawn: bool = False,
        waits_for: str | None = None,
        along_m: float = 0.0,
    ) -> VehicleProgress:
        done = len(self._passed_at)
        nxt = self.visits[done] if done < len(self.visits) else None
        pos = state.position
        distance = distance_m(pos.lat, pos.lon, nxt.lat, nxt.lon) if pos and nxt else None
        speed = state.groundspeed_m_s
        clock, plan_time = self.clock(state), self.plan_time(state)
        return VehicleProgress(
            uav_id=self.uav_id,
            sysid=state.sysid,
            mode=state.mode,
            armed=state.armed,
            airborne=state.airborne,
            link_up=state.link_up,
            lat=pos.lat if pos else None,
            lon=pos.lon if pos else None,
            alt_m=pos.relative_alt_m if pos else None,
            current_seq=state.mission_seq,
            reached=done,
            items=len(self.visits),
            distance_to_next_m=distance,
            eta_s=distance / speed if distance is not None and speed > 0.2 else None,
            scheduled_next_s=nxt.arrive if nxt else None,
            clock_s=clock,
            plan_time_s=plan_time,
            lag_s=clock - plan_time if self.start_boot_ms is not None else 0.0,
            paused=paused,
            held=held,
            waits_for=waits_for,
            along_m=along_m,
            withdrawn=withdrawn,
            holding=self.holding(state),
            landing=self.landing(state),
            finished=self.finished(state),
        )
