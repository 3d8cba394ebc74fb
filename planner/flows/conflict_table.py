"""Who is in conflict with whom, kept up to date one UAV at a time.

Algorithm 1 replans one UAV at a time, so after a replan only that UAV's pairs can
have changed. The table keeps every pair's closest approach (from the exact
`planner.check.safety.closest_approach`) and every UAV's blocked-cell hits, and recomputes
one row when a path changes: n - 1 pairs instead of n (n - 1) / 2, and of those only
the pairs whose bounding boxes come within `NEAR` cells of the sum of the radii (two
flights whose boxes are further apart can never be closer) and whose positions sampled
every `SAMPLE_S` seconds, less what they can fly in half of that, come as near (a lower
bound on their distance, computed for all of them in one numpy pass). That is what
makes fleets of hundreds affordable. Its numbers are the exact check's own, so the
priorities it gives (eq. 7) equal the white hole's; the final verdict on a plan is
still `planner.check.safety.check_plan`'s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from planner.check.safety import Conflict, cell_conflicts, closest_approach
from planner.flows.white_hole import importance
from planner.model.trajectory import Trajectory

NEAR = 0.5  # cells beyond the radii within which a pair's exact closest approach is kept
SAMPLE_S = 1.0  # seconds between the sampled positions that bound a pair from below


def _held(samples: NDArray[np.float64], count: int) -> NDArray[np.float64]:
    """The first `count` samples, the last one repeated where there are fewer."""
    if len(samples) >= count:
        return samples[:count]
    return np.concatenate([samples, np.repeat(samples[-1:], count - len(samples), axis=0)])


@dataclass
class ConflictTable:
    radii: Mapping[str, float]
    blocked: NDArray[np.bool_]
    paths: dict[str, Trajectory] = field(default_factory=dict)
    pairs: dict[frozenset[str], Conflict] = field(default_factory=dict)
    closest: dict[frozenset[str], float] = field(default_factory=dict)  # every pair
    cell_hits: dict[str, int] = field(default_factory=dict)
    boxes: dict[str, NDArray[np.float64]] = field(default_factory=dict)  # (4,) x0 y0 x1 y1
    samples: dict[str, NDArray[np.float64]] = field(default_factory=dict)  # every SAMPLE_S
    speeds: dict[str, float] = field(default_factory=dict)  # each flight's fastest

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

    def update(self, uav: str, trajectory: Trajectory, cell_hits: int | None = None) -> None:
        """`uav` now flies `trajectory`: recompute its pairs and its cell hits, unless the
        caller has just counted those against this table's map (`cell_hits`: the safe
        start's and the improvement's changes are tested for blocked cells before they are
        made, and the count costs as much as the pairs)."""
        self.paths[uav] = trajectory
        xy = trajectory.xy
        self.boxes[uav] = np.concatenate([xy.min(axis=0), xy.max(axis=0)])
        self._sample(uav, trajectory)
        others = [u for u in self.paths if u != uav]
        gaps = self._box_gaps(uav, others)
        needs = np.array([self.radii[uav] + self.radii[o] for o in others])
        boxed = np.flatnonzero(gaps < needs + NEAR)
        gaps[boxed] = self._sampled_gaps(uav, [others[k] for k in boxed])
        for other, gap in zip(others, gaps, strict=True):
            key = frozenset((uav, other))
            self.pairs.pop(key, None)
            need = self.radii[uav] + self.radii[other]
            if gap >= need + NEAR:
                self.closest[key] = float(gap)  # a lower bound, and far enough
                continue
            dist, when = closest_approach(trajectory, self.paths[other])
            self.closest[key] = dist
            if dist < need:
                mid = (trajectory.at([when])[0] + self.paths[other].at([when])[0]) / 2
                where = (float(mid[0]), float(mid[1]))
                self.pairs[key] = Conflict("uav", (uav, other), when, where, dist, need)
        if cell_hits is None:
            cell_hits = len(cell_conflicts(uav, trajectory, self.radii[uav], self.blocked))
        self.cell_hits[uav] = cell_hits

    def on_map(self, blocked: NDArray[np.bool_]) -> None:
        """The blocked cells changed (the wormhole step): recount the cell hits only,
        since the pairs do not depend on the map."""
        self.blocked = blocked
        for uav, trajectory in self.paths.items():
            self.cell_hits[uav] = len(cell_conflicts(uav, trajectory, self.radii[uav], blocked))

    def _sample(self, uav: str, trajectory: Trajectory) -> None:
        """`uav`'s positions every SAMPLE_S seconds (held at its goal after it lands) and
        its fastest speed: what `_sampled_gaps` bounds pairs with."""
        count = int(np.ceil(trajectory.end_time / SAMPLE_S)) + 1
        times = np.minimum(np.arange(count) * SAMPLE_S, trajectory.end_time)
        self.samples[uav] = trajectory.at(times)
        self.speeds[uav] = trajectory.max_speed()

    def _sampled_gaps(self, uav: str, others: list[str]) -> NDArray[np.float64]:
        """A lower bound on the distance between `uav` and each of `others` while both
        fly: at any moment t both are within speed x SAMPLE_S / 2 of where they were at
        the sample time nearest t (or at landing, if that came first), so the smallest
        sampled distance less (v_a + v_b) SAMPLE_S / 2 is never more than the truth. The
        samples span `uav`'s whole flight, and so every moment both fly."""
        if not others:
            return np.zeros(0)
        mine = self.samples[uav]
        count = len(mine)
        theirs = np.stack([_held(self.samples[o], count) for o in others])
        gap = np.hypot(theirs[..., 0] - mine[:, 0], theirs[..., 1] - mine[:, 1]).min(axis=1)
        speeds = np.array([self.speeds[o] for o in others]) + self.speeds[uav]
        bound: NDArray[np.float64] = np.maximum(gap - speeds * SAMPLE_S / 2 - 1e-9, 0.0)
        return bound

    def _box_gaps(self, uav: str, others: list[str]) -> NDArray[np.float64]:
        """Distance between `uav`'s bounding box and each of the others'."""
        if not others:
            return np.zeros(0)
        mine = self.boxes[uav]
        theirs = np.array([self.boxes[u] for u in others])
        dx = np.maximum(0.0, np.maximum(theirs[:, 0] - mine[2], mine[0] - theirs[:, 2]))
        dy = np.maximum(0.0, np.maximum(theirs[:, 1] - mine[3], mine[1] - theirs[:, 3]))
        gaps: NDArray[np.float64] = np.hypot(dx, dy)
        return gaps

    def comes_near(self, uav: str, slack: float, leave_out: str) -> bool:
        """Does `uav` come within the sum of the radii plus `slack` (at most `NEAR`) of
        any UAV but `leave_out`?"""
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
