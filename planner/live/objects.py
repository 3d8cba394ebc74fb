"""What objects reported in flight block, and when (the live wormhole step's map).

A reported object is on a cell from now on, or only during a window; `Blocking` holds
them with the obstacles and the objects known before, with time counted from `now`:
the exact cell rule with each timed object only in its window, and the timed objects as
motionless discs for a search's traffic.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.check.safety import Conflict, cell_conflicts, check_plan
from planner.flows.planning import MAX_HOVER
from planner.geometry.clearance import ClearanceField
from planner.geometry.grid_search import cell_map
from planner.model.scenario import UAVSpec
from planner.model.trajectory import Trajectory

Cell = tuple[int, int]
# The search keeps UAVs apart as discs: a disc round each quarter of a cell covers the
# cell's square, and it reaches at most 0.1 cell beyond it, so neighbours stay usable.
QUARTERS = np.array([(-0.25, -0.25), (-0.25, 0.25), (0.25, -0.25), (0.25, 0.25)])
QUARTER_RADIUS = math.sqrt(2.0) / 4.0


@dataclass(frozen=True)
class NewObject:
    """A non-UAV object on `cell`, there during `window` (plan seconds, the end may be
    math.inf) or, without a window, from now on."""

    cell: tuple[int, int]
    window: tuple[float, float] | None = None


@dataclass(frozen=True)
class Blocking:
    """What every UAV keeps clear of, with time counted from `now`."""

    obstacles: NDArray[np.bool_]
    objects: NDArray[np.bool_]  # known objects and reported ones there from now on
    timed: tuple[tuple[Cell, float, float], ...]  # reported objects there only in [a, b]
    field: ClearanceField  # obstacles and objects, for the search

    @classmethod
    def build(
        cls,
        obstacles: NDArray[np.bool_],
        known: Sequence[Cell],
        live: Sequence[NewObject],
        now: float,
    ) -> Blocking:
        objects = cell_map(known, obstacles.shape)
        timed = []
        for obj in live:
            a, b = window_from(obj, now)
            if b < 0:
                continue  # already gone
            if a <= 0 and math.isinf(b):
                objects[obj.cell] = True
            else:
                timed.append((obj.cell, max(a, 0.0), b))
        return cls(obstacles, objects, tuple(timed), ClearanceField.build(obstacles | objects))

    def cell_conflicts(self, uav: str, trajectory: Trajectory, radius: float) -> list[Conflict]:
        """The exact cell rule for one UAV, timed objects only during their window."""
        found = cell_conflicts(uav, trajectory, radius, self.obstacles, "obstacle")
        found += cell_conflicts(uav, trajectory, radius, self.objects, "non_uav_object")
        for cell, a, b in self.timed:
            found += timed_conflicts(uav, trajectory, radius, cell, (a, b), self.obstacles.shape)
        return found

    def discs(self, until: float) -> list[tuple[Trajectory, float, float]]:
        """Timed objects as motionless discs for the search's traffic, up to `until`."""
        out = []
        for (x, y), a, b in self.timed:
            if a > until:
                continue
            for dx, dy in QUARTERS:
                hover = np.array([[a, x + dx, y + dy], [min(b, until), x + dx, y + dy]])
                out.append((Trajectory(hover), QUARTER_RADIUS, 0.0))
        return out

    def max_wait(self, horizon: float) -> float:
        """Hover long enough to let the others pass, or a timed object go."""
        ends = [b for _, _, b in self.timed if math.isfinite(b)]
        return max([min(horizon + 1.0, MAX_HOVER)] + [b + 1.0 for b in ends])


def window_from(obj: NewObject, now: float) -> tuple[float, float]:
    """The object's window with time counted from `now` (from now on if it has none)."""
    if obj.window is None:
        return 0.0, math.inf
    return obj.window[0] - now, obj.window[1] - now


def timed_conflicts(
    uav: str,
    trajectory: Trajectory,
    radius: float,
    cell: Cell,
    window: tuple[float, float],
    shape: tuple[int, int],
) -> list[Conflict]:
    """The cell rule on the part of the flight during the window."""
    part = trajectory.between(*window)
    if part is None:
        return []
    return cell_conflicts(uav, part, radius, cell_map([cell], shape), "non_uav_object")


def fleet_conflicts(
    fleet: Mapping[str, Trajectory], specs: Mapping[str, UAVSpec], blocking: Blocking
) -> list[Conflict]:
    """`planner.check.safety.check_plan` on the remaining fleet, plus timed objects in
    their window."""
    radii = {u: specs[u].radius for u in fleet}
    objects = [(int(x), int(y)) for x, y in np.argwhere(blocking.objects)]
    found = check_plan(fleet, radii, blocking.obstacles, objects).conflicts
    for uav, track in fleet.items():
        for cell, a, b in blocking.timed:
            found += timed_conflicts(uav, track, radii[uav], cell, (a, b), blocking.obstacles.shape)
    return found
