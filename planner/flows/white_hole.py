"""Exploration (the white hole): who would collide with whom, when, and who replans first.

For the UAVs' current paths this finds the common path sets CPS(i, j) (the places
and times where two paths come closer than the sum of the radii, judged exactly in
continuous time), each UAV's collision paths PC_i, and the paper's metrics:

- UMR_i, eq. (3): the shortest distance from the UAV's position to its destination
  over its possible paths, in cells;
- OTP_i, eq. (4): UCP x WEP, the share of the other UAVs whose paths cross this one
  times the share of the non-UAV objects that lie on it;
- ImP_i, eq. (7): #PC_i / (t_c^i x T_i), more collision paths and an earlier
  collision first, where t_c^i is the time to the first collision and T_i the flight
  time. The UAV with the highest ImP replans first.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from planner.check.safety import Conflict, cell_conflicts, uav_conflicts
from planner.geometry.grid_search import cell_map
from planner.model.trajectory import Trajectory

Cell = tuple[int, int]
EARLIEST = 1e-3  # seconds; a collision at take-off still gets a finite priority


@dataclass(frozen=True)
class Exploration:
    conflicts: list[Conflict]  # the CPS(i, j) of every pair, one entry per pair
    collision_paths: dict[str, list[Conflict]]  # PC_i
    priority: dict[str, float]  # ImP_i, eq. (7)
    moving_rate: dict[str, float]  # UMR_i, eq. (3)
    threat: dict[str, float]  # OTP_i, eq. (4)
    min_separation: float


def importance(collision_paths: list[Conflict], flight_time: float) -> float:
    """ImP, eq. (7): #PC_i / (t_c x T_i); 0 for a UAV without collision paths."""
    if not collision_paths:
        return 0.0
    first = max(min(c.time for c in collision_paths), EARLIEST)
    return len(collision_paths) / (first * max(flight_time, EARLIEST))


def explore(
    trajectories: Mapping[str, Trajectory],
    radii: Mapping[str, float],
    shortest: Mapping[str, float],
    objects: Iterable[Cell],
    grid_shape: tuple[int, int],
) -> Exploration:
    conflicts, closest = uav_conflicts(trajectories, radii)
    collision_paths = {u: [c for c in conflicts if u in c.uavs] for u in trajectories}
    object_map = cell_map(objects, grid_shape)
    objects_total = int(object_map.sum())
    others = max(len(trajectories) - 1, 1)
    priority, threat = {}, {}
    for uav, trajectory in trajectories.items():
        pc = collision_paths[uav]
        priority[uav] = importance(pc, trajectory.end_time)
        on_path = len(cell_conflicts(uav, trajectory, radii[uav], object_map, "non_uav_object"))
        wep = on_path / objects_total if objects_total else 0.0
        threat[uav] = len(pc) / others * wep
    return Exploration(conflicts, collision_paths, priority, dict(shortest), threat, closest)
