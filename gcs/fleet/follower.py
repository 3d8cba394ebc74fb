"""Following a flight to its end: items reached, landings, link losses, the passing order.

The flight ends when every vehicle has flown its mission and is disarmed on the ground
(or, if the operator sent it home or down, is on the ground), when it is aborted, or at
its time bound. A vehicle whose link drops is waited for: an autopilot flies its
mission without us, and a short outage must not end a flight while vehicles are up
(those that wait for it keep waiting where it was last seen).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Awaitable
from dataclasses import dataclass
from typing import Any, TypeVar

from gcs.fleet.crew import Crew, Fallback
from gcs.fleet.events import (
    AddressClaimed,
    BrakedOnLinkLoss,
    FlightEnded,
    FlightOutcome,
    ItemReached,
    LeadTaken,
    Progress,
    VehicleFailed,
    VehicleFinished,
    VehicleLinkRegained,
    Waiting,
    WaitOver,
)
from gcs.fleet.interventions import abort, fall_back
from gcs.fleet.member import Member
from gcs.mission.geodesy import distance_m
from gcs.mission.motion import Gate

T = TypeVar("T")

UNHEARD_S = 1.0
"""Nothing heard from a vehicle for this long (about ten messages of its streams, a run
that 20 % packet loss makes once in ten million), and it counts as flying on unheard."""


@dataclass(frozen=True)
class FlightReport:
    completed: bool  # every vehicle flew its mission to the end and landed
    outcome: FlightOutcome
    min_separation_m: float | None
    closest_pair: tuple[str, str] | None
    finished: tuple[str, ...]
    failed: dict[str, str]
    withdrawn: dict[str, str]


class Follower:
    def __init__(self, crew: Crew) -> None:
        self.crew = crew
        self.finished: set[str] = set()
        self._link_down: set[str] = set()
        self._claimants: dict[str, str] = {}  # uav -> the latest other address claiming it
        self._sent_back: dict[str, asyncio.Task[Any]] = {}  # braked, sent home or down again
        self._modes: dict[str, str] = {}  # uav -> the mode it was last looked at in

    async def follow(self, timeout_s: float | None = None) -> FlightReport:
        """Watch the flight to its end; `timeout_s` is in the vehicles' seconds (default:
        three times the longest schedule plus two minutes) and bounds the wall time too."""
        crew = self.crew
        limit = timeout_s or default_timeout(crew)
        loop = asyncio.get_running_loop()
        wall_deadline = loop.time() + limit
        next_progress = 0.0
        timed_out = False
        while crew.aborted is None and not self._all_down():
            self._note_items_and_ends()
            self._note_links()
            self._note_brakes()
            if crew.settings.keep_order:
                self._keep_order()
            if loop.time() >= next_progress:
                crew.bus.publish(Progress(crew.progress(), self.min_separation_m))
                next_progress = loop.time() + crew.settings.progress_every_s
            if crew.clock() > limit or loop.time() > wall_deadline:
                timed_out = True
                await abort(crew, crew.settings.fallback.value, f"flight exceeded {limit:.0f} s")
                break
            await asyncio.sleep(crew.settings.tick_s)
        return self.report(timed_out)

    async def starting(self, start: Awaitable[T]) -> T:
        """The fleet's `start`, the passing order kept meanwhile for every vehicle whose
        start was answered: the start waits for the slowest answer (up to 3.2 s over a
        lossy link), and the others fly their missions meanwhile (fuzzed flight 19782 at
        10 m/s: two of them, unfollowed for 3 s while a silent one was asked again and
        again, then held as they sped up, ran on into each other's way, 5.65 m apart
        with 2R 6 m). A start cancelled (the operator's hold) stops asking at once."""
        keeping = asyncio.ensure_future(self._keep_order_every_tick())
        try:
            return await start
        finally:
            keeping.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await keeping  # (raises what went wrong in it)

    async def _keep_order_every_tick(self) -> None:
        crew = self.crew
        while True:
            await asyncio.sleep(crew.settings.tick_s)
            if crew.aborted is None and crew.settings.keep_order:
                self._keep_order()

    @property
    def min_separation_m(self) -> float | None:
        closest = self.crew.separation.closest if self.crew.separation else None
        return closest.distance_m if closest else None

    def report(self, timed_out: bool = False) -> FlightReport:
        crew = self.crew
        completed = crew.aborted is None and len(self.finished) == len(crew.members)
        if completed:
            outcome = FlightOutcome.LANDED
        elif timed_out:
            outcome = FlightOutcome.TIMEOUT
        elif crew.aborted is not None:
            outcome = FlightOutcome.ABORTED
        else:
            outcome = FlightOutcome.ENDED
        closest = crew.separation.closest if crew.separation else None
        pair = closest.pair if closest else None
        crew.bus.publish(FlightEnded(completed, self.min_separation_m, pair, outcome))
        return FlightReport(
            completed,
            outcome,
            self.min_separation_m,
            pair,
            tuple(sorted(self.finished)),
            dict(crew.failed),
            dict(crew.withdrawn),
        )

    def _all_down(self) -> bool:
        return all(
            uav in self.finished or (uav in self.crew.withdrawn and m.link.state.down)
            for uav, m in self.crew.members.items()
        )

    def _note_items_and_ends(self) -> None:
        for m in self.crew.members.values():
            state = m.link.state
            for k in m.tracker.newly_passed(state):
                self.crew.commander.item_reached(m.uav_id)
                visit = m.tracker.visits[k]
                self.crew.bus.publish(
                    ItemReached(m.uav_id, visit.seq, m.tracker.passed_at(k), visit.arrive)
                )
            if m.uav_id not in self.finished and m.tracker.finished(state):
                self.finished.add(m.uav_id)
                self.crew.bus.publish(VehicleFinished(m.uav_id, _distance_to_goal(m)))

    def _note_links(self) -> None:
        for m in self.crew.members.values():
            up = m.link.state.link_up
            if not up and m.uav_id not in self._link_down:
                self._link_down.add(m.uav_id)
                self.crew.failed[m.uav_id] = "link lost in flight"
                self.crew.bus.publish(VehicleFailed(m.uav_id, "flight", "link lost"))
            elif up and m.uav_id in self._link_down:
                self._link_down.discard(m.uav_id)
                self.crew.failed.pop(m.uav_id, None)
                self.crew.bus.publish(VehicleLinkRegained(m.uav_id))
            claim = m.link.connection.contested.get(m.link.sysid)
            if claim is not None and self._claimants.get(m.uav_id) != claim.address:
                self._claimants[m.uav_id] = claim.address
                self.crew.bus.publish(AddressClaimed(m.uav_id, claim.address))

    def _note_brakes(self) -> None:
        """Vehicles their own GCS failsafe braked while nobody heard them (`link_loss`),
        found so once heard: one in the plan is stopped out of its mission, and the
        passing order sends it on (AUTO again) when its way is clear; one the operator
        sent home (or down, though ArduCopter lets a landing go on) is sent so again.
        A switch into BRAKE counts, not BRAKE itself: the HEARTBEATs after our own AUTO
        still say BRAKE for a moment. Not while we change the vehicle's gate (our own
        brake), nor for one the operator holds (his)."""
        crew = self.crew
        for uav, m in crew.members.items():
            state = m.link.state
            if crew.commander.changing(uav) or self._sending_back(uav) or not state.link_up:
                continue  # looked at again once that is over
            before, self._modes[uav] = self._modes.get(uav), state.mode
            if (
                state.mode != "BRAKE"
                or before == "BRAKE"
                or not crew.started
                or uav in self.finished
                or uav in crew.held
                or m.actions.out_of_mission
            ):
                continue
            crew.bus.publish(BrakedOnLinkLoss(uav))
            withdrawn = crew.withdrawn.get(uav)
            if withdrawn is not None:
                again = fall_back(crew, [uav], Fallback(withdrawn))
                self._sent_back[uav] = asyncio.ensure_future(again)
                continue
            crew.commander.held_out_of_mission(uav)
            crew.gatekeeper.stop(uav)

    def _sending_back(self, uav: str) -> bool:
        task = self._sent_back.get(uav)
        return task is not None and not task.done()

    def _keep_order(self) -> None:
        """Stop, release or edge up the vehicles the passing order says (`gatekeeper`)."""
        crew = self.crew
        heard = set()
        for uav, m in crew.members.items():
            if m.along.update(m.link.state):
                m.actions.mission_speed_m_s = crew.flight.cruise_at(uav, m.along.s)
                heard.add(uav)
        gated = [uav for uav, m in crew.members.items() if self._gated(uav, m)]
        along = {uav: m.along for uav, m in crew.members.items()}
        now = asyncio.get_running_loop().time()
        changes = crew.gatekeeper.decide(along, gated, unheard=self._flying_on_unheard(), now=now)
        for uav, past, turned, unheard in crew.gatekeeper.leads_taken:
            crew.bus.publish(LeadTaken(uav, past, tuple(turned), unheard))
        crew.gatekeeper.leads_taken.clear()
        for uav in heard.intersection(gated):
            crew.commander.heard(uav)
        for change in changes:
            crew.commander.want(change.uav_id, change.gate, change.speed_m_s, change.speed_first)
            if change.gate == Gate.GO:
                crew.bus.publish(WaitOver(change.uav_id))
            else:
                leader, how = change.waits_for or "", change.gate.value
                crew.bus.publish(
                    Waiting(change.uav_id, leader, how, change.gap_m, change.speed_m_s)
                )

    def _flying_on_unheard(self) -> list[str]:
        """Vehicles flying their plans that nobody has heard for UNHEARD_S and that were
        not stopped (a pause the vehicle acknowledged holds without the ground station;
        anything else flies on, its mission going on without it). Not the link's 4 s:
        by then a vehicle that others meet may be too close to stop for it (fuzzed
        flight 1014 with uav4's link silent 5 s: uav3 could no longer wait). Not one
        whose start is not answered yet: it may still hover at its start, and the start
        ends only once it answers or has failed (taken to fly on, a vehicle silent during
        the start led every encounter ahead, its followers were turned round where they
        stood, and the flight stuck after passing 5.30 m apart: fuzzed flight 19888)."""
        crew, now = self.crew, asyncio.get_running_loop().time()
        return [
            uav
            for uav, m in crew.members.items()
            if crew.started
            and uav not in crew.starting
            and now - m.link.state.last_heard > UNHEARD_S
            and uav not in self.finished
            and uav not in crew.withdrawn
            and uav not in crew.held
            and crew.commander.applied[uav] != Gate.STOP
        ]

    def _gated(self, uav: str, member: Member) -> bool:
        """Whether the passing order commands this vehicle now: flying its plan, heard,
        not held by the operator (whose hold nobody else lifts), not stopped for a new
        mission (a live replan, until it flies it), and not coming down at
        its goal (ArduCopter will not pause a landing), unless it was stopped short of it
        (it must be let go when its way is clear)."""
        crew = self.crew
        state = member.link.state
        if uav in crew.starting:
            return False  # not yet in its mission for sure (`starting`)
        if uav in self.finished or uav in crew.withdrawn or not crew.started:
            if uav in self.finished or (uav in crew.withdrawn and state.down):
                crew.gatekeeper.out_of_the_way(uav)
            return False
        stopped = crew.gatekeeper.gates[uav] != Gate.GO
        landing = member.tracker.landing(state) and not stopped
        replanning = uav in crew.replanning
        return state.link_up and uav not in crew.held and not replanning and not landing


def default_timeout(crew: Crew) -> float:
    longest = max(
        (m.tracker.visits[-1].leave for m in crew.members.values() if m.tracker.visits),
        default=0.0,
    )
    return 3 * longest + 120.0


def _distance_to_goal(member: Member) -> float:
    pos, goal = member.link.state.position, member.tracker.visits[-1]
    return distance_m(pos.lat, pos.lon, goal.lat, goal.lon) if pos else float("nan")
