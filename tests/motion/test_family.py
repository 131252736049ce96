"""Trajectory families (pipeline.motion.families): the exact-endpoints construction pins the tip to P1
and P5, joint 2's pinned phase, analytic inverse kinematics on both elbow branches, and the
canonical free parameters (same motion, one representation)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pipeline.exceptions import InvalidParameterError, UnreachableObstacleError
from pipeline.model.arm import PlanarArm
from pipeline.model.kinematics import inverse_kinematics
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.families import (
    EXACT_ENDPOINTS,
    FAMILIES,
    PAPER,
    EndpointContext,
    TrajectoryFamily,
    endpoint_context,
    family_from_name,
)
from pipeline.motion.families.exact_endpoints import MIN_DENOMINATOR
from pipeline.motion.path import QuarticPath, desired_path
from pipeline.motion.trajectory import joint_angles

L1, L2 = 0.30, 0.35
HALF_PI = math.pi / 2
# Obstacles over and a little beyond the DOE range.
SIZES = [(0.30, 0.12), (0.25, 0.10), (0.20, 0.08), (0.17, 0.07), (0.23, 0.115)]


def eq2(q: np.ndarray) -> np.ndarray:
    """The paper's Eq. 2 written out for l1 = 0.30, l2 = 0.35: tip (x, y) of q (..., 2)."""
    q = np.asarray(q, dtype=float)
    a1, a12 = q[..., 0], q[..., 0] + q[..., 1]
    return np.stack([L1 * np.cos(a1) + L2 * np.cos(a12), L1 * np.sin(a1) + L2 * np.sin(a12)], -1)


def path_for(length: float, width: float) -> QuarticPath:
    scene = Scene()
    return desired_path(Obstacle.in_scene(length, width, scene), scene)


def random_free(family: TrajectoryFamily, rng: np.random.Generator, count: int) -> np.ndarray:
    lower, upper = family.search_bounds()
    return lower + rng.random((count, lower.size)) * (upper - lower)


def unclamped(free: np.ndarray, duration_s: float) -> np.ndarray:
    """Rows of exact-endpoints free parameters for which expand does not clamp A1."""
    w1, phi1 = free[:, 0], free[:, 1]
    return np.abs(np.sin(w1 * duration_s + phi1) - np.sin(phi1)) > 1.01 * MIN_DENOMINATOR


# --------------------------------------------------------------------------------------------
# Exact endpoints.


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("elbow", [1, -1])
def test_exact_endpoints_pin_the_tip_to_p1_and_p5(arm: PlanarArm, size: tuple[float, float], elbow: int) -> None:
    path = path_for(*size)
    context = endpoint_context(path, arm.link_lengths_m, elbow)
    rng = np.random.default_rng(hash((size, elbow)) % 2**32)
    free = random_free(EXACT_ENDPOINTS, rng, 400)
    free = free[unclamped(free, context.duration_s)]
    assert len(free) > 300
    full = EXACT_ENDPOINTS.expand(free, context)
    assert full.shape == (len(free), 8)
    q = joint_angles(full, np.array([0.0, path.duration_s]))  # (P, 2, 2)
    tips = arm.end_effector_planar(q)
    assert_allclose(tips[:, 0], np.broadcast_to(path.points_m[0], tips[:, 0].shape), rtol=0, atol=1e-9)
    assert_allclose(tips[:, 1], np.broadcast_to(path.points_m[-1], tips[:, 1].shape), rtol=0, atol=1e-9)
    # ... and on the requested elbow branch at both ends.
    assert np.all(elbow * q[:, :, 1] > 0)
    # The free parameters pass through unchanged.
    assert_allclose(full[:, [1, 2, 4, 5]], free, rtol=0, atol=0)


def test_endpoint_context_is_the_inverse_kinematics_of_p1_and_p5(arm: PlanarArm) -> None:
    path = path_for(0.25, 0.10)
    context = endpoint_context(path, arm.link_lengths_m, 1)
    assert context.duration_s == path.duration_s
    assert_allclose(eq2(np.array(context.theta_start_rad)), path.points_m[0], rtol=0, atol=1e-12)
    assert_allclose(eq2(np.array(context.theta_end_rad)), path.points_m[-1], rtol=0, atol=1e-12)
    # P1 and P5 are mirror images: the same elbow angle at both ends.
    assert context.theta_start_rad[1] == pytest.approx(context.theta_end_rad[1], abs=1e-12)


