"""Standard test functions, vectorised: each maps a population (n, d) to costs (n,)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def sphere(x: Array) -> Array:
    cost: Array = np.sum(x**2, axis=1)
    return cost


def rosenbrock(x: Array) -> Array:
    cost: Array = np.sum(100.0 * (x[:, 1:] - x[:, :-1] ** 2) ** 2 + (x[:, :-1] - 1.0) ** 2, axis=1)
    return cost


def step(x: Array) -> Array:
    """Σ ⌊x + 0.5⌋², the step function of the literature: flat plateaus, 0 on [-0.5, 0.5)."""
    cost: Array = np.sum(np.floor(x + 0.5) ** 2, axis=1)
    return cost


def step_matlab(x: Array) -> Array:
    """Σ |x + 0.5|², the F6 of the authors' MATLAB benchmark code (no floor): 0 at x = -0.5."""
    cost: Array = np.sum(np.abs(x + 0.5) ** 2, axis=1)
    return cost


def rastrigin(x: Array) -> Array:
    cost: Array = np.sum(x**2 - 10.0 * np.cos(2.0 * np.pi * x) + 10.0, axis=1)
    return cost


def ackley(x: Array) -> Array:
    d = x.shape[1]
    cost: Array = (
        -20.0 * np.exp(-0.2 * np.sqrt(np.sum(x**2, axis=1) / d))
        - np.exp(np.sum(np.cos(2.0 * np.pi * x), axis=1) / d)
        + 20.0
        + np.e
    )
    return cost


def griewank(x: Array) -> Array:
    i = np.arange(1, x.shape[1] + 1)
    cost: Array = np.sum(x**2, axis=1) / 4000.0 - np.prod(np.cos(x / np.sqrt(i)), axis=1) + 1.0
    return cost


_WEIERSTRASS_K = np.arange(21)  # k_max = 20
_WEIERSTRASS_A = 0.5**_WEIERSTRASS_K
_WEIERSTRASS_B = 3.0**_WEIERSTRASS_K


def weierstrass(x: Array) -> Array:
    """Σ_i Σ_k a^k cos(2π b^k (x_i + 0.5)) - d Σ_k a^k cos(π b^k), a = 0.5, b = 3, k ≤ 20."""
    d = x.shape[1]
    terms = _WEIERSTRASS_A * np.cos(2.0 * np.pi * _WEIERSTRASS_B * (x[..., None] + 0.5))
    offset = d * np.sum(_WEIERSTRASS_A * np.cos(np.pi * _WEIERSTRASS_B))
    cost: Array = np.sum(terms, axis=(1, 2)) - offset
    return cost


@dataclass(frozen=True)
class BenchmarkFunction:
    """A test function with its standard search box and known optimum."""

    name: str
    function: Callable[[Array], Array]
    lower: float
    upper: float
    optimum: float
    argmin: float  # every coordinate of a minimiser

    def __call__(self, x: Array) -> Array:
        return self.function(x)

    def bounds(self, dim: int) -> tuple[Array, Array]:
        return np.full(dim, self.lower), np.full(dim, self.upper)

    def minimiser(self, dim: int) -> Array:
        return np.full(dim, self.argmin)


BENCHMARKS: dict[str, BenchmarkFunction] = {
    f.name: f
    for f in (
        BenchmarkFunction("sphere", sphere, -100.0, 100.0, 0.0, 0.0),
        BenchmarkFunction("rosenbrock", rosenbrock, -30.0, 30.0, 0.0, 1.0),
        BenchmarkFunction("step", step, -100.0, 100.0, 0.0, 0.0),
        BenchmarkFunction("step_matlab", step_matlab, -100.0, 100.0, 0.0, -0.5),
        BenchmarkFunction("rastrigin", rastrigin, -5.12, 5.12, 0.0, 0.0),
        BenchmarkFunction("ackley", ackley, -32.0, 32.0, 0.0, 0.0),
        BenchmarkFunction("griewank", griewank, -600.0, 600.0, 0.0, 0.0),
        BenchmarkFunction("weierstrass", weierstrass, -0.5, 0.5, 0.0, 0.0),
    )
}
