"""One touched UAV's search in flight (the black hole, eq. 8, from where it is).

Routes from the UAV's exact position to its goal round the objects (and, second, round
the cells the others will still fly through), searched with the detour encoding against
everyone else's remaining flight held fixed and the timed objects as discs; kept only if
the exact check clears it. `planner.live.replan` calls it for each touched UAV in turn.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from planner.check.safety import Conflict, cell_conflicts, uav_conflicts
from planner.flows.planning import ATTEMPTS, PlannerSettings
from planner.geometry.grid_search import GridGraph, cell_map, descend
from planner.geometry.path_encoding import DetourEncoding
from planner.live.objects import Blocking
from planner.model.scenario import Scenario, UAVSpec
from planner.model.trajectory import Trajectory, merge_collinear
from planner.search.black_hole import Search, search_path
from planner.search.objectives import QosObjective
from planner.search.path_cost import Traffic

Array = NDArray[np.float64]
Cell = tuple[int, int]


def replan_one(
    spec: UAVSpec,
    position: Array,
    fixed: Mapping[str, Trajectory],
    specs: Mapping[str, UAVSpec],
    blocking: Blocking,
    scenario: Scenario,
    settings: PlannerSettings,
    rng: np.random.Generator,
) -> tuple[Trajectory | None, list[Conflict]]:
    """A new path that the exact check clears against everything held fixed (eq. 8), or
    None and what the last attempt ran into (nothing if there is no route at all).

    The searches alternate between two routes: the shortest way round the objects, and
    the shortest that also keeps off the cells the others will still fly through (the
    detour encoding bends a route by 1.5 cells at most). Each attempt continues the same
    generator. The last resort hovers where the UAV is until the others have landed and
    the timed objects have gone, then flies the first route."""
    routes = _routes(spec, position, fixed, specs, blocking)
    if not routes:
        return None, []
    horizon = max((t.end_time for t in fixed.values()), default=1.0)
    last: list[Conflict] = []
    for attempt in range(ATTEMPTS):
        encoding = DetourEncoding.around(
            routes[attempt % len(routes)], max_wait=blocking.max_wait(horizon)
        )
        outcome = search_path(
            encoding,
            _search(spec, position, encoding, fixed, specs, blocking, scenario),
            algorithm=settings.algorithm,
            population=settings.population,
            iterations=settings.iterations,
            rng=rng,
        )
        last = _own_conflicts(spec, outcome.trajectory, fixed, specs, blocking)
        if not last:
            return outcome.trajectory, []
    ends = [horizon] + [b for _, _, b in blocking.timed if math.isfinite(b)]
    corners = merge_collinear(routes[0])
    waits = np.zeros(len(corners))
    waits[0] = max(ends) + 0.1
    patient = Trajectory.from_waypoints(corners, spec.speed, waits)
    if not _own_conflicts(spec, patient, fixed, specs, blocking):
        return patient, []
    return None, last


def _routes(
    spec: UAVSpec,
    position: Array,
    fixed: Mapping[str, Trajectory],
    specs: Mapping[str, UAVSpec],
    blocking: Blocking,
) -> list[Array]:
    """The routes to search around (see replan_one), the shortest first."""
    static = blocking.obstacles | blocking.objects
    timed = cell_map([c for c, _, _ in blocking.timed], static.shape)
    everywhere = np.ones_like(static)
    swept = cell_map(
        [
            c.cell
            for u, t in fixed.items()
            for c in cell_conflicts(u, t, specs[u].radius, everywhere)
            if c.cell is not None  # always set for a cell conflict
        ],
        static.shape,
    )
    # Timed objects are walked round if possible; the search may still cross their cells
    # when they are not there, and a UAV may wait for one on its goal to go.
    timed[spec.goal] = swept[spec.goal] = False
    first = _route(position, spec.goal, spec.radius, static | timed)
    if first is None:
        first = _route(position, spec.goal, spec.radius, static)
    if first is None:
        return []
    clear = _route(position, spec.goal, spec.radius, static | timed | swept)
    if clear is None or (len(clear) == len(first) and np.allclose(clear, first)):
        return [first]
    return [first, clear]


def _route(position: Array, goal: Cell, radius: float, blocked: NDArray[np.bool_]) -> Array | None:
    """The exact position, then the shortest grid path to the goal from the neighbouring
    cell that makes the whole way shortest (None if no neighbour leads there)."""
    distance = GridGraph.build(blocked).distances_to(goal)
    start = _entry_cell(position, radius, distance, blocked)
    if start is None:
        return None
    path = np.array(descend(distance, start, blocked), dtype=float)
    if np.allclose(path[0], position):
        return path
    return np.vstack([position, path])


def _entry_cell(
    position: Array, radius: float, distance: Array, blocked: NDArray[np.bool_]
) -> Cell | None:
    """Of the free cells around `position`, the one with the shortest way to the goal,
    preferring those the UAV reaches in a straight line without touching a blocked cell
    (the first leg is the one leg the search cannot bend)."""
    centre = np.rint(position).astype(int)
    offsets = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)])
    cells = centre + offsets
    cells = cells[np.all((cells >= 0) & (cells < distance.shape), axis=1)]
    cells = cells[~blocked[cells[:, 0], cells[:, 1]]]
    total = np.hypot(*(cells - position).T) + distance[cells[:, 0], cells[:, 1]]
    leads_there = np.isfinite(total)  # a straight way into a pocket cut off is no way
    if not leads_there.any():
        return None
    cells, total = cells[leads_there], total[leads_there]
    grazes = [
        bool(cell_conflicts("", Trajectory(np.array([[0, *position], [1, *c]])), radius, blocked))
        for c in cells
    ]
    x, y = cells[np.lexsort((total, grazes))[0]]
    return int(x), int(y)


def _search(
    spec: UAVSpec,
    position: Array,
    encoding: DetourEncoding,
    fixed: Mapping[str, Trajectory],
    specs: Mapping[str, UAVSpec],
    blocking: Blocking,
    scenario: Scenario,
) -> Search:
    """The cost of `spec`'s candidates against the fixed flights and the timed objects."""
    others = [(t, specs[u].radius, specs[u].speed) for u, t in fixed.items()]
    others += blocking.discs(_longest_flight(encoding, spec.speed))
    lower, upper = encoding.region()
    traffic = Traffic.around(
        others, radius=spec.radius, speed=spec.speed, start=position, lower=lower, upper=upper
    )
    penalty = 100.0 * (scenario.grid.width + scenario.grid.height + 10)
    goal = np.array(spec.goal, dtype=float)
    return Search(
        spec.speed, spec.radius, goal, traffic, blocking.field, QosObjective(spec.speed, penalty)
    )


def _longest_flight(encoding: DetourEncoding, speed: float) -> float:
    """A bound on the flight time of any path the encoding can produce."""
    points = np.vstack([encoding.start, encoding.base, encoding.goal])
    legs = len(points) - 1
    length = (
        np.hypot(*np.diff(points, axis=0).T).sum() + legs * 2 * math.sqrt(2) * encoding.max_offset
    )
    return float(length / speed + legs * encoding.max_wait + 1.0)


def _own_conflicts(
    spec: UAVSpec,
    trajectory: Trajectory,
    fixed: Mapping[str, Trajectory],
    specs: Mapping[str, UAVSpec],
    blocking: Blocking,
) -> list[Conflict]:
    """The exact check for one new flight against everything held fixed."""
    found = blocking.cell_conflicts(spec.id, trajectory, spec.radius)
    for other, track in fixed.items():
        radii = {spec.id: spec.radius, other: specs[other].radius}
        found += uav_conflicts({spec.id: trajectory, other: track}, radii)[0]
    return found
