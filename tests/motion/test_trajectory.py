"""The sinusoid family (pipeline.motion.trajectory): canonical form of Eq. 8, derivatives against finite
differences, closed-form peaks against dense sampling, and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pipeline.exceptions import InvalidParameterError
from pipeline.motion.trajectory import (
    PARAMETER_NAMES,
    JointTrajectory,
    canonicalize,
    joint_accelerations,
    joint_angles,
    joint_velocities,
)

HALF_PI = math.pi / 2


def eq1(params: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Eq. 1 written out: theta_i = A_i sin(w_i t + phi_i) + gamma_i, shape (m, 2)."""
    a1, w1, p1, g1, a2, w2, p2, g2 = params
    return np.column_stack([a1 * np.sin(w1 * t + p1) + g1, a2 * np.sin(w2 * t + p2) + g2])


# One joint's parameters already in canonical form: w > 0, phi in [-pi/2, pi/2) with a margin
# so that rounding cannot carry an equivalent form across the boundary.
canonical_joint = st.tuples(
    st.floats(-3.0, 3.0).filter(lambda a: abs(a) > 1e-3),  # A
    st.floats(0.01, 4.0),  # w
    st.floats(-HALF_PI + 1e-6, HALF_PI - 1e-6),  # phi
    st.floats(-3.0, 3.0),  # gamma
)
# An equivalent form: optionally w -> -w (with A -> -A, phi -> -phi), then phi -> phi + k pi
# (with A -> (-1)^k A).
equivalence = st.tuples(st.booleans(), st.integers(-6, 6))


def equivalent_form(joint: tuple[float, float, float, float], negate_w: bool, k: int) -> list[float]:
    a, w, phi, gamma = joint
    if negate_w:
        a, w, phi = -a, -w, -phi
    return [a * (-1) ** k, w, phi + k * math.pi, gamma]


# --------------------------------------------------------------------------------------------
# Canonical form.


def test_table_2_is_already_canonical(table2: np.ndarray) -> None:
    parameters = np.array(table2[:, :8])
    assert_allclose(canonicalize(parameters), parameters, rtol=0, atol=1e-15)
    for row in parameters:
        assert_allclose(canonicalize(row), row, rtol=0, atol=1e-15)


@settings(max_examples=100, deadline=None)
@given(canonical_joint, canonical_joint, equivalence, equivalence)
@example((-0.816, 0.953, 0.378, 1.068), (1.633, 0.768, 0.131, 0.445), (True, 0), (False, 1))
@example((-0.816, 0.953, 0.378, 1.068), (1.633, 0.768, 0.131, 0.445), (True, -3), (True, 2))
def test_equivalent_forms_map_to_one_canonical_form(
    joint1: tuple, joint2: tuple, form1: tuple[bool, int], form2: tuple[bool, int]
) -> None:
    canonical = np.array([*joint1, *joint2])
    other = np.array(equivalent_form(joint1, *form1) + equivalent_form(joint2, *form2))
    t = np.linspace(0.0, 5.0, 50)
    # The two forms are the same motion ...
    assert_allclose(joint_angles(other, t), joint_angles(canonical, t), rtol=0, atol=1e-9)
    # ... and canonicalize recovers the same parameters and so the same joint angles.
    mapped = canonicalize(other)
    assert_allclose(mapped, canonical, rtol=0, atol=1e-9)
    assert_allclose(joint_angles(mapped, t), eq1(canonical, t), rtol=0, atol=1e-9)
    assert_allclose(canonicalize(canonical), canonical, rtol=0, atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-20.0, 20.0), min_size=8, max_size=8))
def test_canonical_form_properties(values: list[float]) -> None:
    """Any parameters: canonical w >= 0, phi in [-pi/2, pi/2), same motion, idempotent."""
    params = np.array(values)
    mapped = canonicalize(params)
    assert np.all(mapped[[1, 5]] >= 0)
    assert np.all(mapped[[2, 6]] >= -HALF_PI - 1e-12) and np.all(mapped[[2, 6]] < HALF_PI + 1e-12)
    assert_allclose(np.abs(mapped[[0, 4]]), np.abs(params[[0, 4]]), rtol=0, atol=0)
    assert_allclose(mapped[[3, 7]], params[[3, 7]], rtol=0, atol=0)  # gamma untouched
    t = np.linspace(0.0, 4.0, 40)
    assert_allclose(joint_angles(mapped, t), eq1(params, t), rtol=0, atol=1e-9)
    assert_allclose(canonicalize(mapped), mapped, rtol=0, atol=1e-12)


