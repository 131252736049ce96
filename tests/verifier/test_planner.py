"""verify.benchmark.ompl_planner and pipeline.geometry.polyline_certificate: the piecewise-linear path
certificate is rigorous, and the OMPL comparison runs.

* Segments built to graze the obstacle exactly between two samples (here: between the two
  waypoints of a segment, sampled only at its ends): a true collision is never certified,
  and a graze that clears by a hair is certified with a bound no larger than the true minimum.
* On random multi-segment paths near and through the obstacle, the certified bound never
  exceeds the clearance at a dense sampling computed independently of Coal (planar analytic
  distance), and it is within the tolerance of it.
* The per-segment speed bounds hold against brute-force point speeds.
* RRT-Connect (skipped without ``ompl``) returns a path between the requested states whose
  waypoints all keep the margin.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import (
    COAL_DISTANCE_ERROR_M,
    CoalClearance,
    analytic_link_clearance,
    link_segments,
    route_from_name,
)
from pipeline.geometry.link_reach import LinkReach
from pipeline.geometry.polyline_certificate import (
    JointPath,
    certify_joint_path,
    certify_path,
    segment_speed_bounds,
    timed_path,
)
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.online.generator import generate
from verify.benchmark.ompl_planner import PlannerConfig, ompl_available, plan_rrt_connect, start_goal_configurations

L1, L2, R_LINK = 0.30, 0.35, 0.005
CORNER = 0.01


def dense_analytic_min(path: JointPath, arm: PlanarArm, obstacle: Obstacle, per_segment: int) -> float:
    """Minimum clearance [m] over ``per_segment`` uniform samples of every segment (no Coal)."""
    fractions = np.linspace(0.0, 1.0, per_segment)[:, None]
    w = path.waypoints_rad
    q = np.concatenate([a + fractions * (b - a) for a, b in itertools.pairwise(w)])
    return float(np.min(analytic_link_clearance(q, arm, obstacle)))


def edge_graze(gap_m: float) -> tuple[JointPath, Obstacle]:
    """Joint 2 frozen, joint 1 swept linearly: the rigid arm's tip passes the obstacle's near edge.

    The arm's farthest point from the base is the tip capsule's end at R + r, the obstacle's
    nearest point the middle of its near edge at d - W, so the true minimum clearance over the
    sweep is d - W - R - r = gap_m, reached where the tip points straight up: at 40% of the
    second segment, far from any waypoint.
    """
    beta = 1.6  # elbow angle [rad]
    reach = math.sqrt(L1**2 + L2**2 + 2 * L1 * L2 * math.cos(beta))
    tip_direction = math.atan2(L2 * math.sin(beta), L1 + L2 * math.cos(beta))
    width = 0.10
    obstacle = Obstacle(0.30, width, top_y_m=width + reach + R_LINK + gap_m, corner_radius_m=CORNER)
    up = math.pi / 2 - tip_direction  # joint 1 angle with the tip straight up
    waypoints = np.array([[up - 0.9, beta], [up - 0.4, beta], [up + 0.6, beta], [up + 0.9, beta]])
    return JointPath(waypoints, np.array([0.0, 0.5, 1.5, 1.8])), obstacle


def corner_graze(gap_m: float) -> tuple[JointPath, Obstacle]:
    """Joint 1 frozen, joint 2 swept linearly: link 2's tip passes the obstacle's rounded corner.

    The elbow E sits below and to the right of the lower right corner, so the nearest point of
    the box to E is on that corner's arc (centre C); the true minimum clearance is
    |C - E| - r_corner - (l2 + r) = gap_m, reached when link 2 points at C (mid-segment).
    """
    theta1 = math.radians(20.0)
    elbow = L1 * np.array([math.cos(theta1), math.sin(theta1)])
    psi = math.radians(120.0)  # direction from E to C
    centre = elbow + (L2 + R_LINK + CORNER + gap_m) * np.array([math.cos(psi), math.sin(psi)])
    width = 0.10
    obstacle = Obstacle(2.0 * (centre[0] + CORNER), width, top_y_m=centre[1] - CORNER + width, corner_radius_m=CORNER)
    a = psi - theta1
    waypoints = np.array([[theta1, a - 0.35], [theta1, a + 0.45]])
    return JointPath(waypoints, np.array([0.0, 1.0])), obstacle


def graze_minimum_time(path: JointPath, arm: PlanarArm, obstacle: Obstacle) -> float:
    """Time [s] of the analytic minimum along the path (dense search)."""
    t = np.linspace(0.0, path.duration_s, 200_001)
    return float(t[np.argmin(np.min(analytic_link_clearance(path.q(t), arm, obstacle), axis=1))])


@pytest.mark.parametrize("build", [edge_graze, corner_graze], ids=["edge", "corner"])
def test_graze_construction_is_exact(arm: PlanarArm, build) -> None:
    path, obstacle = build(3e-4)
    assert dense_analytic_min(path, arm, obstacle, 200_001) == pytest.approx(3e-4, abs=1e-9)
    # The waypoints themselves are far from the obstacle: only the inside of a segment grazes it.
    assert np.min(analytic_link_clearance(path.waypoints_rad, arm, obstacle)) > 0.01


@pytest.mark.parametrize("build", [edge_graze, corner_graze], ids=["edge", "corner"])
@pytest.mark.parametrize("route", ["coal", "analytic"])
def test_collision_between_waypoints_is_not_certified(arm: PlanarArm, build, route: str) -> None:
    path, obstacle = build(-2e-4)
    certificate = certify_path(path, arm, obstacle, route=route_from_name(route), samples_per_segment=2)
    # Every initial sample (the waypoints) clears the obstacle by centimetres ...
    assert certificate.sampled_clearance_m > 0.01
    # ... yet the certificate refuses, and the dense independent check agrees: there is a collision.
    assert not certificate.certified
    assert certificate.certified_clearance_m <= 0.0
    assert dense_analytic_min(path, arm, obstacle, 100_001) < 0.0
    assert certificate.min_observed_clearance_m <= 0.0
    assert abs(certificate.min_observed_time_s - graze_minimum_time(path, arm, obstacle)) < 0.01


@pytest.mark.parametrize("build", [edge_graze, corner_graze], ids=["edge", "corner"])
@pytest.mark.parametrize("route", ["coal", "analytic"])
def test_graze_that_clears_by_a_hair_is_certified_tightly(arm: PlanarArm, build, route: str) -> None:
    gap = 2e-4
    path, obstacle = build(gap)
    certificate = certify_path(path, arm, obstacle, route=route_from_name(route), samples_per_segment=2)
    assert certificate.certified
    assert certificate.certified_clearance_m <= gap  # a lower bound on the true minimum
    assert certificate.certified_clearance_m >= gap - 2 * COAL_DISTANCE_ERROR_M - certificate.tolerance_m
    assert certificate.bound_link == 2
    assert certificate.evaluations > path.segments + 1  # it had to refine


def test_default_sampling_is_also_rigorous_on_the_graze(arm: PlanarArm) -> None:
    path, obstacle = edge_graze(-5e-5)
    certificate = certify_path(path, arm, obstacle)
    assert not certificate.certified


def random_path_near_the_obstacle(arm: PlanarArm, seed: int, sigma_rad: float = 0.02) -> tuple[JointPath, Obstacle]:
    """Waypoints on the paper's generated trajectory at random times, jittered by sigma_rad:
    paths that pass the obstacle within millimetres, some clearing it and some not."""
    rng = np.random.default_rng(seed)
    generated = generate(load_coefficients("paper"), rng.uniform(0.2, 0.3), rng.uniform(0.08, 0.12))
    t = np.concatenate([[0.0], np.sort(rng.random(rng.integers(3, 8))), [1.0]]) * generated.duration_s
    waypoints = generated.trajectory.q(t) + rng.normal(0.0, sigma_rad, (t.size, 2))
    return timed_path(waypoints, arm.velocity_limits_rad_s), generated.obstacle


def test_random_paths_never_exceed_a_dense_independent_check(arm: PlanarArm) -> None:
    """Random multi-segment paths near the obstacle: the Coal certificate (started from 3 samples per
    segment) against a dense planar analytic sampling (no Coal): the bound never exceeds it, is within
    the tolerance of it where the path clears, and never certifies a path the dense check finds in
    collision."""
    reach = LinkReach.from_arm(arm)
    kinds = set()
    for seed in range(12):
        path, obstacle = random_path_near_the_obstacle(arm, seed)
        certificate = certify_path(path, arm, obstacle, samples_per_segment=3)
        dense = dense_analytic_min(path, arm, obstacle, 20_001)
        assert certificate.certified_clearance_m <= dense + 1e-12, seed
        assert certificate.converged
        assert certificate.certified == (certificate.certified_clearance_m > 0.0)
        if dense > 0.0:
            # The dense sampling overestimates the true minimum by at most half a step's motion.
            motion = segment_speed_bounds(path, reach) * np.diff(path.times_s)[:, None]
            slack = certificate.tolerance_m + COAL_DISTANCE_ERROR_M + float(np.max(motion)) / 20_000 / 2 + 1e-9
            assert certificate.certified_clearance_m >= dense - slack, seed
            kinds.add("clear")
        else:
            assert not certificate.certified, seed
            kinds.add("collision")
    assert kinds == {"clear", "collision"}  # both kinds were exercised


def test_speed_bounds_hold_against_brute_force(arm: PlanarArm) -> None:
    """Finite-difference speeds of points of each link's capsule never exceed the segment bound, and
    the bound per unit parameter is at most the closed form |dq1|(l1 + r1), |dq1|(l1 + l2 + r2) + |dq2|(l2 + r2)."""
    rng = np.random.default_rng(7)
    reach = LinkReach.from_arm(arm)
    waypoints = rng.uniform(-math.pi, math.pi, (8, 2))
    path = timed_path(waypoints, arm.velocity_limits_rad_s)
    bounds = segment_speed_bounds(path, reach)
    steps = np.abs(np.diff(path.waypoints_rad, axis=0))
    h = np.diff(path.times_s)
    assert np.all(bounds[:, 0] * h <= steps[:, 0] * (L1 + R_LINK) * (1 + 1e-8))
    assert np.all(bounds[:, 1] * h <= (steps[:, 0] * (L1 + L2 + R_LINK) + steps[:, 1] * (L2 + R_LINK)) * (1 + 1e-8))
    # Points on the capsules' surfaces (offset r across the axis, or r beyond the tip).
    along = np.linspace(0.0, 1.0, 11)
    for j in range(path.segments):
        t = np.linspace(path.times_s[j], path.times_s[j + 1], 401)
        q = path.q(t)
        elbow, tip = link_segments(q, arm.link_lengths_m)
        base = np.zeros_like(elbow)
        for link, (a, b) in enumerate(((base, elbow), (elbow, tip))):
            direction = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
            normal = np.stack([-direction[:, 1], direction[:, 0]], -1)
            points = [a + s * (b - a) + sign * R_LINK * normal for s in along for sign in (-1, 1)]
            points.append(b + R_LINK * direction)
            for p in points:
                speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(t)
                assert np.max(speed) <= bounds[j, link] * (1 + 1e-6)


def test_timed_path_respects_velocity_limits_and_merges_duplicates() -> None:
    waypoints = np.array([[0.0, 0.0], [0.0, 0.0], [0.6, -0.3], [0.6, -0.3 + 1e-15], [0.6, 0.9]])
    path = timed_path(waypoints, (3.0, 1.5))
    assert path.segments == 2
    np.testing.assert_allclose(path.times_s, [0.0, 0.2, 1.0])
    np.testing.assert_allclose(np.max(np.abs(path.joint_velocities_rad_s) / [3.0, 1.5], axis=1), 1.0)
    np.testing.assert_allclose(path.q(0.1), [0.3, -0.15])
    np.testing.assert_allclose(path.q(np.array([0.0, 1.0])), [[0.0, 0.0], [0.6, 0.9]])
    assert path.joint_space_length_rad() == pytest.approx(math.hypot(0.6, 0.3) + 1.2)


@pytest.mark.parametrize(
    ("waypoints", "times"),
    [
        (np.zeros((1, 2)), np.zeros(1)),
        (np.zeros((2, 3)), np.array([0.0, 1.0])),
        (np.zeros((2, 2)), np.array([0.0, 0.0])),
        (np.zeros((2, 2)), np.array([0.5, 1.0])),
        (np.array([[0.0, np.nan], [1.0, 1.0]]), np.array([0.0, 1.0])),
    ],
)
def test_joint_path_rejects_bad_input(waypoints: np.ndarray, times: np.ndarray) -> None:
    with pytest.raises(InvalidParameterError):
        JointPath(waypoints, times)


def test_timed_path_and_certificate_reject_bad_input(arm: PlanarArm) -> None:
    with pytest.raises(InvalidParameterError):
        timed_path(np.zeros((3, 2)), (3.0, 3.0))
    with pytest.raises(InvalidParameterError):
        timed_path(np.eye(2), (3.0, 0.0))
    path, obstacle = corner_graze(1e-3)
    with pytest.raises(InvalidParameterError):
        certify_path(path, arm, obstacle, route=route_from_name("nope"))
    with pytest.raises(InvalidParameterError):
        certify_joint_path(path, CoalClearance(arm, obstacle).link_clearance, LinkReach.from_arm(arm), tolerance_m=0)
    with pytest.raises(InvalidParameterError):
        certify_path(path, arm, obstacle, samples_per_segment=1)


def test_evaluation_budget_keeps_the_bound_rigorous(arm: PlanarArm) -> None:
    path, obstacle = edge_graze(2e-4)
    certificate = certify_path(path, arm, obstacle, samples_per_segment=2, max_evaluations=5)
    assert not certificate.converged
    assert certificate.certified_clearance_m <= 2e-4


# --------------------------------------------------------------------------------------------
# OMPL (optional dependency)


def test_planner_config_rejects_bad_input() -> None:
    with pytest.raises(InvalidParameterError):
        PlannerConfig(time_limit_s=0.0)
    with pytest.raises(InvalidParameterError):
        PlannerConfig(margin_m=-1.0)
    with pytest.raises(InvalidParameterError):
        PlannerConfig(log_level="loud")


@pytest.mark.skipif(not ompl_available(), reason="ompl is not installed (optional bench extra)")
def test_rrt_connect_returns_a_path_whose_waypoints_keep_the_margin(arm: PlanarArm) -> None:
    from verify.benchmark.ompl_planner import seed_ompl

    seed_ompl(0)
    scene = Scene()
    obstacle = Obstacle.in_scene(0.25, 0.10, scene)
    start, goal = start_goal_configurations(obstacle, scene, arm.link_lengths_m)
    result = plan_rrt_connect(arm, obstacle, start, goal, PlannerConfig(time_limit_s=2.0, margin_m=scene.margin_m))
    assert result.solved and result.start_valid and result.goal_valid
    assert result.path is not None
    np.testing.assert_allclose(result.path.waypoints_rad[0], start, atol=1e-12)
    np.testing.assert_allclose(result.path.waypoints_rad[-1], goal, atol=1e-12)
    clearance = CoalClearance(arm, obstacle).link_clearance(result.path.waypoints_rad)
    assert np.all(clearance >= scene.margin_m)
    assert result.validity_checks > 0 and result.coal_queries == 2 * result.validity_checks
    certificate = certify_path(result.path, arm, obstacle)
    assert certificate.certified_clearance_m <= dense_analytic_min(result.path, arm, obstacle, 5001) + 1e-12


@pytest.mark.skipif(not ompl_available(), reason="ompl is not installed (optional bench extra)")
def test_rrt_connect_reports_an_invalid_start(arm: PlanarArm) -> None:
    scene = Scene()
    obstacle = Obstacle.in_scene(0.25, 0.10, scene)
    _, goal = start_goal_configurations(obstacle, scene, arm.link_lengths_m)
    inside = np.array([math.pi / 2, 0.0])  # the stretched arm points straight through the obstacle
    result = plan_rrt_connect(arm, obstacle, inside, goal, PlannerConfig(time_limit_s=0.2))
    assert not result.start_valid
    assert not result.solved and result.path is None
