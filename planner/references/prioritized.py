"""Prioritized planning with space-time A*: the classic decoupled reference.

UAVs are planned one after another; each searches (cell, time) space on the
8-connected grid without corner cutting, with a wait action, and treats the UAVs
planned before it as moving obstacles. Time is continuous: a straight move takes
1/speed, a diagonal √2/speed and a wait `wait`/speed, so the timing is physically
right. Every candidate move is tested exactly (closed form on each linear piece,
the same test as `planner.check.safety.closest_approach`) against the flights already
planned, so a returned plan is safe by OUR continuous-time check, not merely free
of MAPF vertex and edge conflicts. States whose times fall in the same
`resolution` bucket of a cell are merged, which bounds the search.

A UAV is airborne from t = 0 until its last point. A UAV not yet planned is held
on its start for `start_hold` cell times, so that the earlier ones leave it room
to take off; after that it is on its own and may fail, which is the usual price
of prioritized planning (incomplete: an order can fail where another succeeds).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator, Sequence

import numpy as np

from planner.model.scenario import Scenario, UAVSpec
from planner.model.trajectory import Trajectory
from planner.references import ReferenceResult
from planner.search.space_time import DEFAULT_LIMITS, Flight, Search, SearchLimits, to_trajectory

NAME = "prioritized A*"


def _held(spec: UAVSpec, hold: float) -> Flight:
    """A UAV not planned yet: hovering on its start for `hold` cell times."""
    x, y = map(float, spec.start)
    return Flight([0.0, hold / spec.speed], [x, x], [y, y], spec.radius)


def plan_order(
    scenario: Scenario, order: Sequence[str], limits: SearchLimits
) -> tuple[dict[str, Trajectory] | str, int]:
    """Plan the UAVs in `order`; the trajectories, or which UAV failed and why."""
    specs = {u.id: u for u in scenario.uavs}
    free = ~scenario.blocked()
    for cell in scenario.object_cells():
        free[cell] = False
    side = scenario.grid.width + scenario.grid.height
    planned: dict[str, Trajectory] = {}
    flights: list[Flight] = []
    expansions = 0
    for k, uid in enumerate(order):
        spec = specs[uid]
        waiting = [_held(specs[u], limits.start_hold) for u in order[k + 1 :]]
        horizon = limits.horizon
        if horizon is None:
            horizon = max((f.ts[-1] for f in flights), default=0.0) + 2 * side / spec.speed
        search = Search(spec, free, flights + waiting, limits, horizon)
        states = search.run()
        expansions += search.expansions
        if isinstance(states, str):
            after = f" (after {', '.join(order[:k])})" if k else ""
            return f"{uid} found no path{after}: {states}", expansions
        planned[uid] = to_trajectory(states)
        flights.append(Flight.of(planned[uid], spec.radius))
    return planned, expansions


def plan_prioritized(
    scenario: Scenario,
    order: Sequence[str] | None = None,
    limits: SearchLimits = DEFAULT_LIMITS,
    restarts: int = 0,
    seed: int = 0,
) -> ReferenceResult:
    """Prioritized planning in `order` (default: the scenario's), then, while it fails,
    in up to `restarts` random other orders."""
    started = time.perf_counter()
    ids = [u.id for u in scenario.uavs]
    first = list(order) if order is not None else ids
    if sorted(first) != sorted(ids):
        raise ValueError(f"order {first} is not a permutation of the UAV ids {ids}")
    notes: list[str] = []
    total = 0
    for attempt, current in enumerate(_orders(first, restarts, seed)):
        outcome, expansions = plan_order(scenario, current, limits)
        total += expansions
        if not isinstance(outcome, str):
            note = f"order {', '.join(current)}"
            if attempt:
                note += f" (attempt {attempt + 1}; earlier: {'; '.join(notes)})"
            return ReferenceResult(NAME, outcome, True, time.perf_counter() - started, note, total)
        notes.append(outcome)
    seconds = time.perf_counter() - started
    return ReferenceResult(NAME, None, False, seconds, "; ".join(notes), total)


def _orders(first: list[str], restarts: int, seed: int) -> Iterator[list[str]]:
    """`first`, then its reverse, then random orders: `restarts` more at most, all distinct."""
    rng = np.random.default_rng(seed)
    seen: set[tuple[str, ...]] = set()
    candidates = itertools.chain(
        [first, first[::-1]],
        ([first[i] for i in rng.permutation(len(first))] for _ in range(100 * (restarts + 1))),
    )
    for order in candidates:
        if len(seen) > restarts:
            return
        if tuple(order) not in seen:
            seen.add(tuple(order))
            yield order