def test_clamped_denominator_keeps_a1_bounded(arm: PlanarArm) -> None:
    """Where sin(w1 T + phi1) = sin(phi1) (w1 T = pi - 2 phi1) A1 would be infinite; it is clamped."""
    context = endpoint_context(path_for(0.25, 0.10), arm.link_lengths_m, 1)
    T = context.duration_s
    phi1 = 0.3
    w1 = (math.pi - 2 * phi1) / T
    full = EXACT_ENDPOINTS.expand(np.array([w1, phi1, 1.0, 0.8]), context)
    delta = abs(context.theta_end_rad[0] - context.theta_start_rad[0])
    assert np.all(np.isfinite(full))
    assert abs(full[0]) == pytest.approx(delta / MIN_DENOMINATOR, rel=1e-9)
    # The start point is still exact (gamma1 follows A1).
    assert_allclose(joint_angles(full, np.array([0.0]))[0], context.theta_start_rad, rtol=0, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.floats(0.2, 2.5), st.floats(2.0, 5.0), st.floats(-3.0, 3.0), st.floats(0.2, 2.5), st.floats(-1.5, 1.5))
@example(0.768, 3.7, 1.633, 1.0, 0.2)
@example(1.0, 2.7421875, 0.0, 1.0, 0.2)  # sin(w1 T + phi1) = sin(phi1): A1 is clamped
def test_joint_2_phase_is_pinned_and_joint_1_is_exact_wherever_the_family_says_so(
    w2: float, duration_s: float, a2: float, w1: float, phi1: float
) -> None:
    """phi2 = (pi - w2 T) / 2, hence sin(w2 T + phi2) = sin(phi2) and theta2(T) = theta2(0),
    for every draw. Joint 1 reaches both ends exactly wherever ``endpoints_exact`` says so; where
    it says not, the denominator sin(w1 T + phi1) - sin(phi1) was clamped."""
    context = EndpointContext((1.1, 0.4), (2.0, 0.4), duration_s)
    free = np.array([w1, phi1, a2, w2])
    full = EXACT_ENDPOINTS.expand(free, context)
    phi2 = full[6]
    assert phi2 == pytest.approx((math.pi - w2 * duration_s) / 2, abs=1e-15)
    assert math.sin(w2 * duration_s + phi2) == pytest.approx(math.sin(phi2), abs=1e-12)
    q = joint_angles(full, np.array([0.0, duration_s]))
    assert_allclose(q[:, 1], [0.4, 0.4], rtol=0, atol=1e-12)
    assert q[0, 0] == pytest.approx(1.1, abs=1e-12)  # the start is exact either way (gamma1 follows A1)
    denominator = math.sin(w1 * duration_s + phi1) - math.sin(phi1)
    if EXACT_ENDPOINTS.endpoints_exact(free, context):
        assert abs(denominator) >= MIN_DENOMINATOR
        assert q[1, 0] == pytest.approx(2.0, abs=1e-9)
    else:
        assert abs(denominator) < MIN_DENOMINATOR
        assert abs(full[0]) == pytest.approx(0.9 / MIN_DENOMINATOR, rel=1e-9)


def test_paper_family_expand_is_the_identity() -> None:
    free = np.random.default_rng(3).normal(size=(5, 8))
    assert_allclose(PAPER.expand(free, None), free, rtol=0, atol=0)


def test_exact_endpoints_needs_a_context() -> None:
    with pytest.raises(InvalidParameterError):
        EXACT_ENDPOINTS.expand(np.array([1.0, 0.2, 1.0, 0.8]), None)