def test_canonicalize_batches_and_copies() -> None:
    rng = np.random.default_rng(3)
    swarm = rng.uniform(-5, 5, size=(4, 6, 8))
    original = swarm.copy()
    mapped = canonicalize(swarm)
    assert mapped.shape == (4, 6, 8)
    assert_allclose(swarm, original, rtol=0, atol=0)  # input untouched
    rows = np.array([[canonicalize(p) for p in block] for block in swarm])
    assert_allclose(mapped, rows, rtol=0, atol=0)


def test_canonicalize_hand_cases() -> None:
    # w < 0: (A, -w, phi) -> (-A, w, -phi).
    assert_allclose(canonicalize([1, -2, 0.5, 0, 1, 2, 0.5, 0]), [-1, 2, -0.5, 0, 1, 2, 0.5, 0], atol=1e-15, rtol=0)
    # phi = 2.0 -> 2.0 - pi with A flipped.
    assert_allclose(canonicalize([1, 2, 2.0, 0, 1, 2, 0, 0]), [-1, 2, 2.0 - math.pi, 0, 1, 2, 0, 0], rtol=0, atol=1e-15)
    # phi = -pi/2 is kept, +pi/2 becomes -pi/2 with A flipped.
    assert_allclose(
        canonicalize([1, 1, -HALF_PI, 0, 1, 1, HALF_PI, 0])[[0, 2, 4, 6]],
        [1, -HALF_PI, -1, -HALF_PI],
        rtol=0,
        atol=1e-15,
    )


