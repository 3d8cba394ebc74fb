"""A vehicle stopped inside an encounter it was to wait short of leads it there.

The passing order keeps two vehicles apart as long as each stays behind its limit. One
whose stop came late (a pause lost again and again on a lossy link) can stand past its
limit, inside the encounter, and its leader would then pass it where it stands (fuzzed
flight 6698: a pause lost four times running, uav6 stood 1.5 m inside, and uav4 passed it
5.43 m away, 2R 6 m). It cannot go back, so the order is turned round there: it goes
first, and the leader waits for it, if the leader can still stop short, or stands still
already where the other's way keeps 2R from it (`CanWait`: the flight decides).

Turned waits can point backwards in the plan's time, so they can make waits go round in
a circle (the leader waits for it, it waits further on for a third, who waits for the
leader). Each such circle is broken where one of its waits can be turned round too, and
the new order is taken only if everyone then reaches their end (`PassingOrder.reach`);
otherwise the order stays as it was.

A vehicle whose link is down while it flies on cannot be stopped at all: its mission
goes on without the ground station (ArduCopter's GCS failsafe is off by default). It is
given the lead of every encounter it has not left behind, wherever the other can still
wait for it (`lead_ahead`); the others then wait until it is heard past them (a link
drop of 5 s let one fly 5 m into its encounter, and it was stopped there, in its leader's
way: fuzzed flight 1014 with link drops, 0.65 m apart).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from gcs.mission.passing_order import Limit, PassingOrder

CanWait = Callable[[PassingOrder, str, str], bool]
"""Whether, under an order, a vehicle (the first) can still stop where it waits for
another (the second)."""


@dataclass(frozen=True)
class LeadTaken:
    """The order after a vehicle took the lead, and the pairs turned: (first, waits)."""

    order: PassingOrder
    turned: list[tuple[str, str]]


def take_the_lead(
    order: PassingOrder,
    uav: str,
    at: Mapping[str, float],
    ends: Mapping[str, float],
    can_wait: CanWait,
) -> LeadTaken | None:
    """`uav` (at `at[uav]`, everyone at `at`, metres along their paths ending at `ends`)
    leads every encounter it stands inside; then every circle of waits is broken where a
    wait can be turned. None if a leader it stands before can no longer stop short, or
    a circle cannot be broken."""
    turns = _Turns(can_wait)
    limit = order.limit(uav, at)
    while limit.at_m < at[uav]:
        inside = turns.turn(order, uav, limit)
        if inside is None:
            return None
        order, limit = inside, inside.limit(uav, at)
    return turns.without_circles(order, uav, at, ends)


def lead_ahead(
    order: PassingOrder,
    uav: str,
    at: Mapping[str, float],
    ends: Mapping[str, float],
    can_wait: CanWait,
) -> LeadTaken | None:
    """`uav`, which nobody can stop now (its link is down while it flies on, and its
    mission goes on without the ground station), leads every encounter that neither it
    nor the other has left behind, where the other can still wait for it; then every
    circle of waits is broken as `take_the_lead` breaks them. None if nothing could be
    turned, or a circle cannot be broken."""
    turns = _Turns(can_wait)
    for meeting in order.encounters(uav):
        if meeting.last_m >= at[uav] and at.get(meeting.leader, 0.0) < meeting.cleared_m:
            limit = Limit(meeting.first_m, meeting.leader)
            order = turns.turn(order, uav, limit, once=False) or order
    if not turns.turned:
        return None
    return turns.without_circles(order, uav, at, ends)


class _Turns:
    """Encounters turned round, each where the one who is to wait now can still wait;
    a pair turned one way is never turned back (it would go round for ever)."""

    def __init__(self, can_wait: CanWait) -> None:
        self.can_wait = can_wait
        self.turned: list[tuple[str, str]] = []

    def turn(
        self, order: PassingOrder, follower: str, limit: Limit, once: bool = True
    ) -> PassingOrder | None:
        """`follower` leads the encounter where it waits at `limit`; `once`: unless any
        encounter of the pair was turned already (else: unless one was turned the other
        way)."""
        leader = limit.leader
        back = (leader, follower) in self.turned
        again = any({follower, leader} == set(pair) for pair in self.turned)
        if leader is None or (again if once else back):
            return None
        swapped = order.swapped(follower, leader, limit.at_m)
        if swapped is None or not self.can_wait(swapped, leader, follower):
            return None
        self.turned.append((follower, leader))
        return swapped

    def without_circles(
        self, order: PassingOrder, uav: str, at: Mapping[str, float], ends: Mapping[str, float]
    ) -> LeadTaken | None:
        """The order with every circle of waits broken where one of its waits can be
        turned (None if one cannot be)."""
        for _ in range(4 * len(at)):
            circle = _circle(order, order.reach(at, ends), uav)
            if circle is None:
                return LeadTaken(order, self.turned)
            broken = next((o for w in circle if (o := self.turn(order, *w)) is not None), None)
            if broken is None:
                return None
            order = broken
        return None


def _circle(
    order: PassingOrder, reached: Mapping[str, float], start: str
) -> list[tuple[str, Limit]] | None:
    """A circle of waits among the vehicles that stop for ever (`PassingOrder.reach`),
    each with the limit it waits at, from `start` on if it is one of them; None if
    everyone gets through. (Each of them waits for another of them: one that gets
    through lets everyone by.)"""
    stuck = [uav for uav, s in reached.items() if s < math.inf]
    if not stuck:
        return None
    uav, seen = (start if start in stuck else stuck[0]), []
    while uav not in seen:
        seen.append(uav)
        uav = order.limit(uav, reached).leader or ""
    return [(u, order.limit(u, reached)) for u in seen[seen.index(uav) :]]