def test_families_are_found_by_name_and_unknown_names_are_rejected() -> None:
    assert family_from_name("paper") is PAPER
    assert family_from_name("exact-endpoints") is EXACT_ENDPOINTS
    for bad in ("Paper", "exact_endpoints", "", "sinusoid", None, 3):
        with pytest.raises(InvalidParameterError) as info:
            family_from_name(bad)
        assert info.value.value == bad


@pytest.mark.parametrize("family", FAMILIES.values(), ids=FAMILIES.keys())
def test_search_bounds_cover_the_free_parameters(family: TrajectoryFamily) -> None:
    lower, upper = family.search_bounds()
    names = family.free_parameter_names
    assert lower.shape == upper.shape == (len(names),)
    assert np.all(upper > lower)
    for name, lo, hi in zip(names, lower, upper, strict=True):
        if name.startswith("w"):
            assert lo > 0  # canonical frequencies are positive
        if name.startswith("phi"):
            assert (lo, hi) == pytest.approx((-HALF_PI, HALF_PI), abs=1e-15)


# --------------------------------------------------------------------------------------------
# Inverse kinematics.


reachable_points = st.tuples(st.floats(0.06, 0.64), st.floats(-math.pi, math.pi))


@settings(max_examples=200, deadline=None)
@given(reachable_points)
@example((0.27 * math.sqrt(1 + (0.56 / 0.27) ** 2), math.atan2(0.56, 0.27)))  # P1 of Test 1
def test_inverse_kinematics_round_trips_through_eq2_on_both_branches(polar: tuple[float, float]) -> None:
    radius, angle = polar
    point = np.array([radius * math.cos(angle), radius * math.sin(angle)])
    up = inverse_kinematics(point, (L1, L2), elbow=1)
    down = inverse_kinematics(point, (L1, L2), elbow=-1)
    assert_allclose(eq2(up), point, rtol=0, atol=1e-9)
    assert_allclose(eq2(down), point, rtol=0, atol=1e-9)
    # The branches mirror the elbow: theta2 >= 0 for elbow = +1, <= 0 for elbow = -1.
    assert up[1] >= 0 >= down[1]
    assert up[1] == pytest.approx(-down[1], abs=1e-12)


@pytest.mark.parametrize("radius", [0.6501, 0.7, 1.5, 0.0499, 0.01, 0.0])
def test_inverse_kinematics_beyond_reach_raises(radius: float) -> None:
    point = np.array([radius * math.cos(0.7), radius * math.sin(0.7)])
    for elbow in (1, -1):
        with pytest.raises(UnreachableObstacleError) as info:
            inverse_kinematics(point, (L1, L2), elbow)
        assert info.value.radius_m == pytest.approx(radius, abs=1e-15)
        assert info.value.reach_m == pytest.approx((0.05, 0.65), abs=1e-15)


def test_inverse_kinematics_at_the_boundary_of_reach() -> None:
    """Fully stretched (|p| = l1 + l2): theta2 = 0; the boundary is reachable."""
    q = inverse_kinematics(np.array([0.0, 0.65]), (L1, L2), 1)
    assert_allclose(q, [HALF_PI, 0.0], rtol=0, atol=1e-7)


# --------------------------------------------------------------------------------------------
# Canonical free parameters.


@pytest.mark.parametrize("family", FAMILIES.values(), ids=FAMILIES.keys())
def test_canonical_free_then_expand_is_the_same_motion(arm: PlanarArm, family: TrajectoryFamily) -> None:
    """canonical_free + expand reproduces the joint angles of the original free parameters,
    also from non-canonical inputs (w1 < 0, phases beyond [-pi/2, pi/2))."""
    path = path_for(0.25, 0.10)
    context = endpoint_context(path, arm.link_lengths_m, 1)
    rng = np.random.default_rng(11)
    free = random_free(family, rng, 500)
    # Non-canonical equivalents: negate frequencies and shift phases by up to 3 half-turns.
    if family is PAPER:
        free[:, [1, 2, 5, 6]] *= rng.choice([-1.0, 1.0], size=(len(free), 4))
        free[:, [2, 6]] += math.pi * rng.integers(-3, 4, size=(len(free), 2))
    else:
        free[:, 1] += math.pi * rng.integers(-3, 4, size=len(free))
        sign = rng.choice([-1.0, 1.0], size=len(free))
        free[:, 0] *= sign
        free[:, 1] *= sign
        free = free[unclamped(free, context.duration_s)]
    canonical = family.canonical_free(free)
    t = np.linspace(0.0, path.duration_s, 101)
    before = joint_angles(family.expand(free, context), t)
    after = joint_angles(family.expand(canonical, context), t)
    assert_allclose(after, before, rtol=0, atol=1e-9)
    # Canonical: idempotent, w1 >= 0 and phi1 in [-pi/2, pi/2).
    assert_allclose(family.canonical_free(canonical), canonical, rtol=0, atol=1e-12)
    w1, phi1 = (canonical[:, 1], canonical[:, 2]) if family is PAPER else (canonical[:, 0], canonical[:, 1])
    assert np.all(w1 >= 0)
    assert np.all((phi1 >= -HALF_PI) & (phi1 < HALF_PI))


