"""Dragonfly algorithm (Mirjalili 2016), as the authors' DA.m."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.optimizers.algorithm import Algorithm, Best, track_best
from planner.optimizers.problem import Problem


@dataclass(repr=False)
class DA(Algorithm):
    """Separation, alignment, cohesion, food attraction and enemy distraction; Lévy flights
    for a dragonfly with no neighbours.

    DA.m moves the dragonflies one after another, so dragonfly i already sees the new
    positions of dragonflies 1..i-1. Without a loop over agents every dragonfly moves
    from the same snapshot (a synchronous update); the rules and schedules are DA.m's.
    """

    name = "da"
    levy_beta: float = 1.5

    def iterate(
        self, problem: Problem, population: int, iterations: int, rng: np.random.Generator
    ) -> Iterator[Best]:
        n, d = population, problem.dim
        span = problem.span
        step_max = span / 10.0
        x = problem.random_population(n, rng)
        # DA.m initialises the step vectors like positions, inside the bounds.
        dx = problem.random_population(n, rng)
        food: Best | None = None
        enemy = Best(np.zeros(d), -np.inf)
        for it in range(1, iterations + 1):
            radius = span / 4.0 + span * (it / iterations) * 2.0
            w = 0.9 - it * (0.9 - 0.4) / iterations
            c = max(0.0, 0.1 - it * 0.1 / (iterations / 2.0))
            s_w, a_w, c_w = 2.0 * rng.random(3) * c
            f_w = 2.0 * rng.random()
            e_w = c

            costs = problem.evaluate(x)
            food = track_best(food, x, costs)
            enemy = _track_enemy(enemy, x, costs, problem)
            yield food

            near = np.all(np.abs(x[None, :, :] - x[:, None, :]) <= radius, axis=2)
            near &= np.all(x[None, :, :] != x[:, None, :], axis=2)
            count = near.sum(axis=1)
            flock = (count > 1)[:, None]
            mean_x = near @ x / np.maximum(count, 1)[:, None]
            separation = np.where(flock, -(near @ x - count[:, None] * x), 0.0)  # eq. (3.1)
            alignment = np.where(flock, near @ dx / np.maximum(count, 1)[:, None], dx)  # (3.2)
            cohesion = np.where(flock, mean_x, x) - x  # eq. (3.3)
            food_near = np.all(np.abs(x - food.x) <= radius, axis=1)[:, None]
            attraction = np.where(food_near, food.x - x, 0.0)  # eq. (3.4)
            enemy_near = np.all(np.abs(x - enemy.x) <= radius, axis=1)[:, None]
            distraction = np.where(enemy_near, enemy.x + x, 0.0)  # eq. (3.5)
            # DA.m wraps out-of-bounds coordinates to the opposite bound here, but the
            # positions were clipped at the end of the previous move, so it never fires.

            swarm = np.clip(  # eq. (3.6)
                a_w * alignment
                + c_w * cohesion
                + s_w * separation
                + f_w * attraction
                + e_w * distraction
                + w * dx,
                -step_max,
                step_max,
            )
            rand3 = rng.random((3, n, d))
            wander = np.clip(
                w * dx + rand3[0] * alignment + rand3[1] * cohesion + rand3[2] * separation,
                -step_max,
                step_max,
            )
            levy = self._levy(rng, (n, d))  # eq. (3.8)
            new_dx = np.where(food_near, swarm, np.where(flock, wander, 0.0))
            x = np.where(food_near | flock, x + new_dx, x + levy * x)
            dx = new_dx
            x = problem.clip(x)

    def _levy(self, rng: np.random.Generator, shape: tuple[int, int]) -> NDArray[np.float64]:
        """Mantegna's Lévy step, scaled by 0.01, as DA.m's `Levy`."""
        beta = self.levy_beta
        sigma = (
            math.gamma(1 + beta)
            * math.sin(math.pi * beta / 2)
            / (math.gamma((1 + beta) / 2) * beta * 2 ** ((beta - 1) / 2))
        ) ** (1 / beta)
        u = rng.standard_normal(shape) * sigma
        v = rng.standard_normal(shape)
        step: NDArray[np.float64] = 0.01 * u / np.abs(v) ** (1 / beta)
        return step


def _track_enemy(
    enemy: Best, x: NDArray[np.float64], costs: NDArray[np.float64], problem: Problem
) -> Best:
    """The worst dragonfly so far, counting only those strictly inside the bounds (as DA.m)."""
    inside = np.all((x > problem.lower) & (x < problem.upper), axis=1)
    pool = np.where(inside, costs, -np.inf)
    i = int(np.argmax(pool))
    if pool[i] > enemy.cost:
        return Best(x[i].copy(), float(pool[i]))
    return enemy
