"""Literal, loop-by-loop Python ports of the authors' MATLAB demo codes, for use as test oracles.

Each function follows one of Seyedali Mirjalili's published demos (MVO.m, ALO.m, DA.m,
GWO.m, MFO.m, WOA.m, with their helpers initialization.m, RouletteWheelSelection.m,
Random_walk_around_antlion.m and DA.m's Levy) statement by statement: the same loops over
agents and coordinates, the same in-place (sequential) updates, the same strict and
non-strict comparisons, the same schedules, MATLAB's stable `sort` and MATLAB's `round`
(halves away from zero). Indices are 0-based and agents are rows (DA.m keeps them as
columns); everything else is kept, including the demos' quirks.

These ports are slow and naive on purpose. The tests check `planner.optimizers` against
them, so keep them simple and literal rather than fast or clever.

Conventions
-----------
* Signature: ``port(objective, lb, ub, dim, N, T, rng) -> (best_cost, convergence_curve)``.
  ``objective`` maps ONE position (shape ``(dim,)``) to a float. ``lb`` and ``ub`` are
  scalars or length-``dim`` sequences. ``rng`` (a ``numpy.random.Generator``) replaces
  MATLAB's global ``rand``/``randn`` stream: every ``rand`` in the MATLAB is one
  ``rng.random()`` call here, in the same order, unless a comment says otherwise.
* ``initialization.m`` is ``rand(N, dim) .* (ub - lb) + lb``; we draw it row by row, as
  ``planner`` does, which gives the same distribution.
* Two MATLAB bookkeeping slips that ``planner`` documents and deliberately does not copy
  are kept here by default, with a keyword to switch each one off so that a test can
  compare like with like: ``alo(..., stale_fitness=True)`` and ``mfo(..., lag=True)``.
* DA.m and WOA.m move the agents one after another, so a later agent sees the new
  positions of the earlier ones. ``planner`` moves them all from the same snapshot. The
  ports are sequential by default; ``synchronous=True`` makes every agent read the other
  agents from the snapshot taken before the move loop, which is ``planner``'s rule. It
  exists to tell the two effects apart when a comparison fails.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

Objective = Callable[[NDArray[np.float64]], float]
Result = tuple[float, NDArray[np.float64]]
Array = NDArray[np.float64]


# --------------------------------------------------------------------------------------
# Helpers shared by the demos
# --------------------------------------------------------------------------------------


def _bounds(lb: ArrayLike, ub: ArrayLike, dim: int) -> tuple[Array, Array]:
    """`if size(ub,2)==1: ub=ones(1,dim)*ub; lb=ones(1,dim)*lb; end`."""
    lower = np.broadcast_to(np.asarray(lb, dtype=np.float64), (dim,)).copy()
    upper = np.broadcast_to(np.asarray(ub, dtype=np.float64), (dim,)).copy()
    return lower, upper


def initialization(n: int, dim: int, ub: Array, lb: Array, rng: np.random.Generator) -> Array:
    """initialization.m: uniform positions in the box, one row per agent."""
    return rng.random((n, dim)) * (ub - lb) + lb


def bring_back(x: Array, lb: Array, ub: Array) -> Array:
    """`Flag4ub=x>ub; Flag4lb=x<lb; x=(x.*(~(Flag4ub+Flag4lb)))+ub.*Flag4ub+lb.*Flag4lb;`"""
    flag4ub = x > ub
    flag4lb = x < lb
    return x * ~(flag4ub | flag4lb) + ub * flag4ub + lb * flag4lb


def matlab_round(x: float) -> int:
    """MATLAB's `round`: halves go away from zero (Python's `round` sends them to even)."""
    magnitude = abs(x)
    whole = math.floor(magnitude)
    if magnitude - whole >= 0.5:  # exact for doubles below 2**52
        whole += 1
    return int(math.copysign(whole, x))


def matlab_sort(values: Array) -> tuple[Array, NDArray[np.intp]]:
    """`[sorted, I] = sort(values)`: ascending, ties keep their order (MATLAB's sort is stable)."""
    order = np.argsort(values, kind="stable")
    return values[order], order


def roulette_wheel_selection(weights: ArrayLike, rng: np.random.Generator) -> int:
    """RouletteWheelSelection.m: a 1-based index, or -1 when no index qualifies."""
    with np.errstate(over="ignore", invalid="ignore"):
        accumulation = np.cumsum(np.asarray(weights, dtype=np.float64))
        p = rng.random() * accumulation[-1]
    chosen_index = -1
    for index in range(accumulation.size):
        if accumulation[index] > p:
            chosen_index = index + 1
            break
    return chosen_index


def normr(v: Array) -> Array:
    """MATLAB's `normr` on a row vector: v / norm(v).

    An all-zero row (every cost exactly 0) is not a case the MATLAB demos handle; we return
    zeros, as planner's MVO does. No test reaches it.
    """
    norm = math.sqrt(float(np.sum(v * v)))
    return v / norm if norm > 0 else np.zeros_like(v)


def levy(d: int, rng: np.random.Generator) -> Array:
    """DA.m's `Levy(d)`: Mantegna's step with beta = 3/2, scaled by 0.01 (eq. 3.9-3.10)."""
    beta = 3 / 2
    sigma = (
        math.gamma(1 + beta)
        * math.sin(math.pi * beta / 2)
        / (math.gamma((1 + beta) / 2) * beta * 2 ** ((beta - 1) / 2))
    ) ** (1 / beta)
    u = rng.standard_normal(d) * sigma
    v = rng.standard_normal(d)
    step = u / np.abs(v) ** (1 / beta)
    return 0.01 * step


def antlion_ratio(current_iter: int, max_iter: int) -> float:
    """The ratio I of Random_walk_around_antlion.m (eq. 2.10-2.11), its five `if`s in order."""
    ratio = 1.0
    if current_iter > max_iter / 10:
        ratio = 1 + 100 * (current_iter / max_iter)
    if current_iter > max_iter / 2:
        ratio = 1 + 1000 * (current_iter / max_iter)
    if current_iter > max_iter * (3 / 4):
        ratio = 1 + 10000 * (current_iter / max_iter)
    if current_iter > max_iter * (0.9):
        ratio = 1 + 100000 * (current_iter / max_iter)
    if current_iter > max_iter * (0.95):
        ratio = 1 + 1000000 * (current_iter / max_iter)
    return ratio


def random_walk_around_antlion(
    dim: int,
    max_iter: int,
    lb: Array,
    ub: Array,
    antlion: Array,
    current_iter: int,
    rng: np.random.Generator,
) -> Array:
    """Random_walk_around_antlion.m: RWs, shape (max_iter + 1, dim).

    MATLAB's 1-based row RWs(t,:), the position after t - 1 steps, is row t - 1 here.
    """
    ratio = antlion_ratio(current_iter, max_iter)
    lb = lb / ratio  # eq. (2.10)
    ub = ub / ratio  # eq. (2.11)
    lb = lb + antlion if rng.random() < 0.5 else -lb + antlion  # eq. (2.8)
    ub = ub + antlion if rng.random() >= 0.5 else -ub + antlion  # eq. (2.9)
    rws = np.empty((max_iter + 1, dim))
    for i in range(dim):
        steps = 2 * (rng.random(max_iter) > 0.5) - 1
        x = np.concatenate(([0.0], np.cumsum(steps)))  # eq. (2.1)
        a = x.min()
        b = x.max()
        c = lb[i]
        d = ub[i]
        rws[:, i] = ((x - a) * (d - c)) / (b - a) + c  # eq. (2.7)
    return rws


def distance(a: Array, b: Array) -> Array:
    """DA.m's `distance`: the per-coordinate |a - b|, not a norm."""
    return np.sqrt((a - b) ** 2)


def gwo_rank(
    fitness: float,
    position: Array,
    scores: list[float],
    positions: list[Array],
) -> None:
    """GWO.m's three `if`s for one wolf, in place on scores/positions = [alpha, beta, delta]."""
    if fitness < scores[0]:
        scores[0] = fitness
        positions[0] = position.copy()
    if fitness > scores[0] and fitness < scores[1]:
        scores[1] = fitness
        positions[1] = position.copy()
    if fitness > scores[0] and fitness > scores[1] and fitness < scores[2]:
        scores[2] = fitness
        positions[2] = position.copy()


# --------------------------------------------------------------------------------------
# The six demos
# --------------------------------------------------------------------------------------


def mvo(
    objective: Objective,
    lb: ArrayLike,
    ub: ArrayLike,
    dim: int,
    N: int,
    T: int,
    rng: np.random.Generator,
) -> Result:
    """MVO.m (Mirjalili, Mirjalili & Hatamlou 2016)."""
    lb, ub = _bounds(lb, ub, dim)
    max_time = T
    best_universe = np.zeros(dim)
    best_universe_inflation_rate = math.inf
    universes = initialization(N, dim, ub, lb, rng)
    wep_max = 1
    wep_min = 0.2
    convergence_curve = np.zeros(max_time)
    time = 1
    while time < max_time + 1:
        wep = wep_min + time * ((wep_max - wep_min) / max_time)  # eq. (3.3)
        tdr = 1 - (time ** (1 / 6) / max_time ** (1 / 6))  # eq. (3.4)
        inflation_rates = np.zeros(N)
        for i in range(N):
            universes[i] = bring_back(universes[i], lb, ub)
            inflation_rates[i] = objective(universes[i].copy())
            if inflation_rates[i] < best_universe_inflation_rate:  # elitism
                best_universe_inflation_rate = inflation_rates[i]
                best_universe = universes[i].copy()

        sorted_inflation_rates, sorted_indexes = matlab_sort(inflation_rates)
        sorted_universes = np.zeros((N, dim))
        for newindex in range(N):
            sorted_universes[newindex] = universes[sorted_indexes[newindex]]
        normalized_sorted_inflation_rates = normr(sorted_inflation_rates)
        universes[0] = sorted_universes[0]

        for i in range(1, N):  # row 1 is the elite
            back_hole_index = i
            for j in range(dim):
                r1 = rng.random()
                if r1 < normalized_sorted_inflation_rates[i]:
                    white_hole_index = roulette_wheel_selection(-sorted_inflation_rates, rng)
                    if white_hole_index == -1:
                        white_hole_index = 1
                    # eq. (3.1)
                    universes[back_hole_index, j] = sorted_universes[white_hole_index - 1, j]
                # eq. (3.2); MATLAB's scalar-bound branch is this one with lb(j) = lb
                r2 = rng.random()
                if r2 < wep:
                    r3 = rng.random()
                    if r3 < 0.5:
                        universes[i, j] = best_universe[j] + tdr * (
                            (ub[j] - lb[j]) * rng.random() + lb[j]
                        )
                    if r3 > 0.5:
                        universes[i, j] = best_universe[j] - tdr * (
                            (ub[j] - lb[j]) * rng.random() + lb[j]
                        )

        convergence_curve[time - 1] = best_universe_inflation_rate
        time = time + 1
    return float(best_universe_inflation_rate), convergence_curve


def alo(
    objective: Objective,
    lb: ArrayLike,
    ub: ArrayLike,
    dim: int,
    N: int,
    T: int,
    rng: np.random.Generator,
    *,
    stale_fitness: bool = True,
) -> Result:
    """ALO.m (Mirjalili 2015).

    ALO.m sets `sorted_antlion_fitness` once, before its main loop, and never again, so its
    roulette wheel and its merge of antlions with ants keep pairing the current antlions
    with the initial antlions' fitness. `stale_fitness=False` refreshes it at the end of
    every iteration (the fix planner makes). As in ALO.m, the first iteration only
    evaluates the antlions and `convergence_curve[0]` stays 0.
    """
    lb, ub = _bounds(lb, ub, dim)
    max_iter = T
    antlion_position = initialization(N, dim, ub, lb, rng)
    ant_position = initialization(N, dim, ub, lb, rng)
    sorted_antlions = np.zeros((N, dim))
    convergence_curve = np.zeros(max_iter)
    antlions_fitness = np.zeros(N)
    ants_fitness = np.zeros(N)

    for i in range(N):
        antlions_fitness[i] = objective(antlion_position[i].copy())
    sorted_antlion_fitness, sorted_indexes = matlab_sort(antlions_fitness)
    for newindex in range(N):
        sorted_antlions[newindex] = antlion_position[sorted_indexes[newindex]]
    elite_antlion_position = sorted_antlions[0].copy()
    elite_antlion_fitness = sorted_antlion_fitness[0]

    current_iter = 2
    while current_iter < max_iter + 1:
        for i in range(N):
            with np.errstate(divide="ignore"):
                rolette_index = roulette_wheel_selection(1.0 / sorted_antlion_fitness, rng)
            if rolette_index == -1:
                rolette_index = 1
            ra = random_walk_around_antlion(
                dim, max_iter, lb, ub, sorted_antlions[rolette_index - 1], current_iter, rng
            )
            re = random_walk_around_antlion(
                dim, max_iter, lb, ub, elite_antlion_position, current_iter, rng
            )
            ant_position[i] = (ra[current_iter - 1] + re[current_iter - 1]) / 2  # eq. (2.13)

        for i in range(N):
            ant_position[i] = bring_back(ant_position[i], lb, ub)
            ants_fitness[i] = objective(ant_position[i].copy())

        double_population = np.vstack([sorted_antlions, ant_position])
        double_fitness = np.concatenate([sorted_antlion_fitness, ants_fitness])
        double_fitness_sorted, order = matlab_sort(double_fitness)
        double_sorted_population = double_population[order]
        antlions_fitness = double_fitness_sorted[:N].copy()
        sorted_antlions = double_sorted_population[:N].copy()

        if antlions_fitness[0] < elite_antlion_fitness:
            elite_antlion_position = sorted_antlions[0].copy()
            elite_antlion_fitness = antlions_fitness[0]
        sorted_antlions[0] = elite_antlion_position
        antlions_fitness[0] = elite_antlion_fitness

        convergence_curve[current_iter - 1] = elite_antlion_fitness
        if not stale_fitness:  # the refresh ALO.m leaves out
            sorted_antlion_fitness = antlions_fitness.copy()
        current_iter = current_iter + 1
    return float(elite_antlion_fitness), convergence_curve


def da(
    objective: Objective,
    lb: ArrayLike,
    ub: ArrayLike,
    dim: int,
    N: int,
    T: int,
    rng: np.random.Generator,
    *,
    synchronous: bool = False,
) -> Result:
    """DA.m (Mirjalili 2016). Dragonfly i sees dragonflies 1..i-1 already moved, as in DA.m,
    unless `synchronous=True` (see the module docstring)."""
    lb, ub = _bounds(lb, ub, dim)
    max_iteration = T
    delta_max = (ub - lb) / 10
    food_fitness = math.inf
    food_pos = np.zeros(dim)
    enemy_fitness = -math.inf
    enemy_pos = np.zeros(dim)
    x = initialization(N, dim, ub, lb, rng)
    fitness = np.zeros(N)
    delta_x = initialization(N, dim, ub, lb, rng)
    cg_curve = np.zeros(max_iteration)

    for it in range(1, max_iteration + 1):
        r = (ub - lb) / 4 + ((ub - lb) * (it / max_iteration) * 2)
        w = 0.9 - it * ((0.9 - 0.4) / max_iteration)
        my_c = 0.1 - it * ((0.1 - 0) / (max_iteration / 2))
        if my_c < 0:
            my_c = 0
        s = 2 * rng.random() * my_c  # separation weight
        a = 2 * rng.random() * my_c  # alignment weight
        c = 2 * rng.random() * my_c  # cohesion weight
        f = 2 * rng.random()  # food attraction weight
        e = my_c  # enemy distraction weight

        for i in range(N):
            fitness[i] = objective(x[i].copy())
            if fitness[i] < food_fitness:
                food_fitness = fitness[i]
                food_pos = x[i].copy()
            if fitness[i] > enemy_fitness and np.all(x[i] < ub) and np.all(x[i] > lb):
                enemy_fitness = fitness[i]
                enemy_pos = x[i].copy()

        if synchronous:
            seen_x, seen_delta_x = x.copy(), delta_x.copy()
        else:
            seen_x, seen_delta_x = x, delta_x

        for i in range(N):
            neighbours_no = 0
            neighbours_delta_x: list[Array] = []
            neighbours_x: list[Array] = []
            for j in range(N):
                dist2enemy = distance(x[i], seen_x[j])
                if np.all(dist2enemy <= r) and np.all(dist2enemy != 0):
                    neighbours_no = neighbours_no + 1
                    neighbours_delta_x.append(seen_delta_x[j].copy())
                    neighbours_x.append(seen_x[j].copy())

            # Separation, eq. (3.1)
            sep = np.zeros(dim)
            if neighbours_no > 1:
                for k in range(neighbours_no):
                    sep = sep + (neighbours_x[k] - x[i])
                sep = -sep
            # Alignment, eq. (3.2)
            if neighbours_no > 1:
                ali = np.sum(neighbours_delta_x, axis=0) / neighbours_no
            else:
                ali = delta_x[i].copy()
            # Cohesion, eq. (3.3)
            if neighbours_no > 1:
                c_temp = np.sum(neighbours_x, axis=0) / neighbours_no
            else:
                c_temp = x[i].copy()
            coh = c_temp - x[i]
            # Attraction to food, eq. (3.4)
            dist2food = distance(x[i], food_pos)
            food = food_pos - x[i] if np.all(dist2food <= r) else np.zeros(dim)
            # Distraction from enemy, eq. (3.5)
            dist2enemy = distance(x[i], enemy_pos)
            enemy = enemy_pos + x[i] if np.all(dist2enemy <= r) else np.zeros(dim)

            for tt in range(dim):
                if x[i, tt] > ub[tt]:
                    x[i, tt] = lb[tt]
                    delta_x[i, tt] = rng.random()
                if x[i, tt] < lb[tt]:
                    x[i, tt] = ub[tt]
                    delta_x[i, tt] = rng.random()

            if np.any(dist2food > r):
                if neighbours_no > 1:
                    for j in range(dim):
                        delta_x[i, j] = (
                            w * delta_x[i, j]
                            + rng.random() * ali[j]
                            + rng.random() * coh[j]
                            + rng.random() * sep[j]
                        )
                        if delta_x[i, j] > delta_max[j]:
                            delta_x[i, j] = delta_max[j]
                        if delta_x[i, j] < -delta_max[j]:
                            delta_x[i, j] = -delta_max[j]
                        x[i, j] = x[i, j] + delta_x[i, j]
                else:
                    x[i] = x[i] + levy(dim, rng) * x[i]  # eq. (3.8)
                    delta_x[i] = 0
            else:
                for j in range(dim):
                    # eq. (3.6)
                    delta_x[i, j] = (
                        a * ali[j] + c * coh[j] + s * sep[j] + f * food[j] + e * enemy[j]
                    ) + w * delta_x[i, j]
                    if delta_x[i, j] > delta_max[j]:
                        delta_x[i, j] = delta_max[j]
                    if delta_x[i, j] < -delta_max[j]:
                        delta_x[i, j] = -delta_max[j]
                    x[i, j] = x[i, j] + delta_x[i, j]

            x[i] = bring_back(x[i], lb, ub)
        cg_curve[it - 1] = food_fitness
    return float(food_fitness), cg_curve


def gwo(
    objective: Objective,
    lb: ArrayLike,
    ub: ArrayLike,
    dim: int,
    N: int,
    T: int,
    rng: np.random.Generator,
) -> Result:
    """GWO.m (Mirjalili, Mirjalili & Lewis 2014)."""
    lb, ub = _bounds(lb, ub, dim)
    max_iter = T
    scores = [math.inf, math.inf, math.inf]  # Alpha_score, Beta_score, Delta_score
    leaders = [np.zeros(dim), np.zeros(dim), np.zeros(dim)]  # Alpha_pos, Beta_pos, Delta_pos
    positions = initialization(N, dim, ub, lb, rng)
    convergence_curve = np.zeros(max_iter)
    loop = 0
    while loop < max_iter:
        for i in range(N):
            positions[i] = bring_back(positions[i], lb, ub)
            fitness = objective(positions[i].copy())
            gwo_rank(fitness, positions[i], scores, leaders)

        a = 2 - loop * (2 / max_iter)  # decreases linearly from 2 to 0
        alpha_pos, beta_pos, delta_pos = leaders
        for i in range(N):
            for j in range(dim):
                r1 = rng.random()
                r2 = rng.random()
                a1 = 2 * a * r1 - a  # eq. (3.3)
                c1 = 2 * r2  # eq. (3.4)
                d_alpha = abs(c1 * alpha_pos[j] - positions[i, j])  # eq. (3.5)
                x1 = alpha_pos[j] - a1 * d_alpha  # eq. (3.6)

                r1 = rng.random()
                r2 = rng.random()
                a2 = 2 * a * r1 - a
                c2 = 2 * r2
                d_beta = abs(c2 * beta_pos[j] - positions[i, j])
                x2 = beta_pos[j] - a2 * d_beta

                r1 = rng.random()
                r2 = rng.random()
                a3 = 2 * a * r1 - a
                c3 = 2 * r2
                d_delta = abs(c3 * delta_pos[j] - positions[i, j])
                x3 = delta_pos[j] - a3 * d_delta

                positions[i, j] = (x1 + x2 + x3) / 3  # eq. (3.7)
        loop = loop + 1
        convergence_curve[loop - 1] = scores[0]
    return float(scores[0]), convergence_curve


def mfo(
    objective: Objective,
    lb: ArrayLike,
    ub: ArrayLike,
    dim: int,
    N: int,
    T: int,
    rng: np.random.Generator,
    *,
    lag: bool = True,
) -> Result:
    """MFO.m (Mirjalili 2015).

    From the second iteration on, MFO.m merges the flames with `previous_population`, the
    moths it evaluated one iteration earlier, so the moths just evaluated only count one
    iteration later (and those of the last iteration never). `lag=False` merges the moths
    just evaluated (the paper's rule, which planner follows).
    """
    lb, ub = _bounds(lb, ub, dim)
    max_iteration = T
    moth_pos = initialization(N, dim, ub, lb, rng)
    moth_fitness = np.zeros(N)
    convergence_curve = np.zeros(max_iteration)
    previous_population = np.zeros((N, dim))
    previous_fitness = np.zeros(N)
    best_flames = np.zeros((N, dim))
    best_flame_fitness = np.zeros(N)
    iteration = 1
    while iteration < max_iteration + 1:
        flame_no = matlab_round(N - iteration * ((N - 1) / max_iteration))  # eq. (3.14)
        for i in range(N):
            moth_pos[i] = bring_back(moth_pos[i], lb, ub)
            moth_fitness[i] = objective(moth_pos[i].copy())

        if iteration == 1:
            fitness_sorted, order = matlab_sort(moth_fitness)
            sorted_population = moth_pos[order]
            best_flames = sorted_population
            best_flame_fitness = fitness_sorted
        else:
            if lag:
                double_population = np.vstack([previous_population, best_flames])
                double_fitness = np.concatenate([previous_fitness, best_flame_fitness])
            else:
                double_population = np.vstack([moth_pos, best_flames])
                double_fitness = np.concatenate([moth_fitness, best_flame_fitness])
            double_fitness_sorted, order = matlab_sort(double_fitness)
            double_sorted_population = double_population[order]
            fitness_sorted = double_fitness_sorted[:N]
            sorted_population = double_sorted_population[:N]
            best_flames = sorted_population
            best_flame_fitness = fitness_sorted

        best_flame_score = fitness_sorted[0]
        previous_population = moth_pos.copy()
        previous_fitness = moth_fitness.copy()

        a = -1 + iteration * ((-1) / max_iteration)  # -1 -> -2
        for i in range(N):
            for j in range(dim):
                if i + 1 <= flame_no:  # the moth's own flame
                    distance_to_flame = abs(sorted_population[i, j] - moth_pos[i, j])
                    b = 1
                    t = (a - 1) * rng.random() + 1
                    moth_pos[i, j] = (
                        distance_to_flame * np.exp(b * t) * np.cos(t * 2 * np.pi)
                        + sorted_population[i, j]
                    )
                if i + 1 > flame_no:  # the last flame
                    distance_to_flame = abs(sorted_population[i, j] - moth_pos[i, j])
                    b = 1
                    t = (a - 1) * rng.random() + 1
                    moth_pos[i, j] = (
                        distance_to_flame * np.exp(b * t) * np.cos(t * 2 * np.pi)
                        + sorted_population[flame_no - 1, j]
                    )

        convergence_curve[iteration - 1] = best_flame_score
        iteration = iteration + 1
    return float(best_flame_score), convergence_curve


def woa(
    objective: Objective,
    lb: ArrayLike,
    ub: ArrayLike,
    dim: int,
    N: int,
    T: int,
    rng: np.random.Generator,
    *,
    synchronous: bool = False,
) -> Result:
    """WOA.m (Mirjalili & Lewis 2016). A whale searching around a random whale sees the new
    positions of the whales moved before it, as in WOA.m, unless `synchronous=True`."""
    lb, ub = _bounds(lb, ub, dim)
    max_iter = T
    leader_pos = np.zeros(dim)
    leader_score = math.inf
    positions = initialization(N, dim, ub, lb, rng)
    convergence_curve = np.zeros(max_iter)
    t = 0
    while t < max_iter:
        for i in range(N):
            positions[i] = bring_back(positions[i], lb, ub)
            fitness = objective(positions[i].copy())
            if fitness < leader_score:
                leader_score = fitness
                leader_pos = positions[i].copy()

        a = 2 - t * (2 / max_iter)  # 2 -> 0, eq. (2.3)
        a2 = -1 + t * ((-1) / max_iter)  # -1 -> -2
        seen = positions.copy() if synchronous else positions
        for i in range(N):
            r1 = rng.random()
            r2 = rng.random()
            big_a = 2 * a * r1 - a  # eq. (2.3)
            big_c = 2 * r2  # eq. (2.4)
            b = 1
            spiral_l = (a2 - 1) * rng.random() + 1
            p = rng.random()  # eq. (2.6)
            for j in range(dim):
                if p < 0.5:
                    if abs(big_a) >= 1:
                        rand_leader_index = math.floor(N * rng.random() + 1)
                        x_rand = seen[rand_leader_index - 1].copy()
                        d_x_rand = abs(big_c * x_rand[j] - positions[i, j])  # eq. (2.7)
                        positions[i, j] = x_rand[j] - big_a * d_x_rand  # eq. (2.8)
                    elif abs(big_a) < 1:
                        d_leader = abs(big_c * leader_pos[j] - positions[i, j])  # eq. (2.1)
                        positions[i, j] = leader_pos[j] - big_a * d_leader  # eq. (2.2)
                elif p >= 0.5:
                    distance2leader = abs(leader_pos[j] - positions[i, j])
                    positions[i, j] = (  # eq. (2.5)
                        distance2leader * np.exp(b * spiral_l) * np.cos(spiral_l * 2 * np.pi)
                        + leader_pos[j]
                    )
        t = t + 1
        convergence_curve[t - 1] = leader_score
    return float(leader_score), convergence_curve


PORTS: dict[str, Callable[..., Result]] = {
    "mvo": mvo,
    "alo": alo,
    "da": da,
    "gwo": gwo,
    "mfo": mfo,
    "woa": woa,
}


def per_vector(vectorised: Callable[[Array], ArrayLike]) -> Objective:
    """A one-position objective from a population objective (n, d) -> (n,)."""

    def objective(x: Array) -> float:
        return float(np.asarray(vectorised(x[None, :]))[0])

    return objective


__all__: Sequence[str] = [
    "PORTS",
    "alo",
    "antlion_ratio",
    "bring_back",
    "da",
    "gwo",
    "gwo_rank",
    "initialization",
    "levy",
    "matlab_round",
    "matlab_sort",
    "mfo",
    "mvo",
    "normr",
    "per_vector",
    "random_walk_around_antlion",
    "roulette_wheel_selection",
    "woa",
]
