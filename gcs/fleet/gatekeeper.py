"""Keeping the plan's passing order in flight: who waits for whom, stopped in time.

Every look: where each vehicle is along its path (`path_progress`), how far the passing
order lets it go while the others are where they are (`PassingOrder.limit`), and what
the stopping rule makes of the gap at its speed (`StoppingRule.decide`): fly on, stop
(DO_PAUSE_CONTINUE, or a brake where ArduCopter will not pause), or approach the limit
slowly (DO_CHANGE_SPEED, faster as the limit moves on), ready to stop short of it, to be
there sooner once the way is free, or because someone else waits for it to pass a point
before it.
A vehicle waits only for those its path meets, never for a clock: a late take-off, an
operator's hold or a lost link delays the vehicles that depend on that one, and nobody
else. A vehicle down for good (landed at its goal, or sent down) is in nobody's way.

The commands to one vehicle go out one at a time, in their own task, so a vehicle that
answers slowly (a lossy link) never holds up the decisions about the others; if the
decision changes meanwhile, the latest one is what the vehicle is brought to.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from gcs.fleet.lead_taking import CanWait, LeadTaken, lead_ahead, take_the_lead
from gcs.fleet.path_progress import PathProgress
from gcs.mavlink.actions import FlightActions
from gcs.mavlink.errors import GcsError, LinkError
from gcs.mission.motion import CopterLimits, Gate, StoppingRule
from gcs.mission.passing_order import Limit, PassingOrder

STRANDED_M = 0.5
"""A vehicle stopped this far past its limit or more is inside the encounter it was to
wait short of (a pause lost again and again): it leads it instead."""
STOPPED_M_S = 0.2
FRESH_S = 0.25
"""A position this old is as fresh as the streams make them (GLOBAL_POSITION_INT at
5 Hz, 4 Hz by the older stream request): the stopping rule's reaction time allows for
it, and only what a position is older than this is reckoned on (`Gatekeeper._reckoned`)."""


@dataclass(frozen=True)
class GateChange:
    uav_id: str
    gate: Gate
    waits_for: str | None
    gap_m: float
    speed_m_s: float | None = None  # of an approach (CREEP)
    speed_first: bool = False  # an approach from a stop given its speed before it sets off


class Gatekeeper:
    """The gate states of a fleet, decided from where everyone is."""

    def __init__(
        self,
        order: PassingOrder,
        limits: Mapping[str, CopterLimits],
        rule: StoppingRule | None = None,
    ) -> None:
        self.order = order
        self.limits = dict(limits)
        self.rule = rule or StoppingRule()
        self.silent_s: dict[str, float] = {}
        """How long each vehicle that hears nothing from us flies on before its own
        failsafe stops it, on its own clock (`link_loss`); not known: for ever."""
        self.gates = dict.fromkeys(self.limits, Gate.GO)
        self.waits_for: dict[str, str | None] = dict.fromkeys(self.limits)
        self.approach: dict[str, float | None] = {}  # of the vehicles approaching (CREEP)
        self.gone: set[str] = set()
        self._coming: PassingOrder | None = None  # a live replan's, while it is uploaded
        self._rest_from: dict[str, float] = {}  # where its rests begin, along today's paths
        self.leads_taken: list[tuple[str, float, list[tuple[str, str]], bool]] = []
        """Vehicles that took the lead (`lead_taking`), how far past their limits they
        stood, the pairs turned round, and whether because nobody heard them; for the
        flight to report, then clear."""
        self._unheard: set[str] = set()  # given the lead for the outage they are in

    def decide(
        self,
        progress: Mapping[str, PathProgress],
        gated: Iterable[str],
        starting: bool = False,
        unheard: Iterable[str] = (),
        now: float | None = None,
    ) -> list[GateChange]:
        """New gates of the vehicles in `gated` (the others keep theirs); the changes.
        `starting`: they are about to be sent on from a hover, and a mission started from
        rest speeds up at once, so each is judged as speeding up at its acceleration
        (judged at rest, one with a limit 1.5 m ahead was let go and went on 5.6 m after
        its pause: fuzzed flight 3585). `unheard`: vehicles nobody has heard lately
        while their missions fly them on (not stopped): each leads what it can, once an
        outage. `now`: the loop time, to judge each vehicle where it may be by then
        (`_reckoned`)."""
        at = {uav: np.inf if uav in self.gone else p.s for uav, p in progress.items()}
        self._let_the_unheard_lead(progress, at, set(unheard))
        self._let_the_stranded_lead(progress, at)
        chosen = [uav for uav in gated if uav not in self.gone]
        limits = {uav: self._limit(uav, at) for uav in chosen}
        waited_on = {limit.leader for limit in limits.values() if limit.leader is not None}
        changes = []
        for uav in chosen:
            p, limit = progress[uav], limits[uav]
            s, speed = self._reckoned(uav, p, now)
            gap = limit.at_m - s
            waited, own = uav in waited_on, self.limits[uav]
            accel = own.accel_m_s2 if starting else p.accel
            gate = self.rule.decide(
                self.gates[uav], gap, speed, accel, own, waited, self.approach.get(uav)
            )
            speed_first = self._speed_first(gate, uav, gap)
            if speed_first and speed >= STOPPED_M_S:
                gate, speed_first = Gate.STOP, False  # not yet: made current, it jerks on
            waits_for = limit.leader if gate != Gate.GO else None
            faster = None
            if gate == Gate.CREEP and self.gates[uav] != Gate.CREEP:
                self.approach[uav] = self.rule.approach_speed(gap, own, waited)
            elif gate == Gate.CREEP:
                faster = self.rule.faster_approach(gap, own, waited, self.approach.get(uav))
                self.approach[uav] = faster or self.approach.get(uav)
            if gate != self.gates[uav] or waits_for != self.waits_for[uav] or faster:
                approach = self.approach.get(uav) if gate == Gate.CREEP else None
                changes.append(GateChange(uav, gate, waits_for, gap, approach, speed_first))
            self.gates[uav], self.waits_for[uav] = gate, waits_for
        return changes

    def _speed_first(self, gate: Gate, uav: str, gap_m: float) -> bool:
        """Whether an approach from a stop must have its speed before it sets off. Sent
        on, its item is made current (flown afresh from rest, at the mission's speed),
        then slowed (`FlightActions.approach`); should the link fall silent between the
        two, the vehicle flies on at its mission's speed until its own failsafe brakes
        it (fuzzed flight 20276: uav7, sent on 3.1 m short of its limit, ran 4.4 m, and
        the vehicle it waited for passed 5.87 m from it, 2R 6 m). Given its speed first,
        it sets off no faster whatever is lost; only once it stands, for ArduCopter
        starts an item made current at where a moving vehicle would stop (SITL at
        0.5 m/s: 1.7 m/s forward and 0.5 m back)."""
        if gate != Gate.CREEP or self.gates[uav] != Gate.STOP:
            return False
        silent_s = self.silent_s.get(uav, math.inf)
        return gap_m < self.limits[uav].unheard_run_m(silent_s)

    def _reckoned(self, uav: str, p: PathProgress, now: float | None) -> tuple[float, float]:
        """Where along its path a vehicle may be by `now`, and how fast: its last place
        and speed, flown on for what the position is older than FRESH_S, speeding up as
        it was (up to its cruise). Judged where it was last heard, one whose positions
        were lost for 1.2 s while it sped up from 6.9 m/s was taken for 10 m behind where
        it was; its pause came too late, and it stopped 3.8 m past the place it was to
        wait short of, 5.66 m from the vehicle it waited for (the gap swap at 10 m/s
        with 20 % packet loss both ways). Only a vehicle's own gap is reckoned: the
        vehicles others wait for count where they were last heard, which is never
        further on than they are."""
        late = 0.0 if now is None or p.heard_at is None else now - p.heard_at - FRESH_S
        if late <= 0.0:
            return p.s, p.speed
        own = self.limits[uav]
        rising = min(max(p.accel, 0.0), own.accel_m_s2)
        top = max(p.speed, own.speed_m_s)
        rise_s = min(late, (top - p.speed) / rising) if rising > 0.0 else 0.0
        speed = p.speed + rising * rise_s
        flown = (p.speed + speed) / 2 * rise_s + speed * (late - rise_s)
        return min(p.s + flown, p.path.length), speed

    def _let_the_stranded_lead(
        self, progress: Mapping[str, PathProgress], at: Mapping[str, float]
    ) -> None:
        """A vehicle stopped well inside an encounter it was to wait short of leads it
        (`lead_taking`), where the order can be turned round for it."""
        for uav, p in progress.items():
            if p.speed >= STOPPED_M_S or uav in self.gone:
                continue
            past = p.s - self.order.limit(uav, at).at_m
            if past <= STRANDED_M:
                continue
            ends = {u: q.path.length for u, q in progress.items()}
            taken = take_the_lead(self.order, uav, at, ends, self._can_wait(progress))
            self._took(uav, past, taken, unheard=False)

    def _let_the_unheard_lead(
        self, progress: Mapping[str, PathProgress], at: Mapping[str, float], unheard: set[str]
    ) -> None:
        """A vehicle nobody hears while it flies on leads every encounter it has not left
        behind, where the other can still wait for it (`lead_taking.lead_ahead`); once an
        outage (heard again, it is judged afresh at its next one)."""
        self._unheard &= unheard
        ends = {u: q.path.length for u, q in progress.items()}
        for uav in sorted(unheard - self._unheard - self.gone):
            self._unheard.add(uav)
            past = at[uav] - self.order.limit(uav, at).at_m
            taken = lead_ahead(self.order, uav, at, ends, self._can_wait(progress))
            self._took(uav, past, taken, unheard=True)

    def _took(self, uav: str, past: float, taken: LeadTaken | None, unheard: bool) -> None:
        if taken is not None:
            self.order = taken.order
            self.leads_taken.append((uav, past, taken.turned, unheard))

    def _can_wait(self, progress: Mapping[str, PathProgress]) -> CanWait:
        """Whether a vehicle can wait for another where an order has it wait: it can
        still stop short of that place, or it stands still already and the other passes
        it no closer than their radii (fuzzed flight 8403: both stopped inside their
        encounter; the one stranded 2 m past its limit went round the one standing)."""

        def can_wait(order: PassingOrder, uav: str, leader: str) -> bool:
            wait = next(w for w in order.waits[uav] if w.leader == leader)
            p, first = progress[uav], progress[leader]
            if uav in self.gone:
                return False
            if wait.limit(first.s) - p.s > self.rule.needed_m(p.speed, p.accel, self.limits[uav]):
                return True
            way = first.path.between(first.s, float(wait.after.max()))
            gap = np.hypot(*(way - np.asarray(p.path.position(p.s))).T).min()
            return p.speed < STOPPED_M_S and gap >= p.path.radius_m + first.path.radius_m

        return can_wait

    def _limit(self, uav: str, at: Mapping[str, float]) -> Limit:
        limit = self.order.limit(uav, at)
        if self._coming is None or uav not in self._rest_from:
            return limit
        on_rest = {u: at[u] - s for u, s in self._rest_from.items() if u in at}
        coming = self._coming.limit(uav, on_rest)
        coming_at = coming.at_m + self._rest_from[uav]
        return Limit(coming_at, coming.leader) if coming_at < limit.at_m else limit

    def expect(self, order: PassingOrder, rest_from: Mapping[str, float]) -> None:
        """While a live replan is uploaded, the vehicles it keeps on their paths fly on,
        and keep the order it will most likely bring too (the rests of their paths from
        `rest_from` metres along them; the others are taken as at the starts of their new
        paths): the order that came at the end of the uploads had one already 4.5 m past
        where it was to wait for another, which flew up to it (fuzzed flight 3676)."""
        self._coming, self._rest_from = order, dict(rest_from)

    def replan(self, order: PassingOrder, limits: Mapping[str, CopterLimits]) -> None:
        """A new order (a live replan); the gates stay as they are until the next look."""
        self.order, self.limits = order, dict(limits)
        self.expect_nothing()

    def expect_nothing(self) -> None:
        """No replan is coming (it was made, or it failed)."""
        self._coming, self._rest_from = None, {}

    def stop(self, uav_id: str) -> None:
        """`uav_id` stops where it is, whatever the order says, until gated again."""
        self.gates[uav_id], self.waits_for[uav_id] = Gate.STOP, None
        self.approach.pop(uav_id, None)

    def out_of_the_way(self, uav_id: str) -> None:
        """`uav_id` is down for good: nobody waits for it any more, nor it for anyone."""
        self.gone.add(uav_id)
        self.gates[uav_id], self.waits_for[uav_id] = Gate.GO, None


class GateCommander:
    """Brings each vehicle to its gate with the commands that change it, one vehicle's at
    a time; `cruise(uav)` is the speed its mission flies it at where it is now."""

    def __init__(
        self,
        actions: Mapping[str, FlightActions],
        rule: StoppingRule,
        cruise: Callable[[str], float],
        on_failure: Callable[[str, str], None],
    ) -> None:
        self._actions = actions
        self._rule = rule
        self._cruise = cruise
        self._on_failure = on_failure
        self.applied = dict.fromkeys(actions, Gate.GO)
        self._wanted = dict.fromkeys(actions, Gate.GO)
        self._approach: dict[str, float] = {}  # the speed wanted of an approach
        self._speed_first: dict[str, bool] = {}  # an approach from a stop slowed first
        self._slowed: dict[str, float | None] = {}  # the approach speed last commanded
        self._tasks: dict[str, asyncio.Task[None]] = {}
        self._braking: set[str] = set()  # to be stopped out of their missions
        self._unanswered: set[str] = set()  # changes given up: the vehicle did not answer

    def want(
        self, uav_id: str, gate: Gate, speed_m_s: float | None = None, speed_first: bool = False
    ) -> None:
        """Bring the vehicle to `gate` (approaching at `speed_m_s`, a CREEP's; from a stop
        given its speed first if `speed_first`: `Gatekeeper._speed_first`)."""
        self._wanted[uav_id] = gate
        if speed_m_s is not None:
            self._approach[uav_id] = speed_m_s
        self._speed_first[uav_id] = speed_first
        task = self._tasks.get(uav_id)
        if task is None or task.done():
            self._tasks[uav_id] = asyncio.ensure_future(self._bring(uav_id))

    def brake(self, uav_id: str) -> None:
        """Stop the vehicle out of its mission (`FlightActions.brake_in_mission`), whatever
        its gate: its mission is about to change (a live replan), which would give up a
        pause. Its next change from STOP sends it on in AUTO, at the mission's speed."""
        self._braking.add(uav_id)
        self.applied[uav_id] = Gate.GO
        self._slowed[uav_id] = None
        self.want(uav_id, Gate.STOP)

    def settle(self, uav_id: str, gate: Gate) -> None:
        """The vehicle is at `gate` by other means (the operator held or continued it);
        one continued after an approach gets its mission's speed back."""
        self.applied[uav_id] = self._wanted[uav_id] = gate
        if gate == Gate.GO and self._slowed.get(uav_id) is not None:
            self.applied[uav_id] = Gate.CREEP  # so that `_bring` restores the speed
            self.want(uav_id, Gate.GO)

    def restarted(self, uav_id: str, gate: Gate, speed_m_s: float | None) -> None:
        """The vehicle was sent to the start of a new mission (a live replan's
        MISSION_SET_CURRENT), which gives up a pause (the mock flew on 50 m past its
        limit in fuzzed flight 3034, its pause taken as still in force): bring it to
        `gate` again, its speed commanded afresh."""
        self.applied[uav_id] = Gate.GO
        self._slowed[uav_id] = math.nan
        self.want(uav_id, gate, speed_m_s)

    def item_reached(self, uav_id: str) -> None:
        """The vehicle's mission reached an item: a DO_CHANGE_SPEED item after it sets the
        next leg's speed whatever an approach had asked for, so an approach is given its
        speed again (fuzzed flight 19864 at 10 m/s: uav3, creeping at 0.5 m/s 6 m short of
        its limit, passed a speed item and sped up; judged on its track once faster than
        its approach, it was paused 1.6 m short and ran on 4.6 m, 4.05 m from uav8)."""
        if self._wanted[uav_id] == Gate.CREEP and self.applied[uav_id] == Gate.CREEP:
            self._slowed[uav_id] = math.nan  # commanded afresh (`_brought`)
            self.want(uav_id, Gate.CREEP)

    def held_out_of_mission(self, uav_id: str) -> None:
        """The vehicle hovers out of its mission (not started yet): at STOP, and its next
        change sends it on in AUTO (`FlightActions.found_stopped_out_of_mission`)."""
        self._actions[uav_id].found_stopped_out_of_mission()
        self.applied[uav_id] = self._wanted[uav_id] = Gate.STOP
        self._slowed[uav_id] = None

    def found_stopped(self, uav_id: str) -> None:
        """The vehicle was stopped by others (a flight followed again): at STOP, and its
        speed not known, so that the first change gives it its mission's speed again."""
        self.applied[uav_id] = self._wanted[uav_id] = Gate.STOP
        self._slowed[uav_id] = math.nan  # equal to no speed: always commanded afresh

    async def stand_down(self, uav_ids: Iterable[str]) -> None:
        """The operator takes these vehicles (a hold, a landing, a return, an abort): a
        change under way is given up before the operator's command goes out, so that
        none of its commands (a resume, AUTO after a brake) lands after the operator's
        and undoes it."""
        tasks = [task for uav in uav_ids if (task := self._tasks.pop(uav, None)) is not None]
        for task in tasks:
            task.cancel()
        for task in tasks:
            with contextlib.suppress(asyncio.CancelledError, GcsError):
                await task

    def heard(self, uav_id: str) -> None:
        """The vehicle was heard again: a change given up because it did not answer is
        tried again (fuzzed flight 1014 with uav4's link silent 5 s: the pause decided
        while nobody heard it failed, and once heard it flew on past its limit, 2.32 m
        from uav1, its gate taken as in force)."""
        if uav_id in self._unanswered and not self._brought(uav_id):
            self.want(uav_id, self._wanted[uav_id])
        self._unanswered.discard(uav_id)

    def changing(self, uav_id: str) -> bool:
        """A change of the vehicle's gate is under way (its commands may be on the way)."""
        task = self._tasks.get(uav_id)
        return task is not None and not task.done()

    def _brought(self, uav_id: str) -> bool:
        """At its gate; one to be braked only once braked (a brake asked for while a
        pause was under way was taken as done by the pause's end: its mission, given
        anew, sent it on, fuzzed flight 4703, 0.63 m)."""
        wanted = self._wanted[uav_id]
        braking = wanted == Gate.STOP and uav_id in self._braking
        sped_up = wanted == Gate.CREEP and self._slowed.get(uav_id) != self._approach.get(uav_id)
        return self.applied[uav_id] == wanted and not braking and not sped_up

    async def _bring(self, uav_id: str) -> None:
        while not self._brought(uav_id):
            target = self._wanted[uav_id]
            try:
                await self._change(uav_id, self.applied[uav_id], target)
            except GcsError as exc:
                self._on_failure(uav_id, f"could not {target.value}: {exc}")
                if isinstance(exc, TimeoutError | LinkError):
                    self._unanswered.add(uav_id)
                return
            self.applied[uav_id] = target

    async def _change(self, uav_id: str, old: Gate, new: Gate) -> None:
        """Pause for STOP; an approach from a stop (`FlightActions.approach`: no faster
        than its speed); AUTO again for one stopped out of its mission; otherwise the
        speed first (an approach's, or the mission's again after one, even one that
        ended in a stop), then resume if stopped."""
        actions = self._actions[uav_id]
        if new == Gate.STOP and uav_id in self._braking:
            await actions.brake_in_mission()
            self._braking.discard(uav_id)
            return
        if new == Gate.STOP:
            await actions.pause_mission()
            return
        speed = self._approach.get(uav_id, self._rule.creep_m_s) if new == Gate.CREEP else None
        if speed is not None and old == Gate.STOP:
            self._slowed[uav_id] = math.nan  # unknown until the approach's speed is in
            await actions.approach(speed, self._speed_first.get(uav_id, False))
            self._slowed[uav_id] = speed
            return
        if old == Gate.STOP and actions.out_of_mission:
            await actions.resume_mission()  # AUTO, then the mission's speed: ArduCopter
            self._slowed[uav_id] = None  # refuses a speed in BRAKE (FAILED)
            return
        if speed != self._slowed.get(uav_id):
            await actions.change_speed(self._cruise(uav_id) if speed is None else speed)
            self._slowed[uav_id] = speed
        if old == Gate.STOP:
            await actions.resume_mission()

    async def close(self) -> None:
        await self.stand_down(list(self._tasks))
