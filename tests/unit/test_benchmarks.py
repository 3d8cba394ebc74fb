import math

import numpy as np
import pytest

from planner.optimizers.benchmarks import (
    BENCHMARKS,
    ackley,
    griewank,
    rastrigin,
    rosenbrock,
    sphere,
    step,
    step_matlab,
    weierstrass,
)


@pytest.mark.parametrize("name", sorted(BENCHMARKS))
@pytest.mark.parametrize("dim", [1, 2, 30])
def test_known_optimum(name: str, dim: int) -> None:
    f = BENCHMARKS[name]
    value = f(f.minimiser(dim)[None, :])
    assert value.shape == (1,)
    assert value[0] == pytest.approx(f.optimum, abs=1e-12)


@pytest.mark.parametrize("name", sorted(BENCHMARKS))
def test_optimum_is_a_minimum_nearby(name: str) -> None:
    f = BENCHMARKS[name]
    rng = np.random.default_rng(0)
    lower, upper = f.bounds(5)
    points = np.clip(f.minimiser(5) + rng.normal(0, 0.3, (200, 5)), lower, upper)
    assert np.all(f(points) >= f.optimum - 1e-12)


@pytest.mark.parametrize("name", sorted(BENCHMARKS))
def test_vectorised_matches_row_by_row(name: str) -> None:
    f = BENCHMARKS[name]
    rng = np.random.default_rng(1)
    lower, upper = f.bounds(7)
    x = rng.uniform(lower, upper, (13, 7))
    rows = np.array([f(row[None, :])[0] for row in x])
    np.testing.assert_allclose(f(x), rows, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    ("function", "x", "expected"),
    [
        (sphere, [1.0, 2.0, 3.0], 14.0),
        (rosenbrock, [0.0, 0.0], 1.0),
        (rosenbrock, [1.0, 2.0], 100.0),
        (step, [0.4, -0.6, 1.5], 0.0 + 1.0 + 4.0),
        (step_matlab, [0.5, -0.5], 1.0),
        (rastrigin, [1.0, 0.5], 1.0 + 20.25),
        (ackley, [1.0, 1.0], 20.0 - 20.0 * math.exp(-0.2)),
        (griewank, [2.0 * math.pi], 4.0 * math.pi**2 / 4000.0),
        # cos(2π 3^k) = 1 and cos(π 3^k) = -1: twice the geometric sum of 0.5^k, k = 0..20.
        (weierstrass, [0.5], 4.0 - 2.0**-19),
    ],
)
def test_hand_computed_values(function, x: list[float], expected: float) -> None:
    assert function(np.array([x]))[0] == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_standard_bounds() -> None:
    expected = {
        "sphere": 100,
        "rosenbrock": 30,
        "step": 100,
        "rastrigin": 5.12,
        "ackley": 32,
        "griewank": 600,
        "weierstrass": 0.5,
    }
    for name, bound in expected.items():
        lower, upper = BENCHMARKS[name].bounds(3)
        assert np.all(lower == -bound) and np.all(upper == bound)
