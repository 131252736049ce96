"""The online generator (pipeline.online.generator): Eq. 9 evaluated at (L, W), the path's duration,
the out-of-range policies, bad and impossible obstacles, and batch == single queries for both
families."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import quad

from pipeline.exceptions import (
    InvalidParameterError,
    OutOfFittedRangeError,
    OutOfFittedRangeWarning,
    UnreachableObstacleError,
)
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.families import EXACT_ENDPOINTS, endpoint_context
from pipeline.motion.path import desired_path
from pipeline.motion.trajectory import PARAMETER_NAMES, joint_angles
from pipeline.offline.coefficients import Coefficients
from pipeline.online.generator import generate, generate_parameters

D, SPEED = 0.56, 0.2
QUERIES = [(0.25, 0.10), (0.22, 0.09), (0.28, 0.115), (0.2, 0.08), (0.3, 0.12), (0.215, 0.105)]


def eq9_by_hand(eq9, L: float, W: float) -> np.ndarray:
    return np.array([b[0] + b[1] * L + b[2] * W + b[3] * L * L + b[4] * L * W + b[5] * W * W for b in eq9.values()])


def duration_by_hand(L: float, W: float) -> float:
    """T = S_total / v for the quartic through P1..P5 (NOTES.md), by adaptive quadrature."""
    x1, x2 = L / 2 + 0.12, L / 2 + 0.03
    quartic = np.poly1d(
        np.polyfit([x1, x2, 0.0, -x2, -x1], [D, D - W - 0.03, D - W - 0.10, D - W - 0.03, D], 4)
    ).deriv()
    length, _ = quad(lambda x: math.sqrt(1 + quartic(x) ** 2), -x1, x1, epsabs=1e-14, epsrel=1e-13, limit=200)
    return length / SPEED


# --------------------------------------------------------------------------------------------
# The paper's Eq. 9.


@pytest.mark.parametrize(("L", "W"), QUERIES)
def test_generate_gives_eq9_and_the_path_duration(paper: Coefficients, paper_eq9, rounding, L: float, W: float) -> None:
    trajectory = generate(paper, L, W)
    assert trajectory.family.name == "paper"
    assert not trajectory.extrapolated
    assert_allclose(trajectory.trajectory.parameters, eq9_by_hand(paper_eq9, L, W), rtol=0, atol=1e-12)
    scene = Scene()
    expected_path = desired_path(Obstacle.in_scene(L, W, scene), scene)
    numpy_duration, bound = rounding.duration(scene, L, W)
    assert expected_path.duration_s == numpy_duration
    assert abs(trajectory.duration_s - numpy_duration) <= bound
    assert_allclose(trajectory.duration_s, duration_by_hand(L, W), rtol=1e-10)
    assert_allclose(trajectory.path.points_m, expected_path.points_m, rtol=0, atol=0)
    # q(t) is Eq. 1 with those parameters.
    t = np.linspace(0, trajectory.duration_s, 7)
    a1, w1, p1, g1, a2, w2, p2, g2 = eq9_by_hand(paper_eq9, L, W)
    assert_allclose(
        trajectory.q(t),
        np.column_stack([a1 * np.sin(w1 * t + p1) + g1, a2 * np.sin(w2 * t + p2) + g2]),
        rtol=0,
        atol=1e-12,
    )


def test_generate_at_test_5_is_close_to_table_2(paper: Coefficients, table2: np.ndarray) -> None:
    parameters = generate(paper, 0.25, 0.10).trajectory.parameters
    assert_allclose(parameters, table2[4, :8], rtol=0, atol=0.02)


# --------------------------------------------------------------------------------------------
# Out of range, bad and impossible obstacles.


@pytest.mark.parametrize(("L", "W"), [(0.31, 0.10), (0.19, 0.10), (0.25, 0.13), (0.25, 0.07), (0.35, 0.06)])
def test_out_of_range_policies(paper: Coefficients, paper_eq9, L: float, W: float) -> None:
    with pytest.warns(OutOfFittedRangeWarning):
        warned = generate(paper, L, W, out_of_range="warn")
    assert warned.extrapolated
    with pytest.raises(OutOfFittedRangeError) as info:
        generate(paper, L, W, out_of_range="error")
    assert info.value.name in ("L", "W")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ignored = generate(paper, L, W, out_of_range="ignore")
    assert ignored.extrapolated
    assert_allclose(ignored.trajectory.parameters, eq9_by_hand(paper_eq9, L, W), rtol=0, atol=1e-12)
    assert ignored.trajectory.parameters == warned.trajectory.parameters


def test_default_policy_warns(paper: Coefficients) -> None:
    with pytest.warns(OutOfFittedRangeWarning):
        generate(paper, 0.32, 0.10)


@pytest.mark.parametrize(("L", "W"), [(0.2, 0.08), (0.3, 0.12), (0.25, 0.1)])
def test_in_range_is_silent_under_every_policy(paper: Coefficients, L: float, W: float) -> None:
    for policy in ("warn", "error", "ignore"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert not generate(paper, L, W, out_of_range=policy).extrapolated


def test_unknown_policy_raises(paper: Coefficients) -> None:
    with pytest.raises(InvalidParameterError):
        generate(paper, 0.25, 0.1, out_of_range="clip")


@pytest.mark.parametrize(
    ("L", "W"),
    [
        (float("nan"), 0.1),
        (0.25, float("nan")),
        (-0.25, 0.1),
        (0.25, -0.1),
        (0.0, 0.1),
        (0.25, 0.0),
        (float("inf"), 0.1),
    ],
)
@pytest.mark.parametrize("policy", ["warn", "error", "ignore"])
def test_bad_sizes_raise(paper: Coefficients, L: float, W: float, policy: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an invalid size is an error, not a range warning
        with pytest.raises(InvalidParameterError):
            generate(paper, L, W, out_of_range=policy)


@pytest.mark.parametrize(("L", "W"), [(1.5, 0.1), (0.8, 0.1), (0.25, 0.46)])
def test_impassable_obstacle_raises(paper: Coefficients, exact: Coefficients, L: float, W: float) -> None:
    for coefficients in (paper, exact):
        with pytest.raises(UnreachableObstacleError) as info:
            generate(coefficients, L, W, out_of_range="ignore")
        assert info.value.point_name in ("P1", "P2", "P3", "P4", "P5")
        assert not info.value.reach_m[0] <= info.value.radius_m <= info.value.reach_m[1]


# --------------------------------------------------------------------------------------------
# Batch == single queries.


@pytest.mark.parametrize("family", ["paper", "exact-endpoints"])
def test_generate_parameters_batch_equals_single_queries(paper: Coefficients, exact: Coefficients, family: str) -> None:
    coefficients = paper if family == "paper" else exact
    L = np.array([q[0] for q in QUERIES])
    W = np.array([q[1] for q in QUERIES])
    batch = generate_parameters(coefficients, L, W)
    assert batch.shape == (len(QUERIES), 8)
    for row, (length, width) in zip(batch, QUERIES, strict=True):
        single = generate(coefficients, length, width)
        assert_allclose(row, single.trajectory.parameters, rtol=0, atol=1e-13)
        t = np.linspace(0, single.duration_s, 11)
        assert_allclose(joint_angles(row, t), single.q(t), rtol=0, atol=1e-12)


def test_exact_endpoints_generator_pins_the_tip(arm: PlanarArm, exact: Coefficients, rounding) -> None:
    for L, W in QUERIES:
        generated = generate(exact, L, W)
        free, bound = rounding.regression(exact, L, W)
        context = endpoint_context(generated.path, arm.link_lengths_m, exact.elbow)
        assert_allclose(generated.trajectory.parameters, EXACT_ENDPOINTS.expand(free, context), rtol=0, atol=1e-12)
        tips = arm.end_effector_planar(generated.q(np.array([0.0, generated.duration_s])))
        assert_allclose(tips[0], generated.path.points_m[0], rtol=0, atol=1e-9)
        assert_allclose(tips[1], generated.path.points_m[-1], rtol=0, atol=1e-9)
        kept = generated.trajectory.as_dict()
        for name, value, most in zip(("w1", "phi1", "A2", "w2"), free, bound, strict=True):
            assert abs(kept[name] - value) <= most, name  # the free parameters, as the regression gave them


def test_parameter_names_order(paper_eq9) -> None:
    assert tuple(paper_eq9) == PARAMETER_NAMES
