"""The operator's commands: abort, hold and continue the fleet; hold, land, return home
or continue one vehicle. They work in every state in which a vehicle may be armed.

An abort never waits: it cancels the flight's operation and runner, commands every
reachable vehicle, and leaves the flight `aborting` until every vehicle is disarmed on
the ground. A hold during the start cancels the start. A flight with no live fleet (after
a restart, or a start that failed) is commanded through the vehicles' links directly.
Per-vehicle commands go to the flight that owns the vehicle, if any, so that the fleet
knows (an operator's hold is never lifted by the schedule keeper; a vehicle sent down or
home leaves the plan); a vehicle that belongs to no flight is simply commanded.

A flight nobody followed for a while (its service was killed, and this one restarted or
took it over) may have vehicles still flying their missions, with nobody keeping the
passing order. Each such vehicle's mission is paused as soon as its link is up, as a
stopping service would have held it, unless the operator commands it first; the
operator then resumes the flight (followed again from where its vehicles are), or lands,
returns or aborts them.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable, Iterable, Mapping
from typing import Any, Literal

from gcs.fleet.crew import Fallback
from gcs.fleet.events import EventKind
from gcs.fleet.outcome import VehicleOutcome
from gcs.mavlink.actions import FlightActions
from gcs.mavlink.errors import GcsError
from gcs.mavlink.link import VehicleLink
from gcs.service.flights.active import ActiveFlight, VehicleAnswer
from gcs.service.flights.book import FlightBook
from gcs.service.flights.service import FlightService
from gcs.service.states import FlightState, StateConflict
from gcs.service.storage.tables import FlightRow
from gcs.service.vehicle_registry import VehicleRegistry

log = logging.getLogger("mvo_gcs.operator")
F = FlightState
VehicleAction = Literal["hold", "land", "rtl", "continue"]
DOWN_POLL_S = 0.25
RESUME_WITHIN_S = 60.0
"""How long a flight taken over waits for every vehicle to be heard to resume by itself."""
SETTLE_S = 4.0
"""How long every vehicle must have been down, and nothing sent to any, before a flight
closes: longer than a packet may take on a link that is still up (its timeout)."""
START_RACE_S = 5.0
"""After a start is cancelled, how long a vehicle not (yet) seen in AUTO is watched for
it: the start's AUTO and MISSION_START may be on their way, and a HEARTBEAT saying so
may be lost."""


class OperatorCommands:
    def __init__(self, flights: FlightService, registry: VehicleRegistry) -> None:
        self.flights = flights
        self.book: FlightBook = flights.book
        self.registry = registry
        self._watchers: dict[str, asyncio.Task[None]] = {}
        self.require: Callable[[str], Awaitable[None]] = _anyone
        """409 unless this service controls the flight (FlightControl.require)."""
        self._owed: dict[str, tuple[Fallback, set[str]]] = {}
        """Per aborting flight: the abort's action, and the vehicles it has not reached yet
        (offline when it was sent, or it failed, or braked on its way since): sent to each
        as soon as it can be."""
        self._abort_modes: dict[str, dict[str, str]] = {}
        """Per aborting flight: each vehicle's mode when last looked at (`_note_brakes`);
        one the operator commands himself after the abort is no longer in it."""
        self._unfollowed: dict[str, dict[str, str]] = {}
        """Per interrupted flight: the vehicles whose missions are to be paused once
        reachable (nobody keeps their passing order), until the operator commands them."""
        self._unfollowed_until: dict[str, float] = {}
        """Per interrupted flight: until when a vehicle not flying its mission is still
        watched for starting it (a cancelled start's commands on their way)."""
        self._resumers: dict[str, asyncio.Task[None]] = {}
        """Per flight taken over in the air: its resume once every vehicle is heard."""

    # --- the fleet ---------------------------------------------------------------------

    async def abort(self, flight_id: str, mode: str) -> list[VehicleAnswer]:
        """Every vehicle returns to launch ("rtl") or lands where it is ("land")."""
        fallback = Fallback(mode)
        asked = _now()
        slot = self.book.slot(flight_id)
        async with slot.intervention():
            row = await self.book.row(flight_id)
            state = FlightState(row.state)
            if not state.is_open:
                raise StateConflict(
                    f"flight {flight_id} is {state.value}: its vehicles are all on the ground, "
                    "so there is nothing to abort (command one with /vehicles/{id}/land)"
                )
            self.operator_took(flight_id)
            self._owed.pop(flight_id, None)  # an earlier abort's owed: this one overrides it
            self._abort_modes[flight_id] = dict.fromkeys(row.bindings.values(), "")
            preempting = asyncio.ensure_future(slot.preempt())
            active = self.book.active.get(flight_id)
            if active is not None and active.fleet.crew.members:
                outcomes = await active.fleet.abort(fallback.value)
            else:
                outcomes = await self._command_links(row, _fallback_action(fallback))
            await preempting
            if state != F.ABORTING:
                with contextlib.suppress(StateConflict):
                    await self.book.transition(
                        flight_id, F.ABORTING, f"{fallback.value} by the operator"
                    )
            missed = {row.bindings[uav] for uav in row.bindings if not _done(outcomes.get(uav))}
            self._owed[flight_id] = (fallback, missed)
            self.watch_until_down(flight_id)
            return _answers(row, outcomes, asked)

    async def hold(self, flight_id: str) -> list[VehicleAnswer]:
        """The operator's fleet hold (`/pause`): every vehicle stops where it is. During
        the start, or when a start goes ahead of it, the start is cancelled first."""
        asked = _now()
        slot = self.book.slot(flight_id)
        if FlightState((await self.book.row(flight_id)).state) == F.STARTING:
            return await self._hold_the_start(flight_id, asked)
        async with slot.serial():
            row = await self.book.row(flight_id)  # afresh: a start may have gone first
            state = FlightState(row.state)
            if state == F.STARTING:
                return await self._hold_the_start(flight_id, asked)
            active = self.book.active.get(flight_id)
            if state in (F.FLYING, F.PAUSED) and active is not None:
                outcomes = await active.fleet.hold()
                if state == F.FLYING:
                    await self.book.transition(flight_id, F.PAUSED, "held by the operator")
            elif state.is_open:
                self.operator_took(flight_id)
                outcomes = await self._command_links(row, lambda a: a.hold())
            else:
                raise StateConflict(f"flight {flight_id} is {state.value}: nothing to hold")
            return _answers(row, outcomes, asked)

    async def _hold_the_start(self, flight_id: str, asked: float) -> list[VehicleAnswer]:
        """The start cannot go on with vehicles held: stop it (and wait until it has
        stopped) before holding every vehicle; the flight is then interrupted and stays
        open until every vehicle is down."""
        slot = self.book.slot(flight_id)
        async with slot.intervention():
            row = await self.book.row(flight_id)
            await slot.preempt()
            outcomes = await self._command_links(row, lambda a: a.hold())
            await self.flights.to_interrupted(flight_id, "held by the operator during the start")
            self.pause_unfollowed(flight_id, row.bindings, watch_s=START_RACE_S)
            return _answers(row, outcomes, asked)

    async def continue_(self, flight_id: str) -> list[VehicleAnswer]:
        """Lift the operator's hold on every vehicle (`/continue`)."""
        asked = _now()
        async with self.book.slot(flight_id).serial():
            row = await self.book.row(flight_id)
            state = FlightState(row.state)
            active = self.book.active.get(flight_id)
            if state not in (F.FLYING, F.PAUSED) or active is None:
                raise StateConflict(
                    f"flight {flight_id} is {state.value}: only a flying or paused flight "
                    "continues (abort, or command the vehicles one by one)"
                )
            outcomes = await active.fleet.continue_()
            if state == F.PAUSED:
                await self.book.transition(flight_id, F.FLYING, "continued by the operator")
            return _answers(row, outcomes, asked)

    def resume_when_heard(self, flight_id: str, why: str) -> None:
        """Resume the flight by itself (taken over in the air) once every vehicle is heard
        and each pause owed to it was tried, within `RESUME_WITHIN_S`; any command of the
        operator's on the flight or one of its vehicles first calls it off."""
        self._resumers[flight_id] = asyncio.ensure_future(self._resume_when_heard(flight_id, why))

    async def _resume_when_heard(self, flight_id: str, why: str) -> None:
        bindings = await self.book.bindings(flight_id)
        deadline = _now() + RESUME_WITHIN_S
        while await self.book.state(flight_id) == F.INTERRUPTED:
            heard = all(self.registry.link_or_none(v) is not None for v in bindings.values())
            if heard and not self._unfollowed.get(flight_id):
                self._resumers.pop(flight_id, None)  # from here on, no command calls it off
                try:
                    answers = await self.resume(flight_id, why)
                    detail = "; ".join(f"{a.uav_id}: {a.detail}" for a in answers)
                except Exception as exc:  # refused (409), or a vehicle did not answer
                    detail = f"not resumed: {exc}"
                ok = await self.book.state(flight_id) == F.FLYING
                self._tell(flight_id, EventKind.AUTO_RESUMED, {"ok": ok, "detail": detail})
                return
            if _now() > deadline:
                detail = f"not resumed: not every vehicle heard within {RESUME_WITHIN_S:g} s"
                self._tell(flight_id, EventKind.AUTO_RESUMED, {"ok": False, "detail": detail})
                return
            await asyncio.sleep(DOWN_POLL_S)

    def _tell(self, flight_id: str, kind: EventKind, data: dict[str, Any]) -> None:
        message = {"type": "event", "kind": kind, **data}
        self.book.events.record(flight_id, kind, message, data.get("uav_id"))
        self.book.tell(flight_id, message)

    async def resume(self, flight_id: str, why: str = "by the operator") -> list[VehicleAnswer]:
        """Follow an interrupted flight again from where its vehicles are
        (`FlightService.resume`). The watch until every vehicle is down, and its pauses
        of the vehicles nobody followed, stop first (none may land after the follower's
        go); both carry on if the flight does not resume."""
        pending = dict(self._unfollowed.get(flight_id, {}))
        self.operator_took(flight_id)  # a resume by itself waiting is called off
        watcher = self._watchers.pop(flight_id, None)
        if watcher is not None:
            watcher.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await watcher
        try:
            return await self.flights.resume(flight_id, why)
        finally:
            if await self.book.state(flight_id) == F.INTERRUPTED:
                if pending:
                    self._unfollowed[flight_id] = pending
                self.watch_until_down(flight_id)

    # --- one vehicle --------------------------------------------------------------------

    async def vehicle(self, vehicle_id: str, action: VehicleAction) -> VehicleAnswer:
        """Hold, land, return home or continue one vehicle, in or out of a flight."""
        asked = _now()
        owner = await self.book.open_flight_of(vehicle_id)
        if owner is None:
            link = self.registry.link(vehicle_id)
            outcome = await _on_link(FlightActions(link), action, vehicle_id)
            return VehicleAnswer("", vehicle_id, outcome.ok, outcome.detail, _now() - asked)
        await self.require(owner.id)  # another live service controls it: 409 naming it
        self.registry.link(vehicle_id)  # offline: 409 saying why
        uav = self.book.uav_of(owner, vehicle_id)
        self.operator_took(owner.id, vehicle_id)
        async with self.book.slot(owner.id).intervention():
            outcome = await self._in_flight(owner, uav, vehicle_id, action)
        kind = EventKind.OPERATOR_COMMAND
        self.book.events.record(
            owner.id, kind, {"type": "event", "kind": kind, "uav_id": uav, "action": action,
            "ok": outcome.ok, "detail": outcome.detail}, uav,
        )  # fmt: skip
        return VehicleAnswer(uav, vehicle_id, outcome.ok, outcome.detail, _now() - asked)

    async def _in_flight(
        self, owner: FlightRow, uav: str, vehicle_id: str, action: VehicleAction
    ) -> VehicleOutcome[Any]:
        state = await self.book.state(owner.id)
        active = self.book.active.get(owner.id)
        if state in (F.FLYING, F.PAUSED) and active is not None:
            return await _in_fleet(active, uav, action)
        if action == "continue":
            raise StateConflict(
                f"vehicle {vehicle_id} ({uav}) is in flight {owner.id}, which is {state.value}: "
                "only a flying flight continues"
            )
        if state == F.STARTING:  # one vehicle taken out of the line-up: the start is off
            await self.book.slot(owner.id).preempt()
            await self.flights.to_interrupted(
                owner.id, f"{uav} commanded to {action} during the start"
            )
            others = {u: vid for u, vid in owner.bindings.items() if vid != vehicle_id}
            self.pause_unfollowed(owner.id, others, watch_s=START_RACE_S)
        outcome = await _on_link(FlightActions(self.registry.link(vehicle_id)), action, uav)
        if state in (F.ABORTING, F.INTERRUPTED, F.STARTING):
            self.watch_until_down(owner.id)
        return outcome

    # --- until every vehicle is down ---------------------------------------------------

    def watch_until_down(self, flight_id: str) -> None:
        """Close the flight (`aborting` → `aborted`, `interrupted` → `ended`) once every
        vehicle is disarmed on the ground, as their links report it."""
        watcher = self._watchers.get(flight_id)
        if watcher is None or watcher.done():
            self._watchers[flight_id] = asyncio.ensure_future(self._until_down(flight_id))

    def owe_abort(self, flight_id: str, fallback: Fallback, vehicle_ids: Iterable[str]) -> None:
        """Send the abort again to each of `vehicle_ids` not yet down, as soon as it can be
        (a flight taken over from a service that died while aborting it)."""
        self._owed[flight_id] = (fallback, set(vehicle_ids))
        self._abort_modes[flight_id] = dict.fromkeys(vehicle_ids, "")
        self.watch_until_down(flight_id)

    def pause_unfollowed(
        self, flight_id: str, bindings: Mapping[str, str], watch_s: float = 0.0
    ) -> None:
        """Pause the mission of each vehicle (`bindings`: UAV to vehicle id) still flying
        it, as soon as its link is up (the flight was not followed for a while: after a
        restart, or taken over; or its start was cancelled, which may have sent some
        vehicles off on their missions already: fuzzed flight 3519 saw two of them
        collide). A vehicle not flying its mission is watched for `watch_s` more."""
        self._unfollowed[flight_id] = {vid: uav for uav, vid in bindings.items()}
        self._unfollowed_until[flight_id] = _now() + watch_s
        self.watch_until_down(flight_id)

    def operator_took(self, flight_id: str, vehicle_id: str | None = None) -> None:
        """The operator commands the flight's vehicles (or one): none of them (or not that
        one) is paused for being unfollowed from now on, nor sent an abort again once
        braked; that one is not owed an earlier abort either."""
        if vehicle_id is None:
            self._unfollowed.pop(flight_id, None)
            self._abort_modes.pop(flight_id, None)
        else:
            self._unfollowed.get(flight_id, {}).pop(vehicle_id, None)
            self._abort_modes.get(flight_id, {}).pop(vehicle_id, None)
            owed = self._owed.get(flight_id)
            if owed is not None:
                owed[1].discard(vehicle_id)
        resumer = self._resumers.pop(flight_id, None)
        if resumer is not None:
            resumer.cancel()

    def stop_watching(self, flight_id: str) -> None:
        """Another service holds the flight now: it watches it, not this one."""
        watcher = self._watchers.pop(flight_id, None)
        if watcher is not None:
            watcher.cancel()
        self._owed.pop(flight_id, None)
        self.operator_took(flight_id)  # no resume of a flight another service holds

    async def _until_down(self, flight_id: str) -> None:
        bindings = await self.book.bindings(flight_id)
        down_since: float | None = None
        while True:
            state = await self.book.state(flight_id)
            if not state.is_open or state not in (F.ABORTING, F.INTERRUPTED):
                break
            self._note_brakes(flight_id, bindings)
            await self._pay_what_is_owed(flight_id)
            await self._pause_unfollowed(flight_id)
            if self._all_down(flight_id, bindings.values()):
                down_since = _now() if down_since is None else down_since
                if _now() - self._settled_since(down_since, bindings.values()) >= SETTLE_S:
                    final = F.ABORTED if state == F.ABORTING else F.ENDED
                    with contextlib.suppress(StateConflict):
                        await self.book.transition(flight_id, final, "every vehicle is down")
                    await self.flights.retire_when_down(flight_id)
                    break
            else:
                down_since = None
            await asyncio.sleep(DOWN_POLL_S)
        self._watchers.pop(flight_id, None)
        self._owed.pop(flight_id, None)
        self._abort_modes.pop(flight_id, None)
        self._unfollowed.pop(flight_id, None)
        self._unfollowed_until.pop(flight_id, None)

    def _note_brakes(self, flight_id: str, bindings: Mapping[str, str]) -> None:
        """A vehicle on its abort's way that switches into BRAKE by itself is owed the
        abort again: an RTL is no landing, so its GCS failsafe brakes it once it has not
        heard us for a while (`gcs.fleet.link_loss`; ArduCopter's failsafe_gcs_on_event),
        and it would hover there. A switch counts, not BRAKE itself (one the operator
        holds has left the abort's care: `operator_took`)."""
        modes, owed = self._abort_modes.get(flight_id), self._owed.get(flight_id)
        if modes is None or owed is None:
            return
        for uav, vehicle_id in sorted(bindings.items()):
            link = self.registry.link_or_none(vehicle_id)
            if vehicle_id not in modes or link is None or not link.state.link_up:
                continue
            before, modes[vehicle_id] = modes[vehicle_id], link.state.mode
            if link.state.mode == "BRAKE" and before not in ("", "BRAKE") and link.state.armed:
                owed[1].add(vehicle_id)
                self._tell(flight_id, EventKind.BRAKED_ON_LINK_LOSS, {"uav_id": uav})

    async def _pay_what_is_owed(self, flight_id: str) -> None:
        """The abort to the vehicles it has not reached yet, now that they can be; given
        up as soon as another abort takes over (fuzzed flight 10380, flown with a change
        to the passing order's approach that was not kept: an RTL owed to uav4, offline
        after a restart, went out behind the operator's later LAND)."""
        owed = self._owed.get(flight_id)
        if owed is None:
            return
        fallback, missed = owed
        for vehicle_id in sorted(missed):
            if self._owed.get(flight_id) is not owed:
                return
            link = self.registry.link_or_none(vehicle_id)
            if link is None:
                continue  # not back yet
            with contextlib.suppress(GcsError):
                if not link.state.down:
                    await _fallback_action(fallback)(FlightActions(link))
                missed.discard(vehicle_id)

    async def _pause_unfollowed(self, flight_id: str) -> None:
        """Each reachable vehicle still flying its mission unfollowed: paused, once tried,
        all at once (one after another, over lossy links, the last of eight was paused
        seconds late at 10 m/s: 5.76 m from another in a replay of fuzzed flight 3519).
        A pause only (DO_PAUSE_CONTINUE), never a mode change: what the vehicle does
        otherwise (landing, going home, told so before) is left as it is, and the
        operator's commands from then on are not overridden. One found braked (by its
        own GCS failsafe, `gcs.fleet.link_loss`, or held by the service that stopped) is
        stopped already, and said so."""
        waiting = self._unfollowed.get(flight_id, {})
        watching = _now() < self._unfollowed_until.get(flight_id, 0.0)
        due = []
        for vehicle_id, uav in sorted(waiting.items()):
            link = self.registry.link_or_none(vehicle_id)
            if link is None or not link.state.mode:
                continue  # not back yet, or its HEARTBEAT not heard yet
            if link.state.mode == "AUTO" and link.state.armed:  # both from HEARTBEAT
                due.append((vehicle_id, link, uav))
            elif link.state.mode == "BRAKE" and link.state.armed:
                waiting.pop(vehicle_id)
                detail = "braked already (its GCS failsafe, or held): nobody keeps the order"
                data = {"uav_id": uav, "ok": True, "detail": detail}
                self._tell(flight_id, EventKind.UNFOLLOWED_PAUSED, data)
            elif not watching:
                waiting.pop(vehicle_id)
        await asyncio.gather(*(self._pause_one(flight_id, link, uav) for _, link, uav in due))
        for vehicle_id, _, _ in due:  # tried (a resume waits for that)
            self._unfollowed.get(flight_id, {}).pop(vehicle_id, None)

    async def _pause_one(self, flight_id: str, link: VehicleLink, uav: str) -> None:
        try:
            await FlightActions(link).pause()
            ok, detail = True, "mission paused: nobody keeps the passing order"
        except GcsError as exc:
            ok, detail = False, f"mission not paused ({exc}): land, return or abort it"
        log.warning("flight %s: %s: %s", flight_id, uav, detail)
        self._tell(
            flight_id, EventKind.UNFOLLOWED_PAUSED, {"uav_id": uav, "ok": ok, "detail": detail}
        )

    def _all_down(self, flight_id: str, vehicle_ids: Iterable[str]) -> bool:
        """Every vehicle disarmed on the ground, and nothing of the flight still running
        that could arm one (a start being cancelled, an upload)."""
        if self.book.slot(flight_id).busy:
            return False
        return all(self.registry.is_down(vid) for vid in vehicle_ids)

    def _settled_since(self, down_since: float, vehicle_ids: Iterable[str]) -> float:
        """Since when "all down" counts: not before the last thing sent to any of the
        vehicles, which may still be on its way (an ARM sent by a start just cancelled)."""
        sent = [self.registry.last_sent(vid) for vid in vehicle_ids]
        return max([down_since, *(t for t in sent if t is not None)])

    async def after_restart(self, holder_id: str | None = None) -> None:
        """Every flight that was open when the service stopped is `interrupted` now:
        watch it until its vehicles are down (their links come back on their own); with
        several services on one database, those this one holds (`holder_id`)."""
        for row in await self.book.flights.open_flights():
            if holder_id is None or row.owner_id in (None, holder_id):
                if FlightState(row.state) == F.INTERRUPTED:
                    self.pause_unfollowed(row.id, row.bindings)
                self.watch_until_down(row.id)

    async def close(self) -> None:
        tasks = [*self._watchers.values(), *self._resumers.values()]
        for task in tasks:
            task.cancel()
        if tasks:
            await asyncio.wait(tasks, timeout=2.0)

    # --- helpers ---------------------------------------------------------------------------

    async def _command_links(
        self, row: FlightRow, action: Callable[[FlightActions], Awaitable[Any]]
    ) -> dict[str, VehicleOutcome[Any]]:
        """`action` on every bound vehicle that is online, straight through its link."""

        async def one(uav: str, vehicle_id: str) -> VehicleOutcome[Any]:
            link = self.registry.link_or_none(vehicle_id)
            if link is None:
                return VehicleOutcome(
                    uav, False, f"unreachable: {self.registry.why_offline(vehicle_id)}"
                )
            try:
                detail = await action(FlightActions(link))
            except GcsError as exc:
                return VehicleOutcome(uav, False, str(exc), error=exc)
            return VehicleOutcome(uav, True, detail if isinstance(detail, str) else "ok")

        pairs = sorted(row.bindings.items())
        results = await asyncio.gather(*(one(uav, vid) for uav, vid in pairs))
        return {uav: outcome for (uav, _), outcome in zip(pairs, results, strict=True)}


async def _in_fleet(active: ActiveFlight, uav: str, action: VehicleAction) -> VehicleOutcome[Any]:
    fleet = active.fleet
    if action == "hold":
        return (await fleet.hold({uav}))[uav]
    if action == "continue":
        return (await fleet.continue_({uav}))[uav]
    return await fleet.withdraw(uav, action)


async def _on_link(actions: FlightActions, action: VehicleAction, who: str) -> VehicleOutcome[Any]:
    try:
        if action == "hold":
            return VehicleOutcome(who, True, await actions.hold())
        if action == "land":
            await actions.land()
        elif action == "rtl":
            await actions.return_to_launch()
        elif actions.link.state.mode in ("AUTO", "BRAKE"):  # paused, or braked by a hold
            await actions.proceed()
        else:
            raise StateConflict(
                f"vehicle {who} is in {actions.link.state.mode or 'no known mode'}, not paused "
                "or braked in a mission: there is nothing to continue"
            )
    except GcsError as exc:
        return VehicleOutcome(who, False, str(exc), error=exc)
    return VehicleOutcome(who, True, "ok")


async def _anyone(_flight_id: str) -> None:
    """One service alone on its database controls every flight."""


def _done(outcome: VehicleOutcome[Any] | None) -> bool:
    return outcome is not None and outcome.ok


def _fallback_action(fallback: Fallback) -> Callable[[FlightActions], Awaitable[Any]]:
    if fallback == Fallback.LAND:
        return lambda a: a.land()
    if fallback == Fallback.RTL:
        return lambda a: a.return_to_launch()
    return lambda a: a.hold()


def _answers(
    row: FlightRow, outcomes: dict[str, VehicleOutcome[Any]], asked: float
) -> list[VehicleAnswer]:
    """Each vehicle's answer, with the seconds from the request to that vehicle's own
    answer (to the whole operation's end where it was not timed alone)."""
    elapsed = _now() - asked
    answers = []
    for uav, vid in sorted(row.bindings.items()):
        outcome = outcomes.get(uav)
        if outcome is None:
            answers.append(VehicleAnswer(uav, vid, False, "not commanded", elapsed))
            continue
        own = elapsed if outcome.seconds is None else min(elapsed, outcome.seconds)
        answers.append(VehicleAnswer(uav, vid, outcome.ok, outcome.detail, own))
    return answers


def _now() -> float:
    return asyncio.get_running_loop().time()
