"""The objective (pipeline.offline.fitness): Eq. 5 against a hand computation, fitness = sum of squared
residuals, the analytic and Coal clearance routes agree, when the penalty is active, and bad
settings."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import quad

from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL, CoalClearance
from pipeline.model.arm import PlanarArm
from pipeline.model.scene import Scene
from pipeline.motion.families import FAMILIES
from pipeline.motion.trajectory import joint_angles
from pipeline.offline.fitness import FitnessConfig, FitnessProblem, fitness_problem

D, SPEED, L1, L2 = 0.56, 0.2, 0.30, 0.35
TEST5 = np.array([-0.781, 0.996, 0.467, 1.116, 1.449, 0.864, 0.131, 0.543])  # Table 2, L = 0.25, W = 0.10
# Near the exact-endpoints optimum (w1, phi1, A2, w2) for L = 0.25, W = 0.10.
TEST5_EXACT = np.array([0.969, 0.471, 2.08, 0.712])
NEAR = {"paper": TEST5, "exact-endpoints": TEST5_EXACT}
# Small enough to be quick, large enough that every term of Eq. 5 is exercised.
SMALL = {"n_points": 21, "clearance_samples": 41}


def hand_eq5(parameters: np.ndarray, length: float, width: float, n: int, weighted: int, weight: float) -> float:
    """Eq. 5 from the paper and NOTES.md alone: n points uniform in x from P1 to P5 on the quartic
    through P1..P5, timed by arc length at v = 0.2 m/s (Eq. 7), tip by Eq. 2, end weights."""
    x1 = length / 2 + 0.12
    x2 = length / 2 + 0.03
    xs = np.array([x1, x2, 0.0, -x2, -x1])
    ys = np.array([D, D - width - 0.03, D - width - 0.10, D - width - 0.03, D])
    quartic = np.poly1d(np.polyfit(xs, ys, 4))
    slope = quartic.deriv()
    x = np.linspace(x1, -x1, n)
    times = np.array(
        [
            quad(lambda u: math.sqrt(1.0 + slope(u) ** 2), xj, x1, epsabs=1e-14, epsrel=1e-13, limit=200)[0] / SPEED
            for xj in x
        ]
    )
    a1, w1, p1, g1, a2, w2, p2, g2 = parameters
    th1 = a1 * np.sin(w1 * times + p1) + g1
    th2 = a2 * np.sin(w2 * times + p2) + g2
    xa = L1 * np.cos(th1) + L2 * np.cos(th1 + th2)
    ya = L1 * np.sin(th1) + L2 * np.sin(th1 + th2)
    squared = (x - xa) ** 2 + (quartic(x) - ya) ** 2
    weights = np.ones(n)
    weights[:weighted] = weight
    weights[-weighted:] = weight
    return float(np.sum(weights * squared))


def independent_penalty(problem: FitnessProblem, full: np.ndarray) -> tuple[float, bool]:
    """The clearance penalty from Coal distances at the penalty times, and whether it is inactive
    (every clearance above the margin and every elbow * theta2 above its minimum)."""
    config = problem.config
    q = joint_angles(full, problem.clearance_times_s)
    clearance = CoalClearance(problem.arm, problem.obstacle).link_clearance(q)
    elbow = config.elbow * q[:, 1]
    shortfall = np.concatenate(
        [
            np.maximum(0.0, problem.penalty_margin_m - clearance).ravel(),
            np.maximum(0.0, config.min_elbow_angle_rad - elbow),
        ]
    )
    inactive = bool(np.all(clearance > problem.penalty_margin_m) and np.all(elbow > config.min_elbow_angle_rad))
    return config.penalty_weight * float(np.sum(shortfall**2)), inactive


def tracking_part(problem: FitnessProblem, full: np.ndarray) -> np.ndarray:
    errors = problem.tracking_errors(full)
    return np.sum(problem.weights * np.sum(errors * errors, axis=-1), axis=-1)


# --------------------------------------------------------------------------------------------
# Eq. 5.


def test_eq5_by_hand_on_table_2_test_5_with_the_penalty_inactive(arm: PlanarArm, scene: Scene) -> None:
    config = FitnessConfig()
    problem = fitness_problem(arm, 0.25, 0.10, scene, config)
    penalty, inactive = independent_penalty(problem, TEST5)
    assert inactive and penalty == 0.0
    expected = hand_eq5(TEST5, 0.25, 0.10, config.n_points, 3, 100.0)
    assert_allclose(problem.evaluate(TEST5), expected, rtol=1e-9)
    # The end weights matter: without them the value is clearly smaller.
    assert hand_eq5(TEST5, 0.25, 0.10, config.n_points, 3, 1.0) < 0.9 * expected


@pytest.mark.parametrize(
    ("length", "width", "n", "weighted", "weight"), [(0.30, 0.12, 7, 3, 100.0), (0.2, 0.08, 33, 2, 50.0)]
)
def test_eq5_by_hand_on_random_parameters_without_penalty(
    arm: PlanarArm, scene: Scene, length: float, width: float, n: int, weighted: int, weight: float
) -> None:
    config = FitnessConfig(n_points=n, weighted_points=weighted, endpoint_weight=weight, penalty_weight=0.0)
    problem = fitness_problem(arm, length, width, scene, config)
    rng = np.random.default_rng(5)
    batch = TEST5 + rng.normal(scale=0.2, size=(6, 8))
    values = problem.evaluate(batch)
    assert values.shape == (6,)
    expected = [hand_eq5(p, length, width, n, weighted, weight) for p in batch]
    assert_allclose(values, expected, rtol=1e-9)


def test_path_points_and_weights(arm: PlanarArm, scene: Scene) -> None:
    problem = fitness_problem(arm, 0.30, 0.12, scene, FitnessConfig(n_points=11))
    assert_allclose(problem.targets_m[:, 0], np.linspace(0.27, -0.27, 11), rtol=0, atol=1e-15)
    assert_allclose(problem.targets_m[[0, -1], 1], [D, D], rtol=0, atol=1e-12)
    assert_allclose(problem.weights, [100, 100, 100, 1, 1, 1, 1, 1, 100, 100, 100], rtol=0, atol=0)
    assert problem.times_s[0] == 0.0
    assert problem.times_s[-1] == pytest.approx(problem.path.duration_s, rel=1e-12)
    assert np.all(np.diff(problem.times_s) > 0)


# --------------------------------------------------------------------------------------------
# Residuals and routes.


@pytest.mark.parametrize("family", FAMILIES.values(), ids=FAMILIES.keys())
def test_fitness_is_the_sum_of_squared_residuals(arm: PlanarArm, scene: Scene, family: str) -> None:
    problem = fitness_problem(arm, 0.25, 0.10, scene, FitnessConfig(**SMALL), family)
    lower, upper = family.search_bounds()
    rng = np.random.default_rng(2)
    batch = lower + rng.random((40, lower.size)) * (upper - lower)
    batch[:20] = NEAR[family.name] + rng.normal(scale=0.03, size=(20, lower.size))  # near the optimum
    values = problem.evaluate(batch)
    penalised = values > tracking_part(problem, problem.full_parameters(batch)) * (1 + 1e-9)
    assert penalised.any() and (~penalised).any()
    for free, value in zip(batch, values, strict=True):
        residuals = problem.residuals(free)
        assert_allclose(np.sum(residuals**2), value, rtol=1e-12)
        assert_allclose(problem.evaluate(free), value, rtol=1e-12)  # unbatched == batched


@pytest.mark.parametrize("family", FAMILIES.values(), ids=FAMILIES.keys())
def test_analytic_and_coal_routes_give_the_same_fitness(arm: PlanarArm, scene: Scene, family: str) -> None:
    """Equal wherever no sample has a link overlapping the obstacle: tracking-only parameters,
    and penalised ones (0 < clearance < penalty margin, or elbow below its minimum)."""
    fast = fitness_problem(arm, 0.25, 0.10, scene, FitnessConfig(**SMALL), family)
    exact = fitness_problem(arm, 0.25, 0.10, scene, FitnessConfig(**SMALL, clearance_route=COAL), family)
    rng = np.random.default_rng(9)
    lower, upper = family.search_bounds()
    batch = lower + rng.random((300, lower.size)) * (upper - lower)
    batch[:150] = NEAR[family.name] + rng.normal(scale=0.08, size=(150, lower.size))
    full = fast.full_parameters(batch)
    clearance = fast.clearance(full).min(axis=(-2, -1))
    overlap = clearance <= 0
    penalised_clear = (clearance > 0) & (clearance < fast.penalty_margin_m)
    assert penalised_clear.sum() >= 5, "the batch must contain penalised, non-overlapping parameters"
    keep = ~overlap
    assert_allclose(exact.evaluate(batch[keep]), fast.evaluate(batch[keep]), rtol=1e-9)
    # Where a link overlaps the obstacle the two routes measure the overlap differently
    # (Coal: penetration depth; analytic: minus the radii), but both penalise it.
    if overlap.any():
        floor = fast.config.penalty_weight * fast.penalty_margin_m**2
        tracking = tracking_part(fast, full[overlap])
        assert np.all(exact.evaluate(batch[overlap]) - tracking > floor)
        assert np.all(fast.evaluate(batch[overlap]) - tracking > floor)


def test_penalty_is_zero_iff_clearances_and_elbow_clear_their_minimums(arm: PlanarArm, scene: Scene) -> None:
    problem = fitness_problem(arm, 0.25, 0.10, scene, FitnessConfig(**SMALL))
    rng = np.random.default_rng(4)
    batch = TEST5 + rng.normal(scale=0.06, size=(80, 8))
    penalties = problem.evaluate(batch) - tracking_part(problem, batch)
    overlaps = problem.clearance(batch).min(axis=(-2, -1)) <= 0
    outcomes = []
    for parameters, penalty, overlap in zip(batch, penalties, overlaps, strict=True):
        expected, inactive = independent_penalty(problem, parameters)
        outcomes.append(inactive)
        assert (penalty == 0.0) == inactive
        if not overlap:  # the penalty's value by hand (Coal distances) where no link overlaps
            assert_allclose(penalty, expected, rtol=1e-9, atol=1e-15)
    assert any(outcomes) and not all(outcomes)
    assert (~overlaps & ~np.array(outcomes)).any()


def test_elbow_term_alone_activates_the_penalty(arm: PlanarArm, scene: Scene) -> None:
    """Test 5 has theta2 > 0 throughout: on the elbow = -1 branch only the elbow term is active,
    and it equals penalty_weight * sum (min + theta2)^2."""
    config = FitnessConfig(**SMALL, elbow=-1)
    problem = fitness_problem(arm, 0.25, 0.10, scene, config)
    theta2 = joint_angles(TEST5, problem.clearance_times_s)[:, 1]
    assert np.all(theta2 > 0)
    up = fitness_problem(arm, 0.25, 0.10, scene, FitnessConfig(**SMALL))
    assert up.evaluate(TEST5) == pytest.approx(tracking_part(up, TEST5), rel=0, abs=0)
    expected = config.penalty_weight * np.sum((config.min_elbow_angle_rad + theta2) ** 2)
    assert_allclose(problem.evaluate(TEST5) - tracking_part(problem, TEST5), expected, rtol=1e-10)


def test_penalty_margin_defaults_to_scene_margin_plus_buffer(arm: PlanarArm) -> None:
    scene = Scene(margin_m=0.02)
    assert fitness_problem(arm, 0.25, 0.1, scene, FitnessConfig(margin_buffer_m=0.003)).penalty_margin_m == (
        pytest.approx(0.023, abs=1e-15)
    )
    assert fitness_problem(arm, 0.25, 0.1, scene, FitnessConfig(penalty_margin_m=0.005)).penalty_margin_m == 0.005


# --------------------------------------------------------------------------------------------
# Bad settings.


@pytest.mark.parametrize(
    "kwargs",
    [
        {"n_points": 6},
        {"n_points": 20.0},
        {"weighted_points": 0},
        {"n_points": 7, "weighted_points": 4},
        {"n_points": 10, "weighted_points": 5},
        {"endpoint_weight": 0.0},
        {"endpoint_weight": float("nan")},
        {"clearance_samples": 1},
        {"penalty_weight": -1.0},
        {"penalty_weight": float("inf")},
        {"penalty_margin_m": -0.001},
        {"penalty_margin_m": float("nan")},
        {"margin_buffer_m": -0.001},
        {"clearance_route": "fcl"},
        {"elbow": 0},
        {"elbow": 2},
        {"min_elbow_angle_rad": -0.1},
        {"n_points": True},
    ],
)
def test_bad_fitness_config_raises(kwargs: dict) -> None:
    with pytest.raises(InvalidParameterError):
        FitnessConfig(**kwargs)


@pytest.mark.parametrize(("length", "width"), [(float("nan"), 0.1), (0.25, 0.0), (-0.25, 0.1), (0.25, float("inf"))])
def test_bad_obstacle_size_raises(arm: PlanarArm, scene: Scene, length: float, width: float) -> None:
    with pytest.raises(InvalidParameterError):
        fitness_problem(arm, length, width, scene, FitnessConfig())


def test_unknown_family_raises(arm: PlanarArm, scene: Scene) -> None:
    with pytest.raises(InvalidParameterError):
        fitness_problem(arm, 0.25, 0.10, scene, FitnessConfig(), "free")
