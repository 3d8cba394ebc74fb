"""Each UAV's lone path, what the anytime flow anchors its searches on.

A UAV's shortest 8-connected grid path with the objects blocked (`routes`), its string
pulled and tightened round the corners it bends at (`shaped`, `planner.search.any_angle`):
the any-angle polyline the UAV alone would fly. The windows of it a search moves
(`hover_window`, `split`) are found here too.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.flows.budget import Budget
from planner.flows.planning import as_waypoints
from planner.geometry.clearance import distance_to_polyline
from planner.geometry.grid_search import GridGraph
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory, merge_collinear
from planner.search.any_angle import pull_strings, tighten_all

Array = NDArray[np.float64]
Route = list[tuple[int, int]]
WINDOW = 5.0  # cells of lone path searched on either side of where a UAV hovers
STORED_SHIFT = 1e-6  # cells: more than a stored plan's rounding (DIGITS) moves a point, so
# that a corner tightened until it just touches a blocked cell stays clear once rounded
AT_ONCE = 100  # UAVs shaped together: fewer would cost more numpy calls per path


def routes(
    scenario: Scenario, obstacles: NDArray[np.bool_], blocked: NDArray[np.bool_], limit: Budget
) -> tuple[dict[str, Route], dict[str, Route], dict[str, float]]:
    """Each UAV's shortest grid path with the objects blocked, its obstacle-only one (they
    differ for the UAVs an object touches: the ones the wormhole step, eq. 9, replans),
    and the first one's length; only the UAVs routed before `limit` (the safe start's
    hard limit, none by default) ran out.

    One bounded Dijkstra per UAV on the obstacle grid (`GridGraph.route`); a second only
    for a touched UAV. Where the objects wall a goal off, the obstacle-only path is kept
    (and the plan will say so).
    """
    plain = GridGraph.build(obstacles)
    with_objects = GridGraph.build(blocked) if (blocked != obstacles).any() else plain
    found, first, lengths = {}, {}, {}
    for u in scenario.uavs:
        if limit.expired():
            break
        length, cells = plain.route(u.start, u.goal)
        assert cells is not None, "the scenario's validation guarantees a path"
        first[u.id], lengths[u.id] = cells, length
        if with_objects is not plain and not valid(cells, blocked):
            around, detour = with_objects.route(u.start, u.goal)
            if detour is not None:
                cells, lengths[u.id] = detour, around
        found[u.id] = cells
    return found, first, lengths


def valid(cells: Route, blocked: NDArray[np.bool_]) -> bool:
    """No blocked cell on the path and no diagonal past one (the grid's own rule)."""
    xy = np.array(cells)
    if blocked[xy[:, 0], xy[:, 1]].any():
        return False
    a, b = xy[:-1], xy[1:]
    diagonal = (a[:, 0] != b[:, 0]) & (a[:, 1] != b[:, 1])
    side_1 = blocked[b[diagonal, 0], a[diagonal, 1]]
    side_2 = blocked[a[diagonal, 0], b[diagonal, 1]]
    return not (side_1.any() or side_2.any())


def shaped(
    scenario: Scenario, found: dict[str, Route], blocked: NDArray[np.bool_], limit: Budget
) -> dict[str, Array]:
    """The routes as polylines, pulled and tightened. Shortcuts and tightening only
    shorten them; `limit` is the safe start's hard limit (none by default): past it the
    rest of the fleet keeps its grid paths (as safe, a bit longer). The fleet is shaped
    AT_ONCE UAVs at a time (`pull_strings`, `tighten_all`: one numpy call for many paths),
    the limit read before each batch."""
    uavs = scenario.uavs
    geometry = {u.id: merge_collinear(np.array(found[u.id], dtype=float)) for u in uavs}
    for first in range(0, len(uavs), AT_ONCE):
        if limit.expired():
            break
        batch = uavs[first : first + AT_ONCE]
        pulled = pull_strings([geometry[u.id] for u in batch], [u.radius for u in batch], blocked)
        clearances = [u.radius + STORED_SHIFT for u in batch]
        for u, cells in zip(batch, tighten_all(pulled, clearances, blocked), strict=True):
            geometry[u.id] = cells
    return geometry


def hover_window(trajectory: Trajectory, lone: Array) -> tuple[float, float] | None:
    """The stretch of the lone path (arc lengths) within WINDOW cells of the points where
    `trajectory` hovers, or None (no hover, or a flight that left its lone path)."""
    waypoints, waits = as_waypoints(trajectory)
    if not waits.any() or distance_to_polyline(waypoints, lone).max() > 1e-6:
        return None
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(lone, axis=0).T))])
    hovering = waypoints[waits > 0]
    at = [arc_position(p, lone, along) for p in hovering]
    return max(min(at) - WINDOW, 0.0), min(max(at) + WINDOW, float(along[-1]))


def arc_position(point: Array, polyline: Array, along: Array) -> float:
    """Arc length along `polyline` of its point nearest to `point`."""
    a, b = polyline[:-1], polyline[1:]
    d = b - a
    length2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    u = np.clip(np.einsum("ij,ij->i", point - a, d) / length2, 0.0, 1.0)
    gap = np.hypot(*(a + u[:, None] * d - point).T)
    k = int(np.argmin(gap))
    return float(along[k] + u[k] * np.sqrt(length2[k]))


def split(polyline: Array, s0: float, s1: float) -> tuple[Array | None, Array, Array | None]:
    """The polyline before arc length s0, between s0 and s1, and after s1 (None: empty)."""
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(polyline, axis=0).T))])

    def at(s: float) -> Array:
        return np.array([np.interp(s, along, polyline[:, 0]), np.interp(s, along, polyline[:, 1])])

    inside = polyline[(along > s0) & (along < s1)]
    inner = np.vstack([at(s0), inside, at(s1)])
    before = np.vstack([polyline[along < s0], at(s0)]) if s0 > 0 else None
    after = np.vstack([at(s1), polyline[along > s1]]) if s1 < along[-1] else None
    return before, inner, after


def geometry_of(trajectory: Trajectory) -> Array:
    """A flight's polyline without its hovers."""
    waypoints, _ = as_waypoints(trajectory)
    return merge_collinear(waypoints)
