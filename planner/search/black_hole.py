"""Exploitation (the black hole, eq. 8): one UAV searches a new path while the others hold theirs.

The optimizer (any of the six) minimises the chosen objective over the UAV's
encoding, against the other UAVs' fixed trajectories and the blocked cells. The
unchanged path is scored too, and a short polish afterwards straightens what the
search left bent (a waypoint that can go without raising the cost goes).

`wait_probe` is the quick alternative the anytime planner tries first: the UAV's
shortest path with one hover, at each base point in turn and of every length on a
grid, all scored in one vectorised call. When one of them is safe it gives a safe
path at once; the improvement phase then lets the optimizer make it shorter.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.geometry.clearance import ClearanceField, ExactClearance
from planner.geometry.path_encoding import DetourEncoding, TurnEncoding
from planner.model.trajectory import Trajectory, merge_collinear
from planner.optimizers import Algorithm, OptimizeResult, Progress, optimize
from planner.search.objectives import PathObjective
from planner.search.path_cost import PathTerms, Traffic, evaluate_paths

Array = NDArray[np.float64]
PROBE_BLOCK = 32  # candidates of a wait probe scored per call


@dataclass(frozen=True)
class Search:
    """What one replanning run needs besides the encoding."""

    speed: float
    radius: float
    goal: Array
    traffic: Traffic
    field: ClearanceField | ExactClearance
    objective: PathObjective

    def terms(self, waypoints: Array, waits: Array) -> PathTerms:
        return evaluate_paths(
            waypoints,
            waits,
            speed=self.speed,
            radius=self.radius,
            goal=self.goal,
            traffic=self.traffic,
            field=self.field,
        )

    def cost(self, waypoints: Array, waits: Array) -> Array:
        return self.objective.cost(self.terms(waypoints, waits))


@dataclass(frozen=True)
class Outcome:
    trajectory: Trajectory
    cost: float
    safe: bool  # by the search's own (sampled obstacle) terms; the plan is checked exactly
    result: OptimizeResult


def search_path(
    encoding: DetourEncoding | TurnEncoding,
    search: Search,
    *,
    algorithm: str | Algorithm,
    population: int,
    iterations: int,
    rng: np.random.Generator,
    on_iteration: Callable[[Progress], bool | None] | None = None,
) -> Outcome:
    lower, upper = encoding.bounds()

    def objective(genes: Array) -> Array:
        return search.cost(*encoding.decode(genes))

    result = optimize(
        algorithm,
        objective,
        lower,
        upper,
        population=population,
        iterations=iterations,
        rng=rng,
        callback=on_iteration,
    )
    waypoints, waits = encoding.decode(result.best_x[None])
    if isinstance(encoding, DetourEncoding):
        waypoints, waits = polish(waypoints, waits, search)
        unchanged = encoding.decode(encoding.unchanged()[None])
        waypoints, waits = _safest(search, (waypoints, waits), unchanged)
    if not waits.any():
        waypoints = merge_collinear(waypoints[0])[None]
        waits = np.zeros((1, waypoints.shape[1]))
    terms = search.terms(waypoints, waits)
    trajectory = Trajectory.from_waypoints(waypoints[0], search.speed, waits[0])
    return Outcome(trajectory, float(search.objective.cost(terms)[0]), bool(terms.safe[0]), result)


def _safest(search: Search, *candidates: tuple[Array, Array]) -> tuple[Array, Array]:
    """The cheapest candidate that keeps clear of blocked cells, else the cheapest."""

    def rank(candidate: tuple[Array, Array]) -> tuple[bool, float]:
        terms = search.terms(*candidate)
        return bool(terms.clearance_hits[0] > 0), float(search.objective.cost(terms)[0])

    return min(candidates, key=rank)


def polish(waypoints: Array, waits: Array, search: Search) -> tuple[Array, Array]:
    """Greedily drop interior waypoints and hovers while the cost does not rise."""
    best = float(search.cost(waypoints, waits)[0])
    while waypoints.shape[1] > 2:
        inner = waypoints.shape[1] - 2
        keep = ~np.eye(inner + 2, dtype=bool)[1:-1]  # row k drops waypoint k + 1
        trial_points = np.stack([waypoints[0][row] for row in keep])
        trial_waits = np.stack([waits[0][row] for row in keep])
        costs = np.where(waits[0, 1:-1] > 0, np.inf, search.cost(trial_points, trial_waits))
        k = int(np.argmin(costs))
        if costs[k] > best + 1e-9:
            break
        best, waypoints, waits = float(costs[k]), trial_points[k : k + 1], trial_waits[k : k + 1]
    return waypoints, waits


@dataclass(frozen=True)
class Probe:
    trajectory: Trajectory
    cost: float
    safe: bool
    evaluations: int


def wait_probe(encoding: DetourEncoding, search: Search, levels: int = 20) -> Probe:
    """The cheapest of: the base path unchanged, or with one hover of k/levels of the
    longest at one of its points (k = 1..levels)."""
    unchanged = encoding.unchanged()
    hovers = encoding.dim - 2 * len(encoding.base)  # one wait gene per point but the goal
    genes = np.repeat(unchanged[None], 1 + hovers * levels, axis=0)
    rows = np.arange(hovers * levels) + 1
    genes[rows, 2 * len(encoding.base) + (rows - 1) // levels] = ((rows - 1) % levels + 1) / levels
    waypoints, waits = encoding.decode(genes)
    # In blocks the size of a population: the terms of a block against dense traffic
    # take (rows x encounters) floats each, which all rows at once would multiply.
    costs, safe = np.empty(len(genes)), np.empty(len(genes), dtype=bool)
    for lo in range(0, len(genes), PROBE_BLOCK):
        block = slice(lo, lo + PROBE_BLOCK)
        terms = search.terms(waypoints[block], waits[block])
        costs[block], safe[block] = search.objective.cost(terms), terms.safe
    k = int(np.argmin(costs))
    points, hold = waypoints[k], waits[k]
    if not hold.any():
        points, hold = merge_collinear(points), np.zeros(len(merge_collinear(points)))
    trajectory = Trajectory.from_waypoints(points, search.speed, hold)
    return Probe(trajectory, float(costs[k]), bool(safe[k]), len(genes))
