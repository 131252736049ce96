"""Per-case measurement (verify.acceptance.metrics): the verifier's clearance against an independent planar
distance (not Coal), endpoint and tracking errors against Eq. 2 written here, and the acceptance
checks (the closed-form joint ranges are tested with the trajectory, tests/motion/test_trajectory.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from pipeline import load_coefficients
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import desired_path
from pipeline.motion.trajectory import JointTrajectory
from verify.acceptance.metrics import (
    AcceptanceThresholds,
    MeasureSettings,
    measure_case,
    measure_trajectory,
)
from verify.acceptance.results import CaseResult, EndpointErrors, Verdict

L1, L2, R_LINK = 0.30, 0.35, 0.005
TABLE2 = {  # Test: (A1, w1, phi1, gamma1, A2, w2, phi2, gamma2, L, W)
    1: (-0.816, 0.953, 0.378, 1.068, 1.633, 0.768, 0.131, 0.445, 0.30, 0.12),
    5: (-0.781, 0.996, 0.467, 1.116, 1.449, 0.864, 0.131, 0.543, 0.25, 0.10),
    9: (-0.797, 0.993, 0.602, 1.222, 1.323, 0.955, 0.167, 0.574, 0.20, 0.08),
}
FAST = MeasureSettings(time_samples=400)


# --------------------------------------------------------------------------------------------
# Independent planar geometry (segment/rectangle by orientation tests; no Coal, no pipeline code).


def _orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    return float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))


def _segments_cross(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> bool:
    d1, d2 = _orient(q1, q2, p1), _orient(q1, q2, p2)
    d3, d4 = _orient(p1, p2, q1), _orient(p1, p2, q2)
    return d1 * d2 <= 0 and d3 * d4 <= 0


def _point_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    s = min(1.0, max(0.0, float(np.dot(p - a, ab) / np.dot(ab, ab))))
    return float(np.linalg.norm(p - (a + s * ab)))


def segment_to_rectangle(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """Planar distance between segment a-b and the rectangle [lo, hi] (0 if they meet)."""
    corners = [np.array(c) for c in ((lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1]))]
    inside = all(lo[i] <= a[i] <= hi[i] for i in (0, 1))
    if inside or any(_segments_cross(a, b, corners[k], corners[(k + 1) % 4]) for k in range(4)):
        return 0.0
    candidates = [_point_segment(c, a, b) for c in corners]
    for p in (a, b):
        candidates.append(float(np.linalg.norm(p - np.clip(p, lo, hi))))
    return min(candidates)


def independent_clearance(q: np.ndarray, obstacle: Obstacle) -> float:
    """min over both links of the capsule-to-rounded-box clearance [m] at q (Eq. 2 kinematics)."""
    r = obstacle.corner_radius_m
    lo = np.array([-obstacle.length_m / 2 + r, obstacle.top_y_m - obstacle.width_m + r])
    hi = np.array([obstacle.length_m / 2 - r, obstacle.top_y_m - r])
    elbow = L1 * np.array([math.cos(q[0]), math.sin(q[0])])
    tip = elbow + L2 * np.array([math.cos(q[0] + q[1]), math.sin(q[0] + q[1])])
    return min(segment_to_rectangle(np.zeros(2), elbow, lo, hi), segment_to_rectangle(elbow, tip, lo, hi)) - R_LINK - r


def eq2(q: np.ndarray) -> np.ndarray:
    return np.array(
        [L1 * math.cos(q[0]) + L2 * math.cos(q[0] + q[1]), L1 * math.sin(q[0]) + L2 * math.sin(q[0] + q[1])]
    )


def table2_case(test: int, scene: Scene) -> tuple[JointTrajectory, object, Obstacle]:
    row = TABLE2[test]
    obstacle = Obstacle.in_scene(row[8], row[9], scene)
    path = desired_path(obstacle, scene)
    return JointTrajectory(row[:8], path.duration_s), path, obstacle


# --------------------------------------------------------------------------------------------


def test_clearance_matches_an_independent_planar_distance_on_random_cases(arm: PlanarArm, scene: Scene) -> None:
    rng = np.random.default_rng(3)
    for _ in range(12):
        row = TABLE2[int(rng.choice(list(TABLE2)))]
        obstacle = Obstacle.in_scene(rng.uniform(0.20, 0.30), rng.uniform(0.08, 0.12), scene)
        path = desired_path(obstacle, scene)
        params = np.array(row[:8]) * (1 + rng.normal(0, 0.03, 8))
        trajectory = JointTrajectory(tuple(params), path.duration_s)
        sampled = measure_trajectory(trajectory, path, obstacle, arm, MeasureSettings(time_samples=150, certify=False))
        result = measure_trajectory(trajectory, path, obstacle, arm, MeasureSettings(certificate_mode="tight"))
        times = np.linspace(0.0, trajectory.duration_s, 150)
        reference = min(independent_clearance(q, obstacle) for q in trajectory.q(times))
        if reference > 0:
            assert sampled.clearance_m == pytest.approx(reference, abs=2e-6)
            assert result.certified_clearance_m <= reference
            # Tight: the bound is within the tolerance and Coal's error of the certificate's samples.
            assert result.clearance_m - result.certified_clearance_m <= 1e-5 + COAL_DISTANCE_ERROR_M + 1e-12
            assert result.clearance_m <= reference + 2e-6
        else:
            assert result.clearance_m <= 1e-9
            assert not result.certificate.collision_free and not result.passed


def test_endpoint_and_tracking_errors_against_eq2(arm: PlanarArm, scene: Scene) -> None:
    trajectory, path, obstacle = table2_case(1, scene)
    result = measure_trajectory(trajectory, path, obstacle, arm, FAST)
    p1 = np.array([0.30 / 2 + 0.12, 0.56])
    p5 = np.array([-(0.30 / 2 + 0.12), 0.56])
    assert result.measurement.endpoints.start_m == pytest.approx(np.linalg.norm(eq2(trajectory.q(0.0)) - p1), abs=1e-12)
    assert result.measurement.endpoints.end_m == pytest.approx(
        np.linalg.norm(eq2(trajectory.q(trajectory.duration_s)) - p5), abs=1e-12
    )
    # At matched times t = 0 and t = T the desired point is P1 and P5.
    assert result.tracking_max_m >= max(result.measurement.endpoints.start_m, result.measurement.endpoints.end_m) - 1e-9
    assert 0 < result.measurement.tracking.rms_m <= result.tracking_max_m
    # Independently: 400 path points uniform in x, the quartic by polyfit through P1..P5, the
    # matched time t = S(x) / v by adaptive quadrature, the tip by Eq. 2.
    quartic = np.polyfit(path.points_m[:, 0], path.points_m[:, 1], 4)
    slope = np.polyder(quartic)
    deviation = []
    for x in np.linspace(path.points_m[0, 0], path.points_m[-1, 0], 400):
        length, _ = quad(lambda u: math.hypot(1.0, np.polyval(slope, u)), x, path.points_m[0, 0], epsabs=1e-13)
        t = min(length / scene.speed_m_s, trajectory.duration_s)
        deviation.append(np.linalg.norm(eq2(trajectory.q(t)) - (x, np.polyval(quartic, x))))
    assert result.tracking_max_m == pytest.approx(max(deviation), abs=1e-12)
    assert result.measurement.tracking.rms_m == pytest.approx(math.sqrt(np.mean(np.square(deviation))), abs=1e-12)


def test_table2_trajectories_are_measured_as_expected(arm: PlanarArm, scene: Scene) -> None:
    for test in TABLE2:
        trajectory, path, obstacle = table2_case(test, scene)
        result = measure_trajectory(trajectory, path, obstacle, arm)
        assert result.error is None and result.measurement.T_s == pytest.approx(path.duration_s)
        assert result.certificate.collision_free and result.certified_clearance_m > 0
        assert result.certified_clearance_m <= result.clearance_m
        # The default (decide) mode tightens the bound only where the margin is not kept.
        assert result.certificate.tight or result.certificate.keeps_margin
        if result.certificate.tight:
            assert result.certified_clearance_m >= result.clearance_m - 3e-5
        tight = measure_trajectory(trajectory, path, obstacle, arm, MeasureSettings(certificate_mode="tight"))
        assert tight.certificate.tight and tight.certified_clearance_m >= tight.clearance_m - 3e-5
        assert tight.certificate.keeps_margin == result.certificate.keeps_margin
        joints = result.measurement.joints
        assert joints.within_velocity_limits and joints.within_position_limits and joints.within_limits
        assert joints.within_acceleration_limits is None  # the URDF has no acceleration limits
        assert joints.peak_velocity_rad_s == pytest.approx(tuple(trajectory.peak_velocity_rad_s()))


def test_thresholds_decide_pass_and_fail(arm: PlanarArm, scene: Scene) -> None:
    trajectory, path, obstacle = table2_case(9, scene)
    lenient = MeasureSettings(time_samples=400, thresholds=AcceptanceThresholds(max_endpoint_error_m=0.05))
    assert measure_trajectory(trajectory, path, obstacle, arm, lenient).passed
    strict = MeasureSettings(
        time_samples=400,
        thresholds=AcceptanceThresholds(
            max_endpoint_error_m=1e-4,
            min_certified_clearance_m=0.5,
            margin_m=0.5,
            require_margin=True,
            max_tracking_error_m=1e-4,
            acceleration_limits_rad_s2=(0.1, 0.1),
        ),
    )
    result = measure_trajectory(trajectory, path, obstacle, arm, strict)
    text = " | ".join(result.failures)
    assert not result.passed and result.certificate.keeps_margin is False
    for words in (
        "endpoint error at start",
        "endpoint error at end",
        "certified clearance",
        "margin",
        "tracking",
        "acceleration",
    ):
        assert words in text
    no_certificate = MeasureSettings(time_samples=400, certify=False)
    unchecked = measure_trajectory(trajectory, path, obstacle, arm, no_certificate)
    assert unchecked.certified_clearance_m is None and not unchecked.passed
    assert "not certified" in unchecked.failures[0]


def test_joint_limits_are_checked(arm: PlanarArm, scene: Scene) -> None:
    _, path, obstacle = table2_case(5, scene)
    fast = JointTrajectory((0.5, 8.0, 0.0, 1.0, 0.2, 1.0, 0.0, 3.1), path.duration_s)  # 4 rad/s; angle > pi
    result = measure_trajectory(fast, path, obstacle, arm, FAST)
    assert not result.measurement.joints.within_velocity_limits
    assert not result.measurement.joints.within_position_limits
    assert any("joint speed" in f for f in result.failures) and any("joint range" in f for f in result.failures)
    relaxed = MeasureSettings(time_samples=400, thresholds=AcceptanceThresholds(check_joint_limits=False))
    assert not any("joint" in f for f in measure_trajectory(fast, path, obstacle, arm, relaxed).failures)


def test_collision_is_reported(arm: PlanarArm, scene: Scene) -> None:
    trajectory, path, _ = table2_case(1, scene)
    big = Obstacle.in_scene(0.60, 0.30, scene)  # the Test 1 motion goes through it
    result = measure_trajectory(trajectory, path, big, arm, FAST)
    assert result.clearance_m < 0 and result.certified_clearance_m <= result.clearance_m
    assert result.certificate.collision_free is False and not result.passed
    assert any("collision not excluded" in f for f in result.failures)


def test_case_result_invariants_and_json(arm: PlanarArm, scene: Scene) -> None:
    trajectory, path, obstacle = table2_case(5, scene)
    result = measure_trajectory(trajectory, path, obstacle, arm, FAST, index=7, extrapolated=True)
    data = result.to_json()
    for key in (
        "L",
        "W",
        "T_s",
        "clearance_m",
        "certified_clearance_m",
        "endpoint_error_start_m",
        "endpoint_error_end_m",
        "tracking_max_m",
        "tracking_rms_m",
        "passed",
        "extrapolated",
        "peak_velocity_rad_s",
        "peak_acceleration_rad_s2",
        "velocity_limits_rad_s",
        "within_velocity_limits",
    ):
        assert key in data
    assert data["index"] == 7 and data["extrapolated"] is True and data["L"] == pytest.approx(0.25)
    assert data["endpoint_error_m"] == pytest.approx(result.measurement.endpoints.max_m)
    assert Verdict().passed and not Verdict(failures=("x",)).passed and not Verdict(error="e").passed
    with pytest.raises(InvalidParameterError):  # a measured case has no error
        CaseResult(0, 0.2, 0.1, False, result.measurement, Verdict(error="e"))
    with pytest.raises(InvalidParameterError):  # a case without a measurement says why
        CaseResult(0, 0.2, 0.1, False, None, Verdict())
    with pytest.raises(InvalidParameterError):
        CaseResult(0, -0.2, 0.1, False, None, Verdict(error="e"))
    with pytest.raises(InvalidParameterError):
        EndpointErrors(start_m=-1.0, end_m=0.0)
    with pytest.raises(InvalidParameterError):
        MeasureSettings(time_samples=1)
    with pytest.raises(InvalidParameterError):
        AcceptanceThresholds(max_endpoint_error_m=-1.0)


def test_measure_case_uses_the_online_generator(arm: PlanarArm) -> None:
    paper = load_coefficients("paper")
    inside = measure_case(paper, 0.27, 0.11, arm, FAST, index=3)
    assert inside.index == 3 and inside.error is None and not inside.extrapolated
    assert inside.L_m == 0.27 and inside.W_m == 0.11
    outside = measure_case(paper, 0.32, 0.13, arm, FAST)
    assert outside.extrapolated
    unreachable = measure_case(paper, 0.9, 0.5, arm, FAST)
    assert unreachable.error is not None and not unreachable.passed and unreachable.clearance_m is None
    assert "reach" in unreachable.error


def test_torques_are_bounded_and_checked_against_the_effort_limits(arm: PlanarArm, scene: Scene, tmp_path) -> None:
    """The sweep's torque bound holds against Pinocchio's RNEA at 20,001 instants (independent of the
    closed form it uses), and an arm whose effort limit is below it fails the case, naming the torque."""
    import pinocchio as pin

    from pipeline.model.arm import DEFAULT_URDF, load_planar_arm
    from verify.acceptance.metrics import joint_check

    trajectory, path, obstacle = table2_case(1, scene)
    check = joint_check(trajectory, arm)
    t = np.linspace(0.0, trajectory.duration_s, 20001)
    data = arm.model.createData()
    states = zip(trajectory.q(t), trajectory.dq(t), trajectory.ddq(t), strict=True)
    rnea = np.abs(np.array([pin.rnea(arm.model, data, *state) for state in states])).max(0)
    assert np.all(np.array(check.torque_bound_n_m) >= rnea - 1e-12)
    assert np.allclose(check.peak_torque_sampled_n_m, rnea, rtol=1e-3)
    assert check.within_effort_limits and check.effort_limits_n_m == (10.0, 10.0)
    weak = tmp_path / "weak.urdf"
    weak.write_text(DEFAULT_URDF.read_text().replace('effort="10"', 'effort="0.01"'))
    result = measure_trajectory(trajectory, path, obstacle, load_planar_arm(weak), FAST)
    assert not result.measurement.joints.within_effort_limits
    assert any("torque bound" in f and "exceeds the URDF limits (0.01, 0.01)" in f for f in result.verdict.failures)
