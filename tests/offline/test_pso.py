"""Particle swarm optimisation (pipeline.offline.pso): finds known minima, is reproducible from its seed,
stays in the box, counts its evaluations, and rejects bad bounds and settings."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from pipeline.exceptions import InvalidParameterError
from pipeline.offline.pso import PsoConfig, PsoResult, minimize


def shifted_sphere(center: np.ndarray):
    def objective(x: np.ndarray) -> np.ndarray:
        return np.sum((x - center) ** 2, axis=-1)

    return objective


def rosenbrock(x: np.ndarray) -> np.ndarray:
    return np.sum(100.0 * (x[:, 1:] - x[:, :-1] ** 2) ** 2 + (1.0 - x[:, :-1]) ** 2, axis=-1)


@pytest.mark.parametrize("dimension", [2, 3, 4])
def test_shifted_sphere(dimension: int) -> None:
    center = np.array([0.7, -1.3, 2.1, -0.4])[:dimension]
    lower, upper = -3.0 * np.ones(dimension), 4.0 * np.ones(dimension)
    result = minimize(shifted_sphere(center), lower, upper, np.random.default_rng(1), PsoConfig(iterations=150))
    assert_allclose(result.x, center, rtol=0, atol=1e-4)
    assert result.value < 1e-8
    assert result.value == pytest.approx(float(shifted_sphere(center)(result.x[None])[0]), rel=0, abs=0)


@pytest.mark.parametrize(
    ("dimension", "iterations", "tolerance"),
    # The curved valley makes gbest PSO slow in 4-D: give it more iterations and a looser x tolerance.
    [(2, 1000, 1e-4), (3, 1000, 1e-3), (4, 3000, 5e-2)],
)
def test_rosenbrock(dimension: int, iterations: int, tolerance: float) -> None:
    lower, upper = -2.0 * np.ones(dimension), 2.0 * np.ones(dimension)
    config = PsoConfig(swarm_size=60, iterations=iterations, restarts=3)
    result = minimize(rosenbrock, lower, upper, np.random.default_rng(7), config)
    assert_allclose(result.x, np.ones(dimension), rtol=0, atol=tolerance)
    assert result.value < 1e-2 * tolerance


def test_minimum_on_the_boundary_is_found_and_bounds_are_respected() -> None:
    """The unconstrained minimum (5, -5) is outside the box [-1, 2]^2: the answer is the corner
    (2, -1), and no point outside the box is ever evaluated."""
    lower, upper = np.array([-1.0, -1.0]), np.array([2.0, 2.0])
    seen: list[np.ndarray] = []
    sphere = shifted_sphere(np.array([5.0, -5.0]))

    def objective(x: np.ndarray) -> np.ndarray:
        seen.append(x.copy())
        return sphere(x)

    result = minimize(objective, lower, upper, np.random.default_rng(3), PsoConfig(swarm_size=10, iterations=60))
    points = np.concatenate(seen)
    assert np.all(points >= lower) and np.all(points <= upper)
    assert np.all(result.restart_x >= lower) and np.all(result.restart_x <= upper)
    assert_allclose(result.x, [2.0, -1.0], rtol=0, atol=1e-9)


def test_initial_points_seed_the_first_swarm() -> None:
    """An initial point at the optimum is evaluated first and never lost."""
    center = np.array([0.123, -0.456, 0.789])
    first: list[np.ndarray] = []

    def objective(x: np.ndarray) -> np.ndarray:
        if not first:
            first.append(x.copy())
        return shifted_sphere(center)(x)

    config = PsoConfig(swarm_size=5, iterations=1, restarts=1)
    result = minimize(objective, -np.ones(3), np.ones(3), np.random.default_rng(0), config, initial=center)
    assert_array_equal(first[0][0], center)
    assert result.value == 0.0
    assert_array_equal(result.x, center)


def _run(seed: int) -> PsoResult:
    config = PsoConfig(swarm_size=12, iterations=30, restarts=2)
    return minimize(rosenbrock, -2.0 * np.ones(3), 2.0 * np.ones(3), np.random.default_rng(seed), config)


def test_same_seed_gives_a_bitwise_identical_result() -> None:
    a, b = _run(42), _run(42)
    assert_array_equal(a.x, b.x)
    assert a.value == b.value
    assert a.evaluations == b.evaluations
    assert_array_equal(a.history, b.history)
    assert_array_equal(a.restart_x, b.restart_x)
    assert_array_equal(a.restart_values, b.restart_values)


def test_different_seed_gives_a_different_history() -> None:
    a, b = _run(42), _run(43)
    assert a.history.shape == b.history.shape
    assert not np.array_equal(a.history, b.history)


@pytest.mark.parametrize(("swarm", "iterations", "restarts"), [(2, 1, 1), (8, 5, 1), (13, 7, 3), (40, 20, 4)])
def test_evaluation_count_and_history(swarm: int, iterations: int, restarts: int) -> None:
    calls = {"points": 0}

    def objective(x: np.ndarray) -> np.ndarray:
        calls["points"] += len(x)
        return np.sum(x * x, axis=-1)

    config = PsoConfig(swarm_size=swarm, iterations=iterations, restarts=restarts)
    result = minimize(objective, -np.ones(2), np.ones(2), np.random.default_rng(0), config)
    assert result.evaluations == swarm * (iterations + 1) * restarts == calls["points"]
    assert result.history.shape == (iterations * restarts,)
    assert result.restart_x.shape == (restarts, 2)
    assert result.restart_values.shape == (restarts,)
    # Each restart's best value never increases within the restart, and the result is the best restart.
    for history in result.history.reshape(restarts, iterations):
        assert np.all(np.diff(history) <= 0)
    assert result.value == result.restart_values.min()
    assert_array_equal(result.x, result.restart_x[int(np.argmin(result.restart_values))])
    assert_allclose(result.restart_values, np.sum(result.restart_x**2, axis=-1), rtol=0, atol=0)


@pytest.mark.parametrize(
    ("lower", "upper"),
    [
        ([0.0, 1.0], [1.0, 1.0]),  # zero width
        ([0.0, 2.0], [1.0, 1.0]),  # upper < lower
        ([0.0, 0.0], [1.0, 1.0, 1.0]),  # shapes differ
        ([[0.0, 0.0]], [[1.0, 1.0]]),  # not 1-D
        ([0.0, float("nan")], [1.0, 1.0]),
        ([0.0, 0.0], [1.0, float("nan")]),
    ],
)
def test_bad_bounds_raise(lower: list, upper: list) -> None:
    with pytest.raises(InvalidParameterError):
        minimize(shifted_sphere(np.zeros(2)), np.array(lower), np.array(upper), np.random.default_rng(0), PsoConfig())


@pytest.mark.parametrize(
    "kwargs",
    [
        {"swarm_size": 1},
        {"swarm_size": 0},
        {"swarm_size": 8.0},
        {"iterations": 0},
        {"iterations": True},
        {"restarts": 0},
        {"restarts": -1},
        {"inertia_start": -0.1},
        {"inertia_end": float("nan")},
        {"cognitive": -1.0},
        {"social": float("inf")},
        {"max_velocity_fraction": 0.0},
        {"max_velocity_fraction": -0.2},
    ],
)
def test_bad_config_raises(kwargs: dict) -> None:
    with pytest.raises(InvalidParameterError):
        PsoConfig(**kwargs)