def test_canonical_phase_stays_in_range_at_the_boundary() -> None:
    """BUG (pipeline/trajectory.py, canonicalize): phi = -pi/2 + k pi, computed in floating point,
    can land one rounding error below -pi/2 after ``phi - half_turns * pi``: the result
    leaves the documented range [-pi/2, pi/2), and canonicalize is then not idempotent (a
    second pass flips A and moves phi to +pi/2 - eps). A final fold (phi < -pi/2 -> phi + pi
    with A -> -A; phi >= pi/2 -> phi - pi with A -> -A) fixes it.
    """
    for k in (-10, -8, 6):
        phi = -HALF_PI + k * math.pi
        params = np.array([1.0, 1.0, phi, 0.0, 1.0, 1.0, 0.0, 0.0])
        once = canonicalize(params)
        assert -HALF_PI <= once[2] < HALF_PI, (k, once[2])
        assert_allclose(canonicalize(once), once, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------------
# Derivatives.

any_params = st.lists(st.floats(-3.0, 3.0), min_size=8, max_size=8).map(np.array)


@settings(max_examples=60, deadline=None)
@given(any_params)
@example(np.array([-0.816, 0.953, 0.378, 1.068, 1.633, 0.768, 0.131, 0.445]))
def test_derivatives_equal_finite_differences(params: np.ndarray) -> None:
    t = np.linspace(0.0, 4.0, 41)
    h = 1e-5
    dq_fd = (joint_angles(params, t + h) - joint_angles(params, t - h)) / (2 * h)
    ddq_fd = (joint_velocities(params, t + h) - joint_velocities(params, t - h)) / (2 * h)
    ddq_fd2 = (joint_angles(params, t + 1e-4) - 2 * joint_angles(params, t) + joint_angles(params, t - 1e-4)) / 1e-8
    scale_v = np.abs(params[[0, 4]] * params[[1, 5]])
    scale_a = np.abs(params[[0, 4]] * params[[1, 5]] ** 2)
    assert_allclose(joint_velocities(params, t), dq_fd, rtol=1e-6, atol=1e-8 + 1e-6 * np.max(scale_v))
    assert_allclose(joint_accelerations(params, t), ddq_fd, rtol=1e-6, atol=1e-8 + 1e-6 * np.max(scale_a))
    assert_allclose(joint_accelerations(params, t), ddq_fd2, rtol=1e-4, atol=1e-5)
    assert_allclose(joint_angles(params, t), eq1(params, t), rtol=0, atol=1e-12)


def test_trajectory_methods_match_functions(table2: np.ndarray) -> None:
    trajectory = JointTrajectory(tuple(table2[0, :8]), 3.75)
    t = np.linspace(0.0, 3.75, 30)
    assert_allclose(trajectory.q(t), eq1(table2[0, :8], t), rtol=0, atol=1e-12)
    assert_allclose(trajectory(t), trajectory.q(t), rtol=0, atol=0)
    assert_allclose(trajectory.dq(t), joint_velocities(table2[0, :8], t), rtol=0, atol=0)
    assert_allclose(trajectory.ddq(t), joint_accelerations(table2[0, :8], t), rtol=0, atol=0)
    assert trajectory.q(1.0).shape == trajectory.dq(1.0).shape == trajectory.ddq(1.0).shape == (2,)
    assert_allclose(trajectory.q(1.0), trajectory.q(np.array([1.0]))[0], rtol=0, atol=0)


def test_swarm_evaluation_shapes() -> None:
    swarm = np.random.default_rng(2).uniform(-2, 2, size=(5, 8))
    t = np.linspace(0.0, 1.0, 7)
    batch = joint_angles(swarm, t)
    assert batch.shape == (5, 7, 2)
    assert_allclose(batch, np.array([eq1(p, t) for p in swarm]), rtol=0, atol=1e-12)
    assert joint_velocities(swarm, t).shape == joint_accelerations(swarm, t).shape == (5, 7, 2)


# --------------------------------------------------------------------------------------------
# Peaks.


def sampled_peaks(trajectory: JointTrajectory) -> tuple[np.ndarray, np.ndarray]:
    """max |dq| and |ddq| over [0, T] by dense sampling (endpoints included)."""
    t = np.linspace(0.0, trajectory.duration_s, 200_001)
    return np.max(np.abs(trajectory.dq(t)), axis=0), np.max(np.abs(trajectory.ddq(t)), axis=0)


@settings(max_examples=80, deadline=None)
@given(
    st.lists(st.floats(-3.0, 3.0), min_size=8, max_size=8),
    st.floats(0.05, 6.0),
)
@example([-0.816, 0.953, 0.378, 1.068, 1.633, 0.768, 0.131, 0.445], 3.748)
@example([1.0, 1.0, 0.2, 0.0, 1.0, -1.0, 0.2, 0.0], 0.5)  # peaks at the endpoints
@example([1.0, 2.0, -2.5, 0.0, -0.5, 3.0, 2.9, 0.0], 0.1)
def test_peaks_equal_dense_sampling(params: list[float], duration: float) -> None:
    trajectory = JointTrajectory(tuple(params), duration)
    velocity, acceleration = sampled_peaks(trajectory)
    assert_allclose(trajectory.peak_velocity_rad_s(), velocity, rtol=0, atol=1e-6)
    assert_allclose(trajectory.peak_acceleration_rad_s2(), acceleration, rtol=0, atol=1e-6)


@settings(max_examples=60, deadline=None)
@given(st.floats(-2, 2), st.floats(0.01, 5), st.floats(-4, 4), st.floats(-1, 1), st.floats(0.1, 8))
@example(1.0, 1.0, 0.2, 0.0, 0.5)  # extremes at the endpoints only
@example(1.0, math.pi, -HALF_PI, 0.0, 2.0)  # a whole period: both extremes inside
def test_angle_ranges_equal_dense_sampling(
    amplitude: float, w: float, phi: float, gamma: float, duration: float
) -> None:
    """The closed-form range contains every sampled angle and is within the sampling's resolution of it."""
    trajectory = JointTrajectory((amplitude, w, phi, gamma, -amplitude, w / 2, -phi, gamma), duration)
    q = trajectory.q(np.linspace(0.0, duration, 50_001))
    for joint, (lo, hi) in enumerate(trajectory.angle_ranges_rad()):
        assert lo <= q[:, joint].min() + 1e-12 and q[:, joint].max() <= hi + 1e-12
        assert lo >= q[:, joint].min() - 1e-6 and hi <= q[:, joint].max() + 1e-6


def test_peaks_at_the_endpoints() -> None:
    """Short windows where |cos| and |sin| are monotone: the peak is at t = 0 or t = T."""
    # Joint 1: |velocity| = cos(t + 0.2) falls from t = 0; |acceleration| = sin(t + 0.2) rises to T.
    # Joint 2 (w < 0): |velocity| = 2 cos(t + 0.3), |acceleration| = 2 sin(t + 0.3), likewise.
    trajectory = JointTrajectory((1.0, 1.0, 0.2, 0.0, 2.0, -1.0, -0.3, 0.0), 0.5)
    assert_allclose(trajectory.peak_velocity_rad_s(), [math.cos(0.2), 2.0 * math.cos(-0.3)], rtol=0, atol=1e-15)
    assert_allclose(
        trajectory.peak_acceleration_rad_s2(), [math.sin(0.7), 2.0 * abs(math.sin(-0.8))], rtol=0, atol=1e-15
    )
    assert np.all(trajectory.peak_velocity_rad_s() < [1.0, 2.0])  # the amplitude is not reached
    # A full period: the amplitude is reached.
    full = JointTrajectory((1.5, 2.0, 0.2, 0.0, -0.5, 3.0, 1.0, 0.0), 2 * math.pi / 2.0)
    assert_allclose(full.peak_velocity_rad_s(), [3.0, 1.5], rtol=0, atol=1e-15)
    assert_allclose(full.peak_acceleration_rad_s2(), [6.0, 4.5], rtol=0, atol=1e-15)


def test_peaks_of_table_2_test_1(table2: np.ndarray) -> None:
    trajectory = JointTrajectory(tuple(table2[0, :8]), 3.748)
    velocity, acceleration = sampled_peaks(trajectory)
    assert_allclose(trajectory.peak_velocity_rad_s(), velocity, rtol=0, atol=1e-6)
    assert_allclose(trajectory.peak_acceleration_rad_s2(), acceleration, rtol=0, atol=1e-6)


# --------------------------------------------------------------------------------------------
# JointTrajectory construction and InvalidParameterError.


def test_mapping_round_trip(table2: np.ndarray) -> None:
    trajectory = JointTrajectory(tuple(table2[4, :8]), 3.3)
    assert list(trajectory.as_dict()) == list(PARAMETER_NAMES)
    again = JointTrajectory.from_mapping(trajectory.as_dict(), 3.3)
    assert again == trajectory
    assert_allclose(again.array, table2[4, :8], rtol=0, atol=0)
    assert JointTrajectory(np.array(table2[4, :8]), 3.3).parameters == trajectory.parameters


def test_mapping_with_missing_key() -> None:
    values = dict(zip(PARAMETER_NAMES, range(8), strict=True))
    del values["phi2"]
    with pytest.raises(InvalidParameterError, match="phi2"):
        JointTrajectory.from_mapping(values, 1.0)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 7), st.sampled_from([math.nan, math.inf, -math.inf]))
def test_non_finite_parameter(index: int, bad: float) -> None:
    values = [0.5] * 8
    values[index] = bad
    with pytest.raises(InvalidParameterError) as info:
        JointTrajectory(tuple(values), 1.0)
    assert info.value.name == PARAMETER_NAMES[index]


@pytest.mark.parametrize("count", [0, 1, 7, 9, 16])
def test_wrong_parameter_count(count: int) -> None:
    with pytest.raises(InvalidParameterError, match="8 values"):
        JointTrajectory(tuple([0.5] * count), 1.0)


@settings(max_examples=50, deadline=None)
@given(st.one_of(st.floats(max_value=0.0), st.just(math.nan), st.just(math.inf)))
def test_non_positive_or_non_finite_duration(duration: float) -> None:
    with pytest.raises(InvalidParameterError) as info:
        JointTrajectory(tuple([0.5] * 8), duration)
    assert info.value.name == "duration_s"
