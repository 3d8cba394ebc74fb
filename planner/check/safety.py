"""The safety check every plan must pass, exact in continuous time.

Two UAVs conflict when their centres are ever closer than the sum of their radii
while both are airborne; a UAV conflicts with a blocked cell (obstacle or non-UAV
object) when its disc enters the cell's unit square. Trajectories are piecewise
linear, so on every interval between breakpoints the distance has a closed-form
minimum: nothing is sampled, nothing is missed.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from planner.geometry.clearance import SQUARE_REACH
from planner.geometry.grid_search import cell_map
from planner.geometry.squares import pairs_square_distance
from planner.model.trajectory import Trajectory

Cell = tuple[int, int]
ConflictKind = Literal["uav", "obstacle", "non_uav_object"]


@dataclass(frozen=True)
class Conflict:
    """Where and when a plan is unsafe."""

    kind: ConflictKind
    uavs: tuple[str, ...]
    time: float
    position: tuple[float, float]
    separation: float  # centre to centre, or centre to the cell's square
    required: float  # sum of the radii, or the radius
    cell: Cell | None = None

    def describe(self) -> str:
        where = f"({self.position[0]:.2f}, {self.position[1]:.2f})"
        if self.kind == "uav":
            who = " and ".join(self.uavs)
            return (
                f"{who} come {self.separation:.3f} cells apart (need {self.required:.3f}) "
                f"at t = {self.time:.2f} s near {where}"
            )
        what = "an obstacle" if self.kind == "obstacle" else "a non-UAV object"
        return (
            f"{self.uavs[0]} enters {what} at cell {self.cell} at t = {self.time:.2f} s "
            f"near {where} (clearance {self.separation:.3f}, radius {self.required:.3f})"
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "uavs": list(self.uavs),
            "time": round(self.time, 4),
            "position": [round(self.position[0], 4), round(self.position[1], 4)],
            "separation": round(self.separation, 4),
            "required": round(self.required, 4),
            "cell": list(self.cell) if self.cell else None,
            "message": self.describe(),
        }


def _timed_gaps(
    flights: Sequence[Trajectory],
    first: NDArray[np.intp],
    second: NDArray[np.intp],
    windows: int = 16,
) -> NDArray[np.float64]:
    """A lower bound on each pair's distance while both are airborne, tighter than their
    whole boxes' gap: the least gap between their boxes over the same time window (two
    long flights' boxes overlap, their windows' boxes seldom do). A margin keeps it
    below the distance `closest_approach` computes, so skipping by it changes nothing."""
    edges = np.linspace(0.0, max(f.end_time for f in flights), windows + 1)
    boxes = np.array([_window_boxes(f, edges) for f in flights])  # (n, windows, 4)
    a, b = boxes[first], boxes[second]
    dx = np.maximum(0.0, np.maximum(b[..., 0] - a[..., 2], a[..., 0] - b[..., 2]))
    dy = np.maximum(0.0, np.maximum(b[..., 1] - a[..., 3], a[..., 1] - b[..., 3]))
    least: NDArray[np.float64] = np.hypot(dx, dy).min(axis=1) - 1e-9
    return least


def _window_boxes(flight: Trajectory, edges: NDArray[np.float64]) -> NDArray[np.float64]:
    """Box (x lo, y lo, x hi, y hi) of the flight's positions in each time window, an
    empty one (inf, inf, -inf, -inf) where it is not airborne."""
    inf = float("inf")
    boxes = np.tile([inf, inf, -inf, -inf], (len(edges) - 1, 1))
    for k in range(len(edges) - 1):
        part = flight.between(float(edges[k]), float(edges[k + 1]))
        if part is not None:
            boxes[k, :2], boxes[k, 2:] = part.xy.min(axis=0), part.xy.max(axis=0)
    return boxes


def closest_approach(a: Trajectory, b: Trajectory) -> tuple[float, float]:
    """Smallest centre distance while both are airborne, and when it happens.

    The conflict table calls this for every near pair after every change of a flight
    (hundreds of times per plan on arrays of a few breakpoints), so it works on the x
    and y columns apart, in as few numpy calls as the arithmetic allows: the same
    operations, element by element, as on the stacked (n, 2) positions."""
    if a.times[0] > 0.0 or b.times[0] > 0.0:  # one takes off late: NaN before, as `at` says
        return _closest_approach_late(a, b)
    end = min(a.end_time, b.end_time)
    times = np.concatenate((a.times, b.times, (0.0, end)))
    times = np.unique(times[(times >= 0) & (times <= end)])
    pa, pb = a.points, b.points
    gx = np.interp(times, a.times, pa[:, 1]) - np.interp(times, b.times, pb[:, 1])
    gy = np.interp(times, a.times, pa[:, 2]) - np.interp(times, b.times, pb[:, 2])
    if len(times) == 1:
        return float(np.hypot(gx[0], gy[0])), float(times[0])
    sx, sy = gx[:-1], gy[:-1]
    cx, cy = gx[1:] - sx, gy[1:] - sy
    speed2 = cx * cx + cy * cy
    moving = speed2 > 0
    tau = np.divide(-(sx * cx + sy * cy), speed2, out=np.zeros(len(speed2)), where=moving)
    tau = np.minimum(np.maximum(tau, 0.0), 1.0)
    dist = np.hypot(sx + tau * cx, sy + tau * cy)
    k = int(np.argmin(dist))
    return float(dist[k]), float(times[k] + tau[k] * (times[k + 1] - times[k]))


def _closest_approach_late(a: Trajectory, b: Trajectory) -> tuple[float, float]:
    """`closest_approach` on the stacked positions, for flights that do not both take off
    at t = 0 (positions before take-off are NaN)."""
    end = min(a.end_time, b.end_time)
    times = np.unique(np.concatenate([a.times, b.times, [0.0, end]]))
    times = times[(times >= 0) & (times <= end)]
    gap = a.at(times) - b.at(times)
    if len(times) == 1:
        return float(np.hypot(*gap[0])), float(times[0])
    start, change = gap[:-1], np.diff(gap, axis=0)
    speed2 = np.einsum("ij,ij->i", change, change)
    with np.errstate(invalid="ignore", divide="ignore"):
        tau = np.where(speed2 > 0, -np.einsum("ij,ij->i", start, change) / speed2, 0.0)
    tau = np.clip(tau, 0.0, 1.0)
    dist = np.hypot(*(start + tau[:, None] * change).T)
    k = int(np.argmin(dist))
    return float(dist[k]), float(times[k] + tau[k] * (times[k + 1] - times[k]))


def uav_conflicts(
    trajectories: Mapping[str, Trajectory], radii: Mapping[str, float]
) -> tuple[list[Conflict], float]:
    """One conflict per pair of UAVs that ever come closer than the sum of their radii,
    and the smallest separation of any pair (inf for a single UAV).

    Pairs are measured in order of the gap between their bounding boxes, a lower bound
    on their distance: once that gap is at least the closest separation found and the
    pair's sum of radii, no later pair can change the answer. The result is the one
    an all-pairs pass gives, in the same order.
    """
    ids: Sequence[str] = list(trajectories)
    n = len(ids)
    if n < 2:
        return [], float("inf")
    boxes = np.array(
        [np.concatenate([t.xy.min(axis=0), t.xy.max(axis=0)]) for t in trajectories.values()]
    )
    first, second = np.triu_indices(n, 1)
    dx = np.maximum(
        0.0, np.maximum(boxes[second, 0] - boxes[first, 2], boxes[first, 0] - boxes[second, 2])
    )
    dy = np.maximum(
        0.0, np.maximum(boxes[second, 1] - boxes[first, 3], boxes[first, 1] - boxes[second, 3])
    )
    gaps = np.hypot(dx, dy)
    bound = np.maximum(gaps, _timed_gaps(list(trajectories.values()), first, second))
    radius = np.array([radii[u] for u in ids])
    need = radius[first] + radius[second]
    found: dict[tuple[int, int], Conflict] = {}
    closest = float("inf")
    for k in np.argsort(gaps, kind="stable"):
        if gaps[k] >= closest and gaps[k] >= need.max():
            break
        if bound[k] >= closest and bound[k] >= need[k]:
            continue
        i, j = int(first[k]), int(second[k])
        a, b = ids[i], ids[j]
        dist, when = closest_approach(trajectories[a], trajectories[b])
        closest = min(closest, dist)
        if dist < need[k]:
            mid = (trajectories[a].at([when])[0] + trajectories[b].at([when])[0]) / 2
            found[i, j] = Conflict(
                "uav", (a, b), when, (float(mid[0]), float(mid[1])), dist, float(need[k])
            )
    return [found[key] for key in sorted(found)], closest


def cell_conflicts(
    uav: str,
    trajectory: Trajectory,
    radius: float,
    blocked: NDArray[np.bool_],
    kind: ConflictKind = "obstacle",
) -> list[Conflict]:
    """Every blocked cell (indexed [x, y]) whose square the UAV's disc enters.

    All legs at once: every blocked cell near the flight's bounding box is paired with
    every leg whose widened box holds it, and the pairs are measured in one vectorised
    pass; a cell's conflict is its closest approach over the legs (the earliest leg on
    a tie), the cells in order of the leg that first comes near them, then x, then y."""
    pts, ts = trajectory.xy, trajectory.times
    if len(pts) == 1:
        k0 = k1 = np.zeros(1, dtype=np.intp)
    else:
        # A hover after a leg stays where the leg ended: nothing the leg did not see.
        moved = np.any(pts[1:] != pts[:-1], axis=1)
        moved[0] = True
        k0 = np.flatnonzero(moved)
        k1 = k0 + 1
    reach = radius + 0.5
    a, b = pts[k0], pts[k1]
    lo = np.maximum(np.floor(np.minimum(a, b) - reach).astype(int), 0)
    hi = np.minimum(np.ceil(np.maximum(a, b) + reach).astype(int), np.array(blocked.shape) - 1)
    box_lo, box_hi = lo.min(axis=0), hi.max(axis=0)
    if np.any(box_lo > box_hi):
        return []
    window = blocked[box_lo[0] : box_hi[0] + 1, box_lo[1] : box_hi[1] + 1]
    cells = np.argwhere(window) + box_lo  # in x, then y order
    if not len(cells):
        return []
    inside = (
        (cells[None, :, 0] >= lo[:, None, 0])
        & (cells[None, :, 0] <= hi[:, None, 0])
        & (cells[None, :, 1] >= lo[:, None, 1])
        & (cells[None, :, 1] <= hi[:, None, 1])
    )
    leg, cell = np.nonzero(inside)  # pairs by leg, then by the cell's order
    leg, cell = _centre_near(a, b, cells, leg, cell, radius)
    if not len(leg):
        return []
    dist, tau = pairs_square_distance(a[leg], b[leg], cells[cell])
    close = np.flatnonzero(dist < radius)
    hits: dict[Cell, Conflict] = {}
    for k in close.tolist():
        key = (int(cells[cell[k], 0]), int(cells[cell[k], 1]))
        d = float(dist[k])
        if key in hits and not d < hits[key].separation:
            continue
        s0, s1, u = int(k0[leg[k]]), int(k1[leg[k]]), tau[k]
        where = pts[s0] + u * (pts[s1] - pts[s0])
        when = ts[s0] + u * (ts[s1] - ts[s0])
        hits[key] = Conflict(
            kind, (uav,), float(when), (float(where[0]), float(where[1])), d, radius, key
        )
    return list(hits.values())


def _centre_near(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    cells: NDArray[np.intp],
    leg: NDArray[np.intp],
    cell: NDArray[np.intp],
    radius: float,
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The (leg, cell) pairs whose cell centre comes within the radius plus the square's
    reach (its corners' distance, with a margin for rounding) of the leg: no other square
    can come within the radius. A leg's box holds a band of cells many times wider than
    that, and the exact square distance costs some sixty numpy calls per batch, so the
    pairs it measures are first thinned by this one projection."""
    if not len(leg):
        return leg, cell
    p0, centre = a[leg], cells[cell]
    d = b[leg] - p0
    rel = centre - p0
    length2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]
    along = rel[:, 0] * d[:, 0] + rel[:, 1] * d[:, 1]
    u = np.divide(along, length2, out=np.zeros(len(leg)), where=length2 > 0)
    u = np.minimum(np.maximum(u, 0.0), 1.0)
    gx, gy = rel[:, 0] - u * d[:, 0], rel[:, 1] - u * d[:, 1]
    near = gx * gx + gy * gy <= (radius + SQUARE_REACH + 1e-6) ** 2
    return leg[near], cell[near]


@dataclass(frozen=True)
class SafetyReport:
    conflicts: list[Conflict]
    min_separation: float  # smallest centre-to-centre distance between UAVs (inf for one UAV)

    @property
    def safe(self) -> bool:
        return not self.conflicts


def check_plan(
    trajectories: Mapping[str, Trajectory],
    radii: Mapping[str, float],
    obstacles: NDArray[np.bool_],
    objects: Iterable[Cell] = (),
) -> SafetyReport:
    """Every conflict of the plan: UAV pairs, obstacle cells and non-UAV objects."""
    conflicts, closest = uav_conflicts(trajectories, radii)
    object_map = cell_map(objects, obstacles.shape)
    for uav, trajectory in trajectories.items():
        conflicts += cell_conflicts(uav, trajectory, radii[uav], obstacles, "obstacle")
        conflicts += cell_conflicts(uav, trajectory, radii[uav], object_map, "non_uav_object")
    return SafetyReport(conflicts, closest)
