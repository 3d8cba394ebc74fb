"""The plan re-timed so that no vehicle waits out another's landing on its way.

The planner's UAVs are gone the moment they arrive; a copter lands there (31 s from 20 m
at ArduCopter's defaults) and is in everyone's way until it is down. Where the plan
brings a UAV (the passer) within reach of another's goal soon after that one arrives,
the passing order stops the passer for the whole landing, and everyone who waits for
the passer waits too (the six-UAV swap through a gap lost 27 s so at 5 m/s).

Here the lander instead holds short of its final approach (the last stretch of its path
within reach of the passer's) until the passer is through. The hold is written into
the lander's plan times, and the order is derived again from the new clock, so every
wait still points forward in the plan's time and none can form a circle. A hold is kept
only where the order still keeps every pair apart at the flight's speed and the timed
flight ends sooner (`_improves`): a lander held short may delay others in turn.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from gcs.mission.geodesy import Floats
from gcs.mission.passing_order import PassingOrder, PlannedPath

MAX_HOLDS_TRIED = 8
"""Each try derives the order and times the flight again (a tenth of a second for ten
vehicles): a bound on what re-timing may add to setting a flight up."""

HOLD_BACK_M = 1.0
"""How far short of its final approach a lander holds, to be clear of the passer's reach
by more than the order's sampling (held 0.2 m short, a hover on the six-UAV gap swap
narrowed the pair's reach by 0.01 m, below what the order must keep)."""

Paths = dict[str, PlannedPath]
Derive = Callable[[Paths], PassingOrder | None]
"""The order of re-timed paths, or None where it cannot keep every pair apart at the
flight's speed (a hover where another passes narrows what the order can keep)."""
Score = Callable[[Paths, PassingOrder], tuple[float, float]]
"""The timed flight's (last arrival, sum of arrivals), seconds: lower is better."""


@dataclass(frozen=True)
class LandingWait:
    """`passer` waits for `lander` to be down; the lander's final approach begins
    `approach_m` along its path, and the passer is clear of it `clear_m` along its own."""

    passer: str
    lander: str
    approach_m: float
    clear_m: float


def landing_waits(order: PassingOrder, paths: Mapping[str, PlannedPath]) -> list[LandingWait]:
    """Every wait of one UAV for another's landing, earliest landing first."""
    found = []
    step = order.step_m
    for passer, waits in order.waits.items():
        for wait in waits:
            lander = paths[wait.leader]
            if not (wait.after > lander.length).any():
                continue  # it waits for the other to pass, not to land
            approach = _final_approach_m(wait.after - step, step)
            in_approach = wait.after - step >= approach - 1e-9
            clear = float(wait.at[in_approach].max()) + 2 * step
            found.append(LandingWait(passer, wait.leader, approach, clear))
    return sorted(found, key=lambda w: (paths[w.lander].arrive[-1], w.lander, w.passer))


def clear_landings(
    paths: Paths, order: PassingOrder, derive: Derive, score: Score
) -> tuple[Paths, PassingOrder]:
    """`paths` with landers held short wherever that makes the flight end sooner, and
    their order."""
    if not landing_waits(order, paths):
        return paths, order  # (most flights: not timed here)
    best = score(paths, order)
    tried: set[tuple[str, str]] = set()
    for _ in range(MAX_HOLDS_TRIED):
        untried = [w for w in landing_waits(order, paths) if (w.lander, w.passer) not in tried]
        if not untried:
            break
        wait = untried[0]
        tried.add((wait.lander, wait.passer))
        held = dict(paths)
        held[wait.lander] = _held_short(paths, wait, order.step_m)
        held_order = derive(held)
        if held_order is None:
            continue
        result = score(held, held_order)
        if _improves(result, best):
            paths, order, best = held, held_order, result
    return paths, order


def _improves(result: tuple[float, float], best: tuple[float, float]) -> bool:
    """Sooner to the last arrival, or as soon and sooner in sum (by a tenth of a second:
    the timing's step is a twentieth)."""
    if result[0] < best[0] - 0.1:
        return True
    return result[0] <= best[0] + 1e-9 and result[1] < best[1] - 0.1


def _held_short(paths: Mapping[str, PlannedPath], wait: LandingWait, step_m: float) -> PlannedPath:
    """The lander hovering before its final approach until the passer has left it."""
    lander, passer = paths[wait.lander], paths[wait.passer]
    hold_at = max(wait.approach_m - HOLD_BACK_M, 0.0)
    return lander.held(hold_at, passer.leaves(min(wait.clear_m, passer.length)) + step_m)


def _final_approach_m(lander_s: Floats, step_m: float) -> float:
    """Where the last unbroken stretch of the lander's samples near the passer begins
    (samples lie at most `step_m` apart)."""
    s = np.unique(lander_s)[::-1]
    breaks = np.flatnonzero(-np.diff(s) > step_m + 1e-6)
    return float(s[breaks[0]] if len(breaks) else s[-1])