def test_canonical_free_of_table_2_is_table_2(table2: np.ndarray) -> None:
    parameters = np.array(table2[:, :8])
    assert_allclose(PAPER.canonical_free(parameters), parameters, rtol=0, atol=1e-15)


def test_exact_endpoints_equal_motions_get_equal_canonical_parameters(arm: PlanarArm) -> None:
    """With phi2 pinned to (pi - w2 T) / 2, joint 2 moves as A2 cos(w2 (t - T/2)) + const, so
    (A2, w2) and (A2, -w2) are the same motion. One canonical form means w2 >= 0 for both."""
    context = endpoint_context(path_for(0.25, 0.10), arm.link_lengths_m, 1)
    free = np.array([0.99, 0.46, 1.45, 0.86])
    mirrored = free * np.array([1.0, 1.0, 1.0, -1.0])
    t = np.linspace(0.0, context.duration_s, 101)
    # Same motion ...
    assert_allclose(
        joint_angles(EXACT_ENDPOINTS.expand(mirrored, context), t),
        joint_angles(EXACT_ENDPOINTS.expand(free, context), t),
        rtol=0,
        atol=1e-12,
    )
    # ... so the same canonical free parameters (what the regression fits).
    assert_allclose(EXACT_ENDPOINTS.canonical_free(mirrored), EXACT_ENDPOINTS.canonical_free(free), rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------------
# Derivatives (what a range certificate needs).


def _central_difference(function, x: np.ndarray, step: float) -> np.ndarray:
    columns = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = step
        columns.append((function(x + e) - function(x - e)) / (2 * step))
    return np.stack(columns, -1)


@pytest.mark.parametrize("family", FAMILIES.values(), ids=FAMILIES.keys())
def test_expand_jacobians_match_finite_differences(arm: PlanarArm, family: TrajectoryFamily) -> None:
    context = endpoint_context(path_for(0.25, 0.10), arm.link_lengths_m, 1)
    rng = np.random.default_rng(5)
    free_batch = random_free(family, rng, 40)
    if family is EXACT_ENDPOINTS:
        free_batch = free_batch[unclamped(free_batch, context.duration_s)]
    j_free, j_context = family.expand_jacobians(free_batch, context)
    assert j_free.shape == (len(free_batch), 8, family.free_count)
    assert j_context.shape == (len(free_batch), 8, 5)
    base = context.as_array()

    def with_context(values: np.ndarray) -> EndpointContext:
        return EndpointContext((values[0], values[1]), (values[2], values[3]), values[4])

    for row, free in enumerate(free_batch):
        numeric_free = _central_difference(lambda x: family.expand(x, context), free, 1e-6)
        numeric_context = _central_difference(lambda c, f=free: family.expand(f, with_context(c)), base, 1e-6)
        assert_allclose(j_free[row], numeric_free, rtol=1e-6, atol=1e-5)
        assert_allclose(j_context[row], numeric_context, rtol=1e-6, atol=1e-5)


def test_paper_family_never_claims_exact_endpoints() -> None:
    free = np.random.default_rng(3).normal(size=(5, 8))
    assert not np.any(PAPER.endpoints_exact(free, None))
