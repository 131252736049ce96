"""The near-optimal timing through certify-or-repair: the answer executes within the limits with
the servo defaults filled in, its measured endpoint errors are the forward kinematics' (the proven
bounds beside them), and a refusal of the paper timing suggests the duration the near-optimal call
then returns."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipeline import NEAR_OPTIMAL, REST_TO_REST
from pipeline.exceptions import ExecutionRefusedError, InvalidParameterError
from pipeline.model.limits import ArmLimits
from pipeline.online.repair import generate_certified


def test_the_answer_executes_within_the_limits_with_the_servo_defaults(arm, paper) -> None:
    answer = generate_certified(paper, 0.27, 0.09, arm, timing=NEAR_OPTIMAL)
    limits = answer.execution.limits
    assert limits.acceleration_rad_s2 == (10.0, 10.0) and limits.jerk_rad_s3 == (200.0, 200.0)
    assert not answer.execution.certificate.violations(limits)
    assert answer.execution.certificate.timing_name == "near-optimal"
    t = np.linspace(0.0, answer.duration_s, 4001)
    _, dq, ddq = answer.executed.states(t)
    assert np.abs(ddq).max() <= 10.0 and np.all(dq[[0, -1]] == 0.0)
    assert answer.duration_s < answer.trajectory.duration_s  # faster than the paper's speed on this arm


def test_endpoint_errors_are_measured_and_their_bounds_proven(arm, paper) -> None:
    answer = generate_certified(paper, 0.27, 0.09, arm, timing=NEAR_OPTIMAL)
    trajectory = answer.trajectory
    # Pinocchio's kinematics of the URDF, not Eq. 2.
    tips = arm.to_plane(arm.end_effector_positions(trajectory.q(np.array([0.0, trajectory.duration_s]))))
    points = answer.generated.path.points_m
    errors = np.linalg.norm(tips - np.array([points[0], points[-1]]), axis=1)
    np.testing.assert_allclose(answer.endpoint_errors_m, errors, rtol=0, atol=1e-12)
    assert np.all(np.array(answer.endpoint_error_bounds_m) >= errors)


def test_a_refused_paper_timing_suggests_the_duration_the_near_optimal_call_returns(arm, paper) -> None:
    slow = replace(ArmLimits.from_arm(arm), velocity_rad_s=(0.3, 0.3))
    with pytest.raises(ExecutionRefusedError) as info:
        generate_certified(paper, 0.27, 0.09, arm, limits=slow)
    message = str(info.value)
    assert "joint 2 speed bound 1.2350 rad/s > limit 0.3000 rad/s" in message
    suggested = float(message.split("keeps them in T' = ")[1].split(" s")[0])
    answer = generate_certified(paper, 0.27, 0.09, arm, limits=slow, timing=NEAR_OPTIMAL)
    assert answer.duration_s == pytest.approx(suggested, abs=5e-4)


def test_the_rest_to_rest_timing_is_still_offered(arm, paper) -> None:
    answer = generate_certified(paper, 0.27, 0.09, arm, timing=REST_TO_REST)
    assert answer.execution.certificate.timing_name == "rest-to-rest"


def test_an_unknown_timing_is_refused(arm, paper) -> None:
    with pytest.raises(InvalidParameterError, match="NEAR_OPTIMAL"):
        generate_certified(paper, 0.27, 0.09, arm, timing="fast")
