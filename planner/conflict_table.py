"""Who is in conflict with whom, kept up to date one UAV at a time.

Algorithm 1 replans one UAV at a time, so after a replan only that UAV's pairs can
have changed. The table keeps every pair's closest approach (from the exact
`planner.safety.closest_approach`) and every UAV's blocked-cell hits, and recomputes
one row when a path changes: n - 1 pairs instead of n (n - 1) / 2, which is what
makes fleets of fifty affordable. Its numbers are the exact check's own, so the
priorities it gives (eq. 7) equal the white hole's; the final verdict on a plan is
still `planner.safety.check_plan`'s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from planner.safety import Conflict, cell_conflicts, closest_approach
from planner.trajectory import Trajectory
from planner.white_hole import importance


@dataclass
class ConflictTable:
    radii: Mapping[str, float]
    blocked: NDArray[np.bool_]
    paths: dict[str, Trajectory] = field(default_factory=dict)
    pairs: dict[frozenset[str], Conflict] = field(default_factory=dict)
    closest: dict[frozenset[str], float] = field(default_factory=dict)  # every pair
    cell_hits: dict[str, int] = field(default_factory=dict)

    @classmethod
    def build(
        cls,
        paths: Mapping[str, Trajectory],
        radii: Mapping[str, float],
        blocked: NDArray[np.bool_],
    ) -> ConflictTable:
        table = cls(radii, blocked)
        for uav, trajectory in paths.items():
            table.update(uav, trajectory)
        return table

    def update(self, uav: str, trajectory: Trajectory) -> None:
        """`uav` now flies `trajectory`: recompute its pairs and its cell hits."""
        self.paths[uav] = trajectory
        for other, track in self.paths.items():
            if other == uav:
                continue
            key = frozenset((uav, other))
            self.pairs.pop(key, None)
            need = self.radii[uav] + self.radii[other]
            dist, when = closest_approach(trajectory, track)
            self.closest[key] = dist
            if dist < need:
                mid = (trajectory.at([when])[0] + track.at([when])[0]) / 2
                where = (float(mid[0]), float(mid[1]))
                self.pairs[key] = Conflict("uav", (uav, other), when, where, dist, need)
        self.cell_hits[uav] = len(cell_conflicts(uav, trajectory, self.radii[uav], self.blocked))

    def comes_near(self, uav: str, slack: float, leave_out: str) -> bool:
        """Does `uav` come within the sum of the radii plus `slack` of any UAV but
        `leave_out`?"""
        return any(
            self.closest[frozenset((uav, other))] < self.radii[uav] + self.radii[other] + slack
            for other in self.paths
            if other not in (uav, leave_out)
        )

    def collision_paths(self, uav: str) -> list[Conflict]:
        return [c for key, c in self.pairs.items() if uav in key]

    def priority(self, uav: str) -> float:
        return importance(self.collision_paths(uav), self.paths[uav].end_time)

    def clear(self) -> bool:
        """No pair too close and no UAV inside a blocked cell."""
        return not self.pairs and not any(self.cell_hits.values())

    def troubled(self) -> list[str]:
        """UAVs in conflict with another or inside a blocked cell, highest priority (ImP)
        first; ties keep the fleet's order (the paper's UAV1 turns when priorities tie)."""
        involved = {u for key in self.pairs for u in key}
        trouble = [u for u in self.paths if u in involved or self.cell_hits[u]]
        return sorted(trouble, key=lambda u: -self.priority(u))

    def conflicts_without(self, uav: str) -> int:
        """Pairs in conflict that do not involve `uav`."""
        return sum(1 for key in self.pairs if uav not in key)
