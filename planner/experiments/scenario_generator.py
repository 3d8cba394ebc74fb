"""Generated scenarios: crossings through a centre, random traffic, swaps through a gap.

In a crossing, UAVs on a ring around the centre fly to the opposite side: every UAV's
straight line passes near the centre at about the same time, the hard case for a
multi-UAV planner; random obstacles and non-UAV objects clutter the grid. In a gap
swap, two groups on either side of a wall trade places through one narrow opening:
everyone must pass the same cells, one after another. A seed gives the same scenario
on any machine.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import ValidationError

from planner.model.scenario import Scenario, load_scenario

MAX_TRIES = 200


def crossing_scenario(
    seed: int,
    *,
    size: int = 20,
    uavs: int = 6,
    obstacle_share: float = 0.10,
    objects: int = 2,
) -> Scenario:
    """A valid scenario (every goal reachable); retries with the same generator until one is."""
    rng = np.random.default_rng(seed)
    for _ in range(MAX_TRIES):
        data = _draw(rng, size, uavs, obstacle_share, objects)
        try:
            return load_scenario({"name": f"crossing-{seed}", **data}, max_uavs=uavs)
        except ValidationError:
            continue
    raise RuntimeError(f"no valid crossing scenario for seed {seed} in {MAX_TRIES} tries")


def _draw(
    rng: np.random.Generator, size: int, uavs: int, obstacle_share: float, objects: int
) -> dict[str, Any]:
    centre = (size - 1) / 2
    radius = centre - 0.5
    angles = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(uavs) / uavs
    angles += rng.uniform(-0.15, 0.15, uavs)
    starts = [_on_ring(centre, radius, a, size) for a in angles]
    goals = [_on_ring(centre, radius, a + np.pi + rng.uniform(-0.2, 0.2), size) for a in angles]
    ends = set(starts) | set(goals)
    free = [(x, y) for x in range(size) for y in range(size) if (x, y) not in ends]
    picks = rng.permutation(len(free))
    n_obstacles = round(obstacle_share * size * size)
    obstacles = [free[i] for i in picks[:n_obstacles]]
    placed = [free[i] for i in picks[n_obstacles : n_obstacles + objects]]
    return {
        "grid": {"width": size, "height": size, "cell_size_m": 10.0},
        "uavs": [
            {"id": f"uav{k + 1}", "start": list(map(int, s)), "goal": list(map(int, g))}
            for k, (s, g) in enumerate(zip(starts, goals, strict=True))
        ],
        "obstacles": [list(map(int, c)) for c in obstacles],
        "non_uav_objects": [list(map(int, c)) for c in placed],
    }


def _on_ring(centre: float, radius: float, angle: float, size: int) -> tuple[int, int]:
    x, y = np.clip(np.rint(centre + radius * np.array([np.cos(angle), np.sin(angle)])), 0, size - 1)
    return int(x), int(y)


def random_scenario(
    seed: int,
    *,
    size: int = 50,
    uavs: int = 50,
    obstacle_share: float = 0.10,
    objects: int = 5,
    min_gap: float = 0.0,
) -> Scenario:
    """Starts and goals drawn on free cells (warehouse-style traffic, no common centre),
    each at least `min_gap` cells from every other start and goal, random obstacles and
    non-UAV objects; retries with the same generator until valid (every goal reachable)."""
    rng = np.random.default_rng(seed)
    for _ in range(MAX_TRIES):
        data = _draw_random(rng, size, uavs, obstacle_share, objects, min_gap)
        try:
            return load_scenario({"name": f"random-{seed}", **data}, max_uavs=uavs)
        except ValidationError:
            continue
    raise RuntimeError(f"no valid random scenario for seed {seed} in {MAX_TRIES} tries")


def _draw_random(
    rng: np.random.Generator,
    size: int,
    uavs: int,
    obstacle_share: float,
    objects: int,
    min_gap: float = 0.0,
) -> dict[str, Any]:
    cells = [(x, y) for x in range(size) for y in range(size)]
    picks = rng.permutation(len(cells))
    n_obstacles = round(obstacle_share * size * size)
    chosen = _spread(np.array(cells)[picks], 2 * uavs, min_gap)
    ends = [cells[picks[k]] for k in chosen]
    rest = np.delete(picks, chosen)
    obstacles = [cells[i] for i in rest[:n_obstacles]]
    placed = [cells[i] for i in rest[n_obstacles : n_obstacles + objects]]
    return {
        "grid": {"width": size, "height": size, "cell_size_m": 10.0},
        "uavs": [
            {
                "id": f"uav{k + 1}",
                "start": list(map(int, ends[2 * k])),
                "goal": list(map(int, ends[2 * k + 1])),
            }
            for k in range(uavs)
        ],
        "obstacles": [list(map(int, c)) for c in obstacles],
        "non_uav_objects": [list(map(int, c)) for c in placed],
    }


def _spread(candidates: np.ndarray, count: int, min_gap: float) -> list[int]:
    """Indices of the first `count` candidates (in order) that are each at least `min_gap`
    from every one taken before (all of the first `count` when the gap is 0)."""
    if min_gap <= 0:
        return list(range(min(count, len(candidates))))
    taken: list[int] = []
    for k, cell in enumerate(candidates):
        if len(taken) == count:
            break
        if not taken or np.min(np.hypot(*(candidates[taken] - cell).T)) >= min_gap:
            taken.append(k)
    return taken


def gap_swap_scenario(seed: int, *, size: int = 10, uavs: int = 6, gap: int = 2) -> Scenario:
    """A wall across the middle of the grid with a `gap`-cell opening at a random height;
    `uavs` UAVs (even), half on each side, each flying to a random cell on the other side,
    so that all of them pass the opening."""
    if uavs % 2 or uavs < 2:
        raise ValueError(f"a gap swap needs an even number of UAVs, got {uavs}")
    rng = np.random.default_rng(seed)
    wall = size // 2
    opening = int(rng.integers(1, size - gap))
    left = [(x, y) for x in range(wall - 1) for y in range(size)]
    right = [(x, y) for x in range(wall + 2, size) for y in range(size)]
    half = uavs // 2
    if 2 * uavs > min(len(left), len(right)):
        raise ValueError(f"a {size}x{size} grid has no room for {uavs} UAVs on two sides")
    sides = [rng.permutation(len(left))[: 2 * half], rng.permutation(len(right))[: 2 * half]]
    starts = [left[i] for i in sides[0][:half]] + [right[i] for i in sides[1][:half]]
    goals = [right[i] for i in sides[1][half:]] + [left[i] for i in sides[0][half:]]
    blocked = [(wall, y) for y in range(size) if not opening <= y < opening + gap]
    return load_scenario(
        {
            "name": f"gap-swap-{seed}",
            "grid": {"width": size, "height": size, "cell_size_m": 10.0},
            "uavs": [
                {"id": f"uav{k + 1}", "start": list(s), "goal": list(g)}
                for k, (s, g) in enumerate(zip(starts, goals, strict=True))
            ],
            "obstacles": [list(c) for c in blocked],
            "non_uav_objects": [],
        }
    )


def short_trips_scenario(
    seed: int,
    *,
    size: int = 60,
    uavs: int = 100,
    obstacle_share: float = 0.12,
    trip: int = 8,
    min_gap: float = 1.5,
) -> Scenario:
    """Dense short trips: starts spread over the grid (at least `min_gap` apart), each goal
    a free cell at most `trip` cells (Chebyshev) from its start and at least `min_gap` from
    every other start and goal; retries with the same generator until valid."""
    rng = np.random.default_rng(seed)
    for _ in range(MAX_TRIES):
        data = _draw_short(rng, size, uavs, obstacle_share, trip, min_gap)
        if data is None:
            continue
        try:
            return load_scenario({"name": f"short-trips-{seed}", **data}, max_uavs=uavs)
        except ValidationError:
            continue
    raise RuntimeError(f"no valid short-trips scenario for seed {seed} in {MAX_TRIES} tries")


def _draw_short(
    rng: np.random.Generator, size: int, uavs: int, obstacle_share: float, trip: int, gap: float
) -> dict[str, Any] | None:
    blocked = rng.random((size, size)) < obstacle_share
    free = np.argwhere(~blocked)
    order = free[rng.permutation(len(free))]
    ends: list[np.ndarray] = []
    starts: list[np.ndarray] = []
    goals: list[np.ndarray] = []
    for cell in order:
        if len(starts) == uavs:
            break
        if ends and np.min(np.hypot(*(np.array(ends) - cell).T)) < gap:
            continue
        lo, hi = np.maximum(cell - trip, 0), np.minimum(cell + trip, size - 1)
        box = np.argwhere(~blocked[lo[0] : hi[0] + 1, lo[1] : hi[1] + 1]) + lo
        box = box[rng.permutation(len(box))]
        taken = np.array([*ends, cell])
        for goal in box:
            if np.min(np.hypot(*(taken - goal).T)) >= gap:
                starts.append(cell)
                goals.append(goal)
                ends += [cell, goal]
                break
    if len(starts) < uavs:
        return None
    return {
        "grid": {"width": size, "height": size, "cell_size_m": 10.0},
        "uavs": [
            {"id": f"uav{k + 1}", "start": list(map(int, s)), "goal": list(map(int, g))}
            for k, (s, g) in enumerate(zip(starts, goals, strict=True))
        ],
        "obstacles": [list(map(int, c)) for c in np.argwhere(blocked)],
        "non_uav_objects": [],
    }
