"""The near time-optimal timing against independent checks: every bound it certifies holds on a
dense sample of the motion (torques by Pinocchio's RNEA, not the closed form it is built on), the
motion is at rest at both ends with continuous accelerations, it is never faster than the speed
limits allow (an analytic lower bound) and close to TOPP-RA on the same path and limits."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline import load_coefficients
from pipeline.exceptions import InvalidParameterError, TimingRefusedError
from pipeline.model.dynamics import identify_dynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.near_optimal import NearOptimalSettings, near_optimal_timing
from pipeline.motion.trajectory import joint_velocities
from pipeline.online.generator import generate


@pytest.fixture(scope="module")
def setting(arm):
    return load_coefficients("paper"), identify_dynamics(arm)


def _limits(arm, speed: float, acceleration: float, effort: float, jerk: float | None = None) -> ArmLimits:
    base = ArmLimits.from_arm(arm, (acceleration, acceleration), None if jerk is None else (jerk, jerk))
    return replace(base, velocity_rad_s=(speed, speed), effort_n_m=(effort, effort)).with_servo_defaults()


def _dense(arm, executed, samples: int = 20001) -> dict[str, np.ndarray]:
    """The motion at ``samples`` instants and just either side of every breakpoint of its timing."""
    knots = executed.timing.knots_s
    t = np.concatenate([np.linspace(0.0, executed.duration_s, samples), knots - 1e-9, knots + 1e-9])
    t = np.clip(t, 0.0, executed.duration_s)
    q, dq, ddq = executed.states(t)
    data = arm.model.createData()
    tau = np.array([pin.rnea(arm.model, data, *state) for state in zip(q, dq, ddq, strict=True)])
    jerk = executed.jerk(t)
    return {"q": q, "dq": dq, "ddq": ddq, "tau": tau, "jerk": jerk}


cases = st.tuples(
    st.floats(0.2, 0.3),
    st.floats(0.08, 0.12),
    st.floats(0.2, 3.0),
    st.floats(1.0, 10.0),
    st.floats(0.03, 10.0),
    st.one_of(st.none(), st.floats(20.0, 400.0)),
)


@settings(max_examples=25, deadline=None)
@given(cases)
def test_every_certified_bound_holds_on_a_dense_sample(arm, setting, case) -> None:
    coefficients, dynamics = setting
    length, width, speed, acceleration, effort, jerk = case
    trajectory = generate(coefficients, length, width).trajectory
    limits = _limits(arm, speed, acceleration, effort, jerk)
    result = near_optimal_timing(trajectory, dynamics, limits)
    executed, certificate = result.executed, result.certificate
    assert not certificate.violations(limits)
    sampled = _dense(arm, executed)
    for key, bound, limit in (
        ("dq", certificate.speed_bound_rad_s, limits.velocity_rad_s),
        ("ddq", certificate.acceleration_bound_rad_s2, limits.acceleration_rad_s2),
        ("tau", certificate.torque_bound_n_m, limits.effort_n_m),
        ("jerk", certificate.jerk_bound_rad_s3, limits.jerk_rad_s3),
    ):
        peak = np.abs(sampled[key]).max(0)
        assert np.all(peak <= bound * (1 + 1e-9) + 1e-12), (key, peak, bound)
        assert np.all(bound <= np.asarray(limit)), (key, bound, limit)
    (lo1, hi1), (lo2, hi2) = certificate.angle_range_rad
    q = sampled["q"]
    assert lo1 <= q[:, 0].min() and q[:, 0].max() <= hi1 and lo2 <= q[:, 1].min() and q[:, 1].max() <= hi2


@settings(max_examples=15, deadline=None)
@given(cases)
def test_at_rest_at_both_ends_on_the_same_path_with_continuous_accelerations(arm, setting, case) -> None:
    coefficients, dynamics = setting
    length, width, speed, acceleration, effort, jerk = case
    trajectory = generate(coefficients, length, width).trajectory
    limits = _limits(arm, speed, acceleration, effort, jerk)
    executed = near_optimal_timing(trajectory, dynamics, limits).executed
    ends = np.array([0.0, executed.duration_s])
    q, dq, ddq = executed.states(ends)
    assert np.all(dq == 0.0) and np.all(ddq == 0.0)
    np.testing.assert_allclose(q, trajectory.q(np.array([0.0, trajectory.duration_s])), rtol=0, atol=1e-12)
    knots = executed.timing.knots_s[1:-1]
    gap = 1e-9
    jump = np.abs(executed.ddq(knots + gap) - executed.ddq(knots - gap)).max()
    assert jump <= 2 * gap * max(limits.jerk_rad_s3) + 1e-9
    sigma = executed.timing.sigma(np.linspace(0.0, executed.duration_s, 20001))
    assert np.all(np.diff(sigma) >= -1e-12)  # never back along the path


def test_never_faster_than_the_speed_limits_allow(arm, setting) -> None:
    """|dq_i| <= v_i means ds/dtau <= v_i / |theta_i'(s)|, so T' >= integral of max_i |theta_i'| / v_i ds:
    an analytic lower bound a lying certificate could break; the timing ends within 5 % of it (the
    acceleration limit is loose here, so the speed limit binds almost everywhere)."""
    coefficients, dynamics = setting
    trajectory = generate(coefficients, 0.27, 0.09).trajectory
    limits = _limits(arm, 0.3, 10.0, 10.0)
    executed = near_optimal_timing(trajectory, dynamics, limits).executed
    s = np.linspace(0.0, trajectory.duration_s, 200001)
    rate = np.max(np.abs(joint_velocities(trajectory.parameters, s)) / 0.3, axis=1)
    lower = float(np.sum(0.5 * (rate[1:] + rate[:-1]) * np.diff(s)))
    assert lower * (1 - 1e-6) <= executed.duration_s <= 1.05 * lower


def test_within_ten_percent_of_toppra_on_the_same_path_and_limits(arm, setting) -> None:
    from verify.benchmark.toppra_peer import ToppraSettings, toppra_timing

    coefficients, dynamics = setting
    for length, width in ((0.22, 0.1), (0.28, 0.09)):
        trajectory = generate(coefficients, length, width).trajectory
        limits = _limits(arm, 3.0, 5.0, 10.0)
        ours = near_optimal_timing(trajectory, dynamics, limits).executed.duration_s
        peer = toppra_timing(trajectory, limits, dynamics, ToppraSettings(gridpoints=1000, oversample=1))
        assert 1.0 <= ours / peer.duration_s <= 1.10


def test_an_infinite_jerk_limit_or_no_limit_at_all_is_refused(arm, setting) -> None:
    coefficients, dynamics = setting
    trajectory = generate(coefficients, 0.27, 0.09).trajectory
    with pytest.raises(InvalidParameterError, match="jerk"):
        near_optimal_timing(trajectory, dynamics, ArmLimits.from_arm(arm, (5.0, 5.0)))
    with pytest.raises(InvalidParameterError, match="finite speed, acceleration or effort"):
        near_optimal_timing(trajectory, dynamics, ArmLimits(jerk_rad_s3=(100.0, 100.0)))


def test_limits_far_below_what_the_path_needs_or_its_angles_are_refused(arm, setting) -> None:
    coefficients, dynamics = setting
    trajectory = generate(coefficients, 0.27, 0.09).trajectory
    with pytest.raises(TimingRefusedError, match="longer than 3600 s"):
        near_optimal_timing(trajectory, dynamics, _limits(arm, 3.0, 5.0, 10.0, jerk=1e-6))
    narrow = replace(_limits(arm, 3.0, 5.0, 10.0), position_rad=((-0.5, 0.5), (-math.pi, math.pi)))
    with pytest.raises(TimingRefusedError, match="joint 1 angle bound"):
        near_optimal_timing(trajectory, dynamics, narrow)


@pytest.mark.parametrize(
    "field_value",
    [("pieces", 1), ("pieces", 2.5), ("limit_share", 0.0), ("speed_share", 1.5), ("jerk_share", float("nan")),
     ("tries", 0), ("longest_duration_s", float("inf"))],
)  # fmt: skip
def test_settings_are_checked(field_value) -> None:
    field, value = field_value
    with pytest.raises(InvalidParameterError, match=field):
        NearOptimalSettings(**{field: value})
