"""Cost terms of many candidate paths for one UAV at once: the planner's hot path.

A candidate is a polyline of waypoints with a hover time at each. Every term is
computed for the whole population in numpy: separation from the other UAVs is
exact (closest approach on every interval where both move linearly), clearance
from blocked cells is read from a fine distance raster with a margin, and the
final plan is still judged by the exact check in `planner.safety`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.clearance import ClearanceField
from planner.trajectory import Trajectory

Array = NDArray[np.float64]
SPACING = 0.1  # cells between clearance samples along a path


@dataclass(frozen=True)
class Traffic:
    """The other UAVs, fixed: breakpoints padded to a common length so they stack."""

    times: Array  # (U, B), non-decreasing per row
    positions: Array  # (U, B, 2)
    radii: Array  # (U,)

    @classmethod
    def of(cls, trajectories: list[Trajectory], radii: list[float]) -> Traffic:
        if not trajectories:
            return cls(np.zeros((0, 1)), np.zeros((0, 1, 2)), np.zeros(0))
        width = max(len(t.points) for t in trajectories)
        padded = [
            np.vstack([t.points, np.repeat(t.points[-1:], width - len(t.points), 0)])
            for t in trajectories
        ]
        stack = np.stack(padded)
        return cls(stack[:, :, 0], stack[:, :, 1:], np.asarray(radii, dtype=float))

    @property
    def end_times(self) -> Array:
        return self.times[:, -1]


@dataclass(frozen=True)
class PathTerms:
    """Per candidate: what the objectives weigh."""

    length: Array
    waiting: Array
    end_time: Array
    deviation: Array  # distance of the last waypoint from the goal
    separation_deficit: Array  # Σ over intervals of (needed - closest) x duration, UAVs
    separation_hits: Array  # intervals where two UAVs come too close
    clearance_deficit: Array  # Σ over samples of (needed - clearance) x spacing, obstacles
    clearance_hits: Array  # samples inside an obstacle's reach

    @property
    def safe(self) -> NDArray[np.bool_]:
        return (self.separation_hits == 0) & (self.clearance_hits == 0)


def timeline(waypoints: Array, waits: Array, speed: float) -> tuple[Array, Array]:
    """Breakpoint times (N, 2P) and positions (N, 2P, 2): arrive, hover, leave each waypoint."""
    legs = np.hypot(*np.moveaxis(np.diff(waypoints, axis=1), -1, 0)) / speed  # (N, P-1)
    n, p = waits.shape
    steps = np.zeros((n, 2 * p))
    steps[:, 1::2] = waits
    steps[:, 2::2] = legs
    return np.cumsum(steps, axis=1), np.repeat(waypoints, 2, axis=1)


def batched_interp(queries: Array, knots: Array, values: Array) -> Array:
    """Row-wise piecewise-linear interpolation: row r of `queries` (R, Q) on knots (R, K)
    with values (R, K, D), clamped at both ends. Knots may repeat (a hover)."""
    rows, k = knots.shape
    span = max(float(knots.max()), float(queries.max()), 0.0) + 1.0
    offset = (np.arange(rows) * span)[:, None]
    idx = np.searchsorted((knots + offset).ravel(), (queries + offset).ravel(), side="right")
    base = np.repeat(np.arange(rows) * k, queries.shape[1])
    right = base + np.clip(idx - base, 1, k - 1)
    flat_t, flat_v = knots.ravel(), values.reshape(rows * k, -1)
    t0, t1 = flat_t[right - 1], flat_t[right]
    span_t = t1 - t0
    frac = np.divide(queries.ravel() - t0, span_t, out=np.ones_like(span_t), where=span_t > 0)
    np.clip(frac, 0.0, 1.0, out=frac)
    v0 = flat_v[right - 1]
    out = v0 + frac[:, None] * (flat_v[right] - v0)
    return out.reshape(*queries.shape, -1)


def separation_terms(
    times: Array, positions: Array, radius: float, traffic: Traffic
) -> tuple[Array, Array]:
    """Exact closest approach of every candidate to every other UAV, interval by interval."""
    n, u = times.shape[0], traffic.radii.size
    if u == 0:
        return np.zeros(n), np.zeros(n)
    # Union of both timelines per (candidate, other), cut where either has landed.
    merged = np.concatenate(
        [
            np.broadcast_to(times[:, None, :], (n, u, times.shape[1])),
            np.broadcast_to(traffic.times[None], (n, u, traffic.times.shape[1])),
        ],
        axis=2,
    )
    end = np.minimum(times[:, -1:, None], traffic.end_times[None, :, None])  # (N, U, 1)
    merged = np.sort(np.minimum(merged, end), axis=2)
    m = merged.shape[2]
    mine = batched_interp(merged.reshape(n, u * m), times, positions).reshape(n, u, m, 2)
    theirs = (
        batched_interp(
            merged.transpose(1, 0, 2).reshape(u, n * m), traffic.times, traffic.positions
        )
        .reshape(u, n, m, 2)
        .transpose(1, 0, 2, 3)
    )
    gap = mine - theirs
    start, change = gap[:, :, :-1], np.diff(gap, axis=2)
    speed2 = np.einsum("...i,...i->...", change, change)
    towards = -np.einsum("...i,...i->...", start, change)
    tau = np.divide(towards, speed2, out=np.zeros_like(speed2), where=speed2 > 0)
    nearest = start + np.clip(tau, 0, 1)[..., None] * change
    closest = np.sqrt(np.einsum("...i,...i->...", nearest, nearest))
    need = radius + traffic.radii[None, :, None]
    deficit = np.maximum(need - closest, 0.0)
    duration = np.diff(merged, axis=2)
    return (deficit * np.maximum(duration, 1e-3)).sum(axis=(1, 2)), (deficit > 0).sum(axis=(1, 2))


@functools.cache
def _fractions(q: int) -> Array:
    return np.linspace(0.0, 1.0, q)


def clearance_terms(
    waypoints: Array, radius: float, field: ClearanceField, margin: float
) -> tuple[Array, Array]:
    """Sampled clearance along every leg against blocked cells (and the grid's edge)."""
    legs = np.diff(waypoints, axis=1)  # (N, P-1, 2)
    longest = float(np.hypot(legs[..., 0], legs[..., 1]).max(initial=0.0))
    q = max(2, int(np.ceil(longest / SPACING)) + 1)
    frac = _fractions(q)
    points = waypoints[:, :-1, None, :] + frac[None, None, :, None] * legs[:, :, None, :]
    deficit = np.maximum(radius + margin - field.at(points), 0.0)  # (N, P-1, q)
    step = np.hypot(legs[..., 0], legs[..., 1])[..., None] / (q - 1)
    return (deficit * np.maximum(step, SPACING)).sum(axis=(1, 2)), (deficit > 0).sum(axis=(1, 2))


def evaluate_paths(
    waypoints: Array,
    waits: Array,
    *,
    speed: float,
    radius: float,
    goal: Array,
    traffic: Traffic,
    field: ClearanceField,
) -> PathTerms:
    """All cost terms of N candidate paths: waypoints (N, P, 2), hover times (N, P)."""
    times, positions = timeline(waypoints, waits, speed)
    steps = np.diff(waypoints, axis=1)
    separation, separation_hits = separation_terms(times, positions, radius, traffic)
    clearance, clearance_hits = clearance_terms(waypoints, radius, field, 1.0 / field.scale)
    return PathTerms(
        length=np.hypot(steps[..., 0], steps[..., 1]).sum(axis=1),
        waiting=waits.sum(axis=1),
        end_time=times[:, -1],
        deviation=np.hypot(*(waypoints[:, -1] - goal).T),
        separation_deficit=separation,
        separation_hits=separation_hits,
        clearance_deficit=clearance,
        clearance_hits=clearance_hits,
    )
