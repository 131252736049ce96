"""The execution certificate against an independent dense check: joint angles, speeds and
accelerations sampled 20,001 times, torques by Pinocchio's RNEA (not the closed form the
certificate uses). No bound may lie below a sampled value; tight bounds are within their
tolerance; decide mode says "violated" exactly when a bound is beyond its limit."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline import load_coefficients
from pipeline.model.dynamics import identify_dynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.execution_certificate import certify_execution
from pipeline.motion.rest_to_rest import shortest_rest_to_rest
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import PAPER_TIMING, RestToRestTiming
from pipeline.online.generator import generate

cases = st.tuples(
    st.floats(0.2, 0.3),
    st.floats(0.08, 0.12),
    st.sampled_from(["paper", "rest"]),
    st.floats(0.1, 1.0),
    st.floats(0.02, 0.9),
)


@pytest.fixture(scope="module")
def setting(arm):
    return load_coefficients("paper"), identify_dynamics(arm)


def _timed(coefficients, case) -> TimedTrajectory:
    L, W, kind, scale, share = case
    trajectory = generate(coefficients, L, W).trajectory
    if kind == "paper":
        return TimedTrajectory(trajectory, PAPER_TIMING)
    duration = trajectory.duration_s
    return TimedTrajectory(trajectory, RestToRestTiming(duration, scale, share * duration / scale))


def dense(arm, timed: TimedTrajectory, samples: int = 20001) -> dict[str, np.ndarray]:
    t = np.linspace(0.0, timed.duration_s, samples)
    q, dq, ddq = timed.q(t), timed.dq(t), timed.ddq(t)
    data = arm.model.createData()
    tau = np.array([pin.rnea(arm.model, data, *state) for state in zip(q, dq, ddq, strict=True)])
    return {
        "q_lo": q.min(0),
        "q_hi": q.max(0),
        "dq": np.abs(dq).max(0),
        "ddq": np.abs(ddq).max(0),
        "tau": np.abs(tau).max(0),
    }


def _bounds(certificate) -> dict[str, np.ndarray]:
    (lo1, hi1), (lo2, hi2) = certificate.angle_range_rad
    return {
        "q_lo": np.array([lo1, lo2]),
        "q_hi": np.array([hi1, hi2]),
        "dq": certificate.speed_bound_rad_s,
        "ddq": certificate.acceleration_bound_rad_s2,
        "tau": certificate.torque_bound_n_m,
    }


@settings(max_examples=25, deadline=None)
@given(cases)
def test_tight_bounds_hold_and_are_tight(arm, setting, case) -> None:
    coefficients, dynamics = setting
    timed = _timed(coefficients, case)
    certificate = certify_execution(timed, dynamics)
    sampled, bounds = dense(arm, timed), _bounds(certificate)
    assert np.all(bounds["q_lo"] <= sampled["q_lo"] + 1e-12) and np.all(bounds["q_hi"] >= sampled["q_hi"] - 1e-12)
    for key in ("dq", "ddq", "tau"):
        assert np.all(bounds[key] >= sampled[key] - 1e-12), (key, bounds[key], sampled[key])
        # within the tolerance (1e-4 of the value, 1e-7 below 1e-3) plus what 20,001 samples miss
        assert np.all(bounds[key] <= sampled[key] * (1 + 2e-4) + 2e-7), (key, bounds[key], sampled[key])


@settings(max_examples=25, deadline=None)
@given(cases, st.floats(0.2, 2.0), st.floats(0.5, 50.0), st.floats(0.005, 0.5))
def test_decide_mode_agrees_with_the_dense_check(arm, setting, case, speed, acceleration, effort) -> None:
    coefficients, dynamics = setting
    timed = _timed(coefficients, case)
    limits = ArmLimits(
        velocity_rad_s=(speed, speed), acceleration_rad_s2=(acceleration, acceleration), effort_n_m=(effort, effort)
    )
    certificate = certify_execution(timed, dynamics, limits)
    sampled, bounds = dense(arm, timed), _bounds(certificate)
    for key in ("dq", "ddq", "tau"):
        assert np.all(bounds[key] >= sampled[key] - 1e-12)
    found = {(v.quantity, v.joint) for v in certificate.violations(limits)}
    for key, quantity, limit in (
        ("dq", "speed", speed),
        ("ddq", "acceleration", acceleration),
        ("tau", "torque", effort),
    ):
        for joint in (0, 1):
            if sampled[key][joint] > limit:  # a sampled value beyond the limit: reported
                assert (quantity, joint + 1) in found
            if (quantity, joint + 1) not in found:  # kept: proven by a bound within the limit
                assert bounds[key][joint] <= limit


def test_the_shortest_rest_to_rest_timing_keeps_the_limits_and_shortens_as_they_loosen(arm, setting) -> None:
    coefficients, dynamics = setting
    trajectory = generate(coefficients, 0.27, 0.09).trajectory
    durations = []
    for speed in (0.2, 0.4, 0.8, 3.0):
        limits = ArmLimits(velocity_rad_s=(speed, speed), acceleration_rad_s2=(1.0, 1.0), effort_n_m=(0.05, 0.05))
        timing = shortest_rest_to_rest(trajectory, dynamics, limits)
        timed = TimedTrajectory(trajectory, timing)
        assert not certify_execution(timed, dynamics, limits).violations(limits)
        sampled = dense(arm, timed)
        assert np.all(sampled["dq"] <= speed) and np.all(sampled["ddq"] <= 1.0) and np.all(sampled["tau"] <= 0.05)
        durations.append(timing.duration_s)
    assert durations == sorted(durations, reverse=True) and durations[0] > trajectory.duration_s


def test_limit_violation_names_a_tiny_excess_not_a_rounded_zero():
    """A bound above its limit by a few micro-units still says by how much (not "by 0.0000")."""
    from pipeline.motion.execution_certificate import LimitViolation

    speed = str(LimitViolation("speed", 1, 3.0000021, 3.0, "rad/s"))
    assert speed == "joint 1 speed bound 3.0000 rad/s > limit 3.0000 rad/s (by 2.1e-06 rad/s)"
    angle = str(LimitViolation("angle", 2, -3.1416, -3.14159, "rad"))
    assert angle.startswith("joint 2 angle bound -3.1416 rad < lower limit -3.1416 rad (by 1e-05 rad)")
