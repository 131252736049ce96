"""The benchmark's TOPP-RA peer: the closed-form dynamics it uses, its timing against an analytic
optimum and against toppra's own output, and the sampled check of its limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline import generate, load_coefficients, load_planar_arm
from pipeline.exceptions import InvalidParameterError, PipelineError
from pipeline.model.dynamics import rnea_torques
from pipeline.model.limits import ArmLimits
from pipeline.motion.trajectory import JointTrajectory, joint_accelerations, joint_velocities
from pipeline.online.execution import dynamics_of

toppra = pytest.importorskip("toppra")

from verify.benchmark.toppra_peer import (  # noqa: E402
    ToppraPeerError,
    ToppraSettings,
    scalar_inverse_dynamics,
    sinusoid_path,
    toppra_path_speeds,
    toppra_timing,
)

#: A simple path: both joints sinusoids, neither speed zero at the same instant.
SIMPLE = JointTrajectory((0.8, 1.0, 0.3, 0.1, 1.2, 0.7, -0.4, 0.2), 3.0)
VELOCITY = (0.5, 0.7)


@pytest.fixture(scope="module")
def arm():
    return load_planar_arm()


@pytest.fixture(scope="module")
def dynamics(arm):
    return dynamics_of(arm)


@pytest.fixture(scope="module")
def paper_trajectory() -> JointTrajectory:
    return generate(load_coefficients("paper"), 0.25, 0.1, out_of_range="ignore").trajectory


def test_closed_form_torque_equals_rnea(arm, dynamics):
    rng = np.random.default_rng(7)
    q = rng.uniform(-math.pi, math.pi, (50, 2))
    dq = rng.uniform(-3.0, 3.0, (50, 2))
    ddq = rng.uniform(-10.0, 10.0, (50, 2))
    np.testing.assert_allclose(dynamics.torque(q, dq, ddq), rnea_torques(arm, q, dq, ddq), rtol=0.0, atol=1e-9)
    # one state at a time, as toppra's torque constraint calls it: the array form and the scalar form
    scalar = scalar_inverse_dynamics(dynamics)
    for state, reference in zip(zip(q, dq, ddq, strict=True), rnea_torques(arm, q, dq, ddq), strict=True):
        np.testing.assert_allclose(dynamics.torque(*state), reference, rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(scalar(*state), reference, rtol=0.0, atol=1e-9)
        assert scalar(*state).shape == (2,)


def test_path_is_exact(paper_trajectory):
    path = sinusoid_path(paper_trajectory)
    assert isinstance(path, toppra.interpolator.AbstractGeometricPath)
    assert path.dof == 2
    np.testing.assert_array_equal(path.path_interval, [0.0, paper_trajectory.duration_s])
    s = np.linspace(0.0, paper_trajectory.duration_s, 7)
    parameters = np.asarray(paper_trajectory.parameters)
    np.testing.assert_array_equal(path.evald(s), joint_velocities(parameters, s))
    np.testing.assert_array_equal(path.evaldd(s), joint_accelerations(parameters, s))
    assert path.eval(0.5).shape == (2,)
    assert path(s, 2).shape == (7, 2)


def test_velocity_only_duration_is_the_analytic_optimum(dynamics):
    # Under speed limits alone the optimum runs every instant at the largest path speed the limits
    # allow: dt/ds = max_i |theta_i'(s)| / v_i, so T* = integral over the path of that.
    s = np.linspace(0.0, SIMPLE.duration_s, 2_000_001)
    rate = np.max(np.abs(joint_velocities(np.asarray(SIMPLE.parameters), s)) / np.asarray(VELOCITY), axis=1)
    optimum_s = float(np.sum(0.5 * (rate[1:] + rate[:-1]) * np.diff(s)))
    result = toppra_timing(SIMPLE, ArmLimits(velocity_rad_s=VELOCITY), dynamics, ToppraSettings(gridpoints=2000))
    assert result.duration_s == pytest.approx(optimum_s, rel=0.01)
    assert result.duration_s >= optimum_s * (1.0 - 1e-6)  # nothing beats the optimum


def test_velocity_only_sampled_speeds_respect_the_limit(dynamics):
    limits = ArmLimits(velocity_rad_s=VELOCITY)
    result = toppra_timing(SIMPLE, limits, dynamics, ToppraSettings(gridpoints=5000, oversample=20))
    assert result.excess[0] <= 1e-6
    assert result.excess[1:] == (0.0, 0.0)  # no acceleration or torque limit
    # the limit is reached: it is what bounds the motion
    assert max(m / v for m, v in zip(result.max_speed_rad_s, VELOCITY, strict=True)) > 1.0 - 1e-3


def test_acceleration_excess_is_a_small_real_measurement(paper_trajectory, dynamics):
    limits = ArmLimits(velocity_rad_s=(3.0, 3.0), acceleration_rad_s2=(5.0, 5.0))
    settings = ToppraSettings(gridpoints=100, oversample=100)
    result = toppra_timing(paper_trajectory, limits, dynamics, settings)
    assert 0.0 < result.excess[1] < 0.01
    assert result.excess[1] == pytest.approx(max(result.max_acceleration_rad_s2) / 5.0 - 1.0)

    # An independent dense sample of the same parameterization, uniform in s within each segment
    # (x = s'^2 is linear in s there), not in t as the peer samples it.
    s, x, _ = toppra_path_speeds(paper_trajectory, limits, dynamics, settings)
    parameters = np.asarray(paper_trajectory.parameters)
    fraction = np.linspace(0.0, 1.0, 201)
    ds = np.diff(s)
    u = np.diff(x) / (2.0 * ds)
    position = (s[:-1, None] + fraction * ds[:, None]).ravel()
    squared_speed = np.maximum((x[:-1, None] + fraction * (x[1:] - x[:-1])[:, None]).ravel(), 0.0)
    path_accel = np.repeat(u, fraction.size)
    ddq = (
        joint_accelerations(parameters, position) * squared_speed[:, None]
        + joint_velocities(parameters, position) * path_accel[:, None]
    )
    dq = joint_velocities(parameters, position) * np.sqrt(squared_speed)[:, None]
    np.testing.assert_allclose(result.max_acceleration_rad_s2, np.max(np.abs(ddq), axis=0), rtol=1e-4)
    np.testing.assert_allclose(result.max_speed_rad_s, np.max(np.abs(dq), axis=0), rtol=1e-4)
    assert result.samples == 100 * 100


def test_duration_matches_toppra_own_trajectory(paper_trajectory, arm, dynamics):
    limits = ArmLimits.from_arm(arm, acceleration_rad_s2=(5.0, 5.0))
    result = toppra_timing(paper_trajectory, limits, dynamics, ToppraSettings(gridpoints=300, oversample=5))
    constraint = toppra.constraint
    interpolation = constraint.DiscretizationType.Interpolation
    own = toppra.algorithm.TOPPRA(
        [
            constraint.JointVelocityConstraint(np.array(limits.velocity_rad_s)),
            constraint.JointAccelerationConstraint(np.array(limits.acceleration_rad_s2), interpolation),
            constraint.JointTorqueConstraint(
                lambda q, dq, ddq: rnea_torques(arm, q[None], dq[None], ddq[None])[0],
                np.array([[-e, e] for e in limits.effort_n_m]),
                np.zeros(2),
                interpolation,
            ),
        ],
        sinusoid_path(paper_trajectory),
        gridpoints=np.linspace(0.0, paper_trajectory.duration_s, 300),
        solver_wrapper="seidel",
    ).compute_trajectory(0.0, 0.0)
    assert result.duration_s == pytest.approx(own.duration, rel=1e-9)


def test_torque_limit_binds(paper_trajectory, arm, dynamics):
    loose = ArmLimits.from_arm(arm, acceleration_rad_s2=(5.0, 5.0))
    tight = ArmLimits(velocity_rad_s=loose.velocity_rad_s, acceleration_rad_s2=(5.0, 5.0), effort_n_m=(0.05, 0.05))
    settings = ToppraSettings(gridpoints=400, oversample=20)
    fast, slow = (toppra_timing(paper_trajectory, limits, dynamics, settings) for limits in (loose, tight))
    assert slow.duration_s > fast.duration_s
    assert max(slow.max_torque_n_m) == pytest.approx(0.05, rel=0.01)
    assert slow.excess[2] < 0.01


def test_one_infinite_limit_beside_a_finite_one(paper_trajectory, dynamics):
    limits = ArmLimits(velocity_rad_s=(3.0, math.inf), acceleration_rad_s2=(math.inf, 5.0))
    result = toppra_timing(paper_trajectory, limits, dynamics, ToppraSettings(gridpoints=200, oversample=10))
    assert math.isfinite(result.duration_s)
    assert result.max_speed_rad_s[0] <= 3.0 * (1.0 + 1e-3)
    assert result.max_acceleration_rad_s2[1] <= 5.0 * 1.01


def test_no_limit_is_refused(paper_trajectory, dynamics):
    with pytest.raises(ToppraPeerError, match="no finite") as caught:
        toppra_timing(paper_trajectory, ArmLimits(), dynamics)
    assert isinstance(caught.value, PipelineError)


@pytest.mark.parametrize(("field", "value"), [("gridpoints", 1), ("gridpoints", 2.0), ("oversample", 0)])
def test_settings_are_checked(field, value):
    with pytest.raises(InvalidParameterError, match=field):
        ToppraSettings(**{field: value})
