from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import planner
from planner import (
    ALGORITHMS,
    ObjectiveError,
    OptimizeResult,
    OptimizerInputError,
    UnknownAlgorithmError,
)
from planner.optimizers.benchmarks import sphere

NAMES = sorted(ALGORITHMS)


def run(name: str, seed: int = 0, **kwargs: Any) -> OptimizeResult:
    options: dict[str, Any] = {
        "population": 12,
        "iterations": 40,
        "rng": np.random.default_rng(seed),
    }
    options.update(kwargs)
    return planner.optimize(name, sphere, -np.ones(4) * 5, np.ones(4) * 5, **options)


def test_registry_names() -> None:
    assert set(ALGORITHMS) == {"mvo", "alo", "da", "gwo", "mfo", "woa"}
    for name in NAMES:
        assert planner.get_algorithm(name.upper()).name == name


@pytest.mark.parametrize("name", NAMES)
def test_result_contract(name: str) -> None:
    result = run(name)
    assert result.algorithm == name
    assert result.history.shape == (40,)
    assert result.nfe == 12 * 40
    np.testing.assert_array_equal(result.nfe_history, 12 * np.arange(1, 41))
    assert np.all(np.diff(result.history) <= 0), "best-so-far must never get worse"
    assert result.best_cost == result.history[-1]
    assert sphere(result.best_x[None, :])[0] == result.best_cost
    assert np.all(np.abs(result.best_x) <= 5)
    assert result.seconds > 0


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_same_run_other_seed_other_run(name: str) -> None:
    a, b, c = run(name, seed=3), run(name, seed=3), run(name, seed=4)
    np.testing.assert_array_equal(a.history, b.history)
    np.testing.assert_array_equal(a.best_x, b.best_x)
    assert not np.array_equal(a.history, c.history)


@pytest.mark.parametrize("name", NAMES)
def test_makes_progress_on_sphere(name: str) -> None:
    result = run(name, population=20, iterations=300)
    assert result.best_cost < result.history[0] / 100


@pytest.mark.parametrize("name", NAMES)
def test_objective_sees_whole_populations(name: str) -> None:
    shapes = []

    def objective(x: np.ndarray) -> np.ndarray:
        shapes.append(x.shape)
        return sphere(x)

    planner.optimize(
        name,
        objective,
        [-1.0] * 3,
        [1.0] * 3,
        population=9,
        iterations=15,
        rng=np.random.default_rng(0),
    )
    assert shapes == [(9, 3)] * 15


@pytest.mark.parametrize("name", NAMES)
def test_callback_sees_every_iteration_and_can_stop(name: str) -> None:
    seen = []

    def callback(progress: planner.Progress) -> bool:
        seen.append((progress.iteration, progress.nfe))
        return progress.iteration == 7

    result = run(name, callback=callback)
    assert seen == [(i, 12 * i) for i in range(1, 8)]
    assert result.history.size == 7
    assert result.nfe == 12 * 7


def test_nfe_to_reach() -> None:
    result = run("gwo", iterations=200)
    target = result.history[50]
    reached = result.nfe_to_reach(target)
    assert reached is not None and reached <= 12 * 51
    assert result.nfe_to_reach(-1.0) is None


def test_scalar_bounds_with_dim() -> None:
    result = planner.optimize(
        "mvo", sphere, -2.0, 2.0, dim=6, population=5, iterations=3, rng=np.random.default_rng(0)
    )
    assert result.best_x.shape == (6,)


@pytest.mark.parametrize(
    ("lower", "upper", "message"),
    [
        ([0.0, 1.0], [1.0, 1.0], "dimension 1 has lower=1.0 >= upper=1.0"),
        ([0.0, np.nan], [1.0, 2.0], "finite"),
        ([0.0, -np.inf], [1.0, 2.0], "finite"),
        ([0.0, 0.0], [1.0, 1.0, 1.0], "differ in length"),
        ([[0.0]], [[1.0]], "1-D"),
        (0.0, 1.0, "need dim"),
        (["a"], [1.0], "numbers"),
    ],
)
def test_bad_bounds(lower, upper, message: str) -> None:
    with pytest.raises(OptimizerInputError, match=message):
        planner.optimize(
            "mvo", sphere, lower, upper, population=5, iterations=3, rng=np.random.default_rng(0)
        )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"population": 1}, "population of at least 2"),
        ({"population": 2, "algorithm": "gwo"}, "gwo needs a population of at least 3"),
        ({"population": 4.5}, "population must be an integer"),
        ({"iterations": 0}, "iterations must be at least 1"),
        ({"rng": 42}, "numpy.random.Generator"),
        ({"algorithm": "pso"}, "unknown algorithm 'pso'; choose one of alo, da, gwo"),
    ],
)
def test_bad_budget(kwargs: dict[str, Any], message: str) -> None:
    options: dict[str, Any] = {
        "algorithm": "mvo",
        "population": 5,
        "iterations": 3,
        "rng": np.random.default_rng(0),
    }
    options.update(kwargs)
    algorithm = options.pop("algorithm")
    with pytest.raises(OptimizerInputError, match=message):
        planner.optimize(algorithm, sphere, [0.0], [1.0], **options)


def test_unknown_algorithm_is_also_a_key_error() -> None:
    with pytest.raises(KeyError):
        planner.get_algorithm("nope")
    assert issubclass(UnknownAlgorithmError, ValueError)


@pytest.mark.parametrize(
    ("objective", "message"),
    [
        (lambda x: np.zeros((x.shape[0], 1)), r"must return shape \(5,\).*got shape \(5, 1\)"),
        (lambda x: np.zeros(x.shape[0] + 1), r"got shape \(6,\)"),
        (lambda x: np.full(x.shape[0], np.nan), "returned nan for row 0"),
        (lambda x: np.where(np.arange(x.shape[0]) == 2, np.inf, 0.0), "returned inf for row 2"),
        (lambda x: ["a"] * x.shape[0], "objective failed"),
        ("not callable", "callable"),
    ],
)
def test_bad_objective(objective, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        planner.optimize(
            "woa",
            objective,
            [0.0],
            [1.0],
            population=5,
            iterations=3,
            rng=np.random.default_rng(0),
        )


def test_objective_errors_are_typed() -> None:
    with pytest.raises(ObjectiveError):
        planner.optimize(
            "mfo",
            lambda x: x,
            [0.0, 0.0],
            [1.0, 1.0],
            population=5,
            iterations=3,
            rng=np.random.default_rng(0),
        )


@settings(max_examples=25, deadline=None)
@given(
    name=st.sampled_from(NAMES),
    dim=st.integers(1, 6),
    population=st.integers(3, 15),
    iterations=st.integers(1, 25),
    seed=st.integers(0, 2**32 - 1),
    offset=st.floats(-1e3, 1e3),
    width=st.floats(1e-3, 1e3),
)
def test_any_box_any_budget(name, dim, population, iterations, seed, offset, width) -> None:
    lower = np.full(dim, offset)
    upper = lower + width
    result = planner.optimize(
        name,
        sphere,
        lower,
        upper,
        population=population,
        iterations=iterations,
        rng=np.random.default_rng(seed),
    )
    assert result.nfe == population * iterations
    assert result.history.size == iterations
    assert np.all((result.best_x >= lower) & (result.best_x <= upper))
    assert sphere(result.best_x[None, :])[0] == result.best_cost
