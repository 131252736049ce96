"""The compiled routes equal the readable ones: the execution certificate of a smooth timing
(:mod:`pipeline.motion.certificate_kernel`) against the NumPy certificate, and the compiled piece
constraints against :func:`enclose_path` then :func:`piece_constraints`, for every draw."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline import load_coefficients
from pipeline.model.dynamics import identify_dynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.execution_certificate import certify_execution
from pipeline.motion.interval_arithmetic import magnitude
from pipeline.motion.near_optimal import near_optimal_timing
from pipeline.motion.path_constraints import compiled_piece_constraints, enclose_path, piece_constraints
from pipeline.online.generator import generate

INF = float("inf")
limit_values = st.one_of(st.just(INF), st.floats(0.02, 20.0))


@pytest.fixture(scope="module")
def setting(arm):
    return load_coefficients("paper"), identify_dynamics(arm)


def _vector(certificate) -> np.ndarray:
    return np.concatenate(
        [
            np.ravel(certificate.angle_range_rad),
            certificate.speed_bound_rad_s,
            certificate.acceleration_bound_rad_s2,
            certificate.torque_bound_n_m,
            certificate.jerk_bound_rad_s3,
        ]
    )


def _sampled(certificate) -> np.ndarray:
    keys = ("speed_rad_s", "acceleration_rad_s2", "torque_n_m", "jerk_rad_s3")
    return np.concatenate([np.ravel(certificate.sampled["angle_range_rad"]), *(certificate.sampled[k] for k in keys)])


@settings(max_examples=20, deadline=None)
@given(st.floats(0.2, 0.3), st.floats(0.08, 0.12), st.floats(0.3, 3.0), st.floats(1.0, 10.0), st.booleans())
def test_the_compiled_certificate_equals_the_numpy_one(arm, setting, length, width, speed, acceleration, tight) -> None:
    coefficients, dynamics = setting
    trajectory = generate(coefficients, length, width).trajectory
    limits = replace(ArmLimits.from_arm(arm, (acceleration, acceleration)), velocity_rad_s=(speed, speed))
    limits = limits.with_servo_defaults()
    executed = near_optimal_timing(trajectory, dynamics, limits).executed
    # Decide against limits a little tighter than the timing's own, so that some intervals are bisected.
    tighter = replace(limits, acceleration_rad_s2=tuple(0.995 * a for a in limits.acceleration_rad_s2))
    decide = None if tight else tighter
    readable = certify_execution(executed, dynamics, decide, compiled=False)
    compiled = certify_execution(executed, dynamics, decide, compiled=True)
    np.testing.assert_allclose(_vector(compiled), _vector(readable), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(_sampled(compiled), _sampled(readable), rtol=1e-12, atol=1e-15)
    assert compiled.intervals == readable.intervals
    assert [str(v) for v in compiled.violations(tighter)] == [str(v) for v in readable.violations(tighter)]


@settings(max_examples=30, deadline=None)
@given(
    st.floats(0.2, 0.3),
    st.floats(0.08, 0.12),
    st.tuples(limit_values, limit_values, limit_values, limit_values, st.floats(0.1, 3.0)),
    st.floats(0.5, 1.0),
    st.floats(0.5, 1.0),
    st.integers(2, 300),
)
def test_the_compiled_constraints_equal_the_readable_ones(arm, setting, length, width, values, share, speed_share, n):
    coefficients, dynamics = setting
    a1, a2, e1, e2, v = values
    limits = ArmLimits(velocity_rad_s=(v, v), acceleration_rad_s2=(a1, a2), effort_n_m=(e1, e2))
    trajectory = generate(coefficients, length, width).trajectory
    edges = np.linspace(0.0, trajectory.duration_s, n + 1)
    enclosures = enclose_path(trajectory.parameters, edges, dynamics)
    readable = piece_constraints(enclosures, limits, share, speed_share)
    compiled, peaks = compiled_piece_constraints(trajectory.parameters, edges, dynamics, limits, share, speed_share)
    for name in ("cu", "cx", "rhs", "speed_cap"):
        np.testing.assert_allclose(getattr(compiled, name), getattr(readable, name), rtol=1e-13, atol=1e-15)
    for peak, enclosure in zip(peaks, (enclosures.d1, enclosures.d2, enclosures.d3), strict=True):
        np.testing.assert_allclose(peak, magnitude(enclosure), rtol=1e-13, atol=1e-15)
