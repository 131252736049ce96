"""The continuous-time clearance certificate (pipeline.geometry.sinusoid_certificate) is sound.

* Trajectories built to graze the obstacle exactly between two samples: the sampled clearance
  is positive, yet the certificate refuses to certify (true minimum < 0), and it certifies a
  positive bound no larger than the true minimum when the graze clears by a hair.
* On random trajectories near the obstacle the certified bound never exceeds the clearance at
  100x denser samples (computed independently of Coal), so no case is ever certified while a
  denser sampling finds a collision.
* The speed bounds and closed-form maxima are checked against brute force.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance, analytic_link_clearance, route_from_name
from pipeline.geometry.link_reach import LinkReach
from pipeline.geometry.sinusoid_certificate import (
    _max_abs_cos,
    certify,
    certify_trajectory,
    link_speed_bounds,
    samples_for_resolution,
)
from pipeline.model.arm import PlanarArm, load_planar_arm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import desired_path
from pipeline.motion.trajectory import JointTrajectory

L1, L2, R_LINK = 0.30, 0.35, 0.005
CORNER = 0.01
TABLE2_TEST1 = (-0.816, 0.953, 0.378, 1.068, 1.633, 0.768, 0.131, 0.445)


def dense_analytic_min(trajectory: JointTrajectory, arm: PlanarArm, obstacle: Obstacle, n: int) -> float:
    """Minimum clearance [m] over n uniform samples by the planar analytic route (no Coal)."""
    t = np.linspace(0.0, trajectory.duration_s, n)
    return float(np.min(analytic_link_clearance(trajectory.q(t), arm, obstacle)))


# --------------------------------------------------------------------------------------------
# Grazing trajectories, built explicitly.


def edge_graze(gap_m: float, samples: int = 11, duration_s: float = 2.0) -> tuple[JointTrajectory, Obstacle, float]:
    """Joint 2 frozen, joint 1 sweeping: link 2's tip circle passes the obstacle's near edge.

    The rigid arm rotates about the base; its farthest point is the tip capsule's end at
    R + r from the base, the obstacle's nearest point is the middle of its near edge at d - W.
    The true minimum clearance over the sweep is therefore exactly d - W - R - r = gap_m,
    reached when the tip points straight up, which is placed halfway between two samples.
    """
    h = duration_s / (samples - 1)
    t_star = (samples // 2) * h + h / 2  # midway between two samples
    beta = 1.6  # elbow angle [rad]
    reach = math.sqrt(L1**2 + L2**2 + 2 * L1 * L2 * math.cos(beta))
    tip_direction = math.atan2(L2 * math.sin(beta), L1 + L2 * math.cos(beta))
    width = 0.10
    top = width + reach + R_LINK + gap_m
    obstacle = Obstacle(0.30, width, top_y_m=top, corner_radius_m=CORNER)
    a1, w1 = 0.5, 1.0
    params = (a1, w1, -w1 * t_star, math.pi / 2 - tip_direction, 0.0, 1.0, 0.0, beta)
    return JointTrajectory(params, duration_s), obstacle, t_star


def corner_graze(gap_m: float, samples: int = 11, duration_s: float = 2.0) -> tuple[JointTrajectory, Obstacle, float]:
    """Joint 1 frozen, link 2 sweeping about the elbow: its tip passes the obstacle's rounded corner.

    The elbow E sits below and to the right of the obstacle's lower right corner, so the nearest
    point of the rounded box to E is on that corner's arc (centre C); the true minimum
    clearance is |C - E| - r_corner - (l2 + r) = gap_m, reached when link 2 points at C,
    halfway between two samples.
    """
    h = duration_s / (samples - 1)
    t_star = (samples // 2) * h + h / 2
    theta1 = math.radians(20.0)
    elbow = L1 * np.array([math.cos(theta1), math.sin(theta1)])
    psi = math.radians(120.0)  # direction from E to C
    centre = elbow + (L2 + R_LINK + CORNER + gap_m) * np.array([math.cos(psi), math.sin(psi)])
    length = 2.0 * (centre[0] + CORNER)
    width = 0.10
    obstacle = Obstacle(length, width, top_y_m=centre[1] - CORNER + width, corner_radius_m=CORNER)
    a2, w2 = 0.6, 1.0
    params = (0.0, 1.0, 0.0, theta1, a2, w2, -w2 * t_star, psi - theta1)
    return JointTrajectory(params, duration_s), obstacle, t_star


@pytest.mark.parametrize("build", [edge_graze, corner_graze], ids=["edge", "corner"])
@pytest.mark.parametrize("route", ["coal", "analytic"])
def test_graze_into_the_obstacle_between_samples_is_not_certified(arm: PlanarArm, build, route: str) -> None:
    trajectory, obstacle, t_star = build(-2e-4)
    certificate = certify_trajectory(trajectory, arm, obstacle, route=route_from_name(route), samples=11)
    # The samples all miss the obstacle ...
    assert certificate.sampled_clearance_m > 2e-4
    # ... the certificate does not certify ...
    assert not certificate.certified
    assert certificate.certified_clearance_m <= 0.0
    # ... and a dense independent check (planar analytic distance) agrees: there is a collision.
    assert dense_analytic_min(trajectory, arm, obstacle, 100_001) < 0.0
    # The certificate found where: refinement sampled inside the obstacle near t*.
    assert certificate.min_observed_clearance_m <= 0.0
    assert abs(certificate.min_observed_time_s - t_star) < 0.01


@pytest.mark.parametrize("build", [edge_graze, corner_graze], ids=["edge", "corner"])
@pytest.mark.parametrize("route", ["coal", "analytic"])
def test_graze_that_clears_by_a_hair_is_certified_tightly(arm: PlanarArm, build, route: str) -> None:
    gap = 2e-4
    trajectory, obstacle, t_star = build(gap)
    certificate = certify_trajectory(trajectory, arm, obstacle, route=route_from_name(route), samples=11)
    assert certificate.certified
    assert certificate.certified_clearance_m <= gap  # a lower bound on the true minimum
    assert certificate.certified_clearance_m >= gap - 2 * COAL_DISTANCE_ERROR_M - certificate.tolerance_m
    assert dense_analytic_min(trajectory, arm, obstacle, 100_001) >= certificate.certified_clearance_m
    assert abs(certificate.bound_time_s - t_star) < 0.05  # the minimum is flat: located to tolerance
    assert certificate.bound_link == 2
    assert certificate.evaluations > 11  # it had to refine


def test_graze_construction_is_exact(arm: PlanarArm) -> None:
    """The grazing builders' true minimum is the requested gap (checked at t* by the analytic route)."""
    for build in (edge_graze, corner_graze):
        trajectory, obstacle, t_star = build(3e-4)
        assert analytic_link_clearance(trajectory.q(t_star), arm, obstacle)[1] == pytest.approx(3e-4, abs=1e-12)
        assert dense_analytic_min(trajectory, arm, obstacle, 20_001) == pytest.approx(3e-4, abs=1e-9)


# --------------------------------------------------------------------------------------------
# Random trajectories near the obstacle: the bound is never above a 100x denser sampling.


def near_obstacle_case(seed: int, samples: int) -> tuple[JointTrajectory, Obstacle]:
    """A perturbed Table 2 trajectory, and an obstacle raised or lowered (root finding on its
    height) until the arm passes within +-1 mm of it at 100x the given sampling."""
    rng = np.random.default_rng(seed)
    scene = Scene()
    length, width = rng.uniform(0.20, 0.30), rng.uniform(0.08, 0.12)
    duration = desired_path(Obstacle.in_scene(length, width, scene), scene).duration_s
    params = np.array(TABLE2_TEST1) * (1 + rng.normal(0, 0.05, 8))
    trajectory = JointTrajectory(tuple(params), duration)
    target = rng.uniform(-1e-3, 1e-3)
    arm = load_planar_arm()

    def excess(top_y: float) -> float:
        return dense_analytic_min(trajectory, arm, Obstacle(length, width, top_y_m=top_y), 100 * samples) - target

    top = brentq(excess, 0.3, 1.2, xtol=1e-7)
    return trajectory, Obstacle(length, width, top_y_m=top)


def test_never_certified_while_a_100x_denser_sampling_collides(arm: PlanarArm) -> None:
    samples = 40
    outcomes = {"missed by the samples": 0, "certified": 0}
    for seed in range(30):
        trajectory, obstacle = near_obstacle_case(seed, samples)
        dense = dense_analytic_min(trajectory, arm, obstacle, 100 * samples)
        for route in ("coal", "analytic"):
            certificate = certify_trajectory(trajectory, arm, obstacle, route=route_from_name(route), samples=samples)
            assert certificate.certified_clearance_m <= dense + 1e-12
            if dense <= 0.0:
                assert not certificate.certified
            assert certificate.certified_clearance_m <= certificate.sampled_clearance_m
        outcomes["missed by the samples"] += certificate.sampled_clearance_m > 0 >= dense
        outcomes["certified"] += certificate.certified
    # The check is meaningful: the coarse samples miss some collisions, and some cases certify.
    assert outcomes["missed by the samples"] >= 3, outcomes
    assert outcomes["certified"] >= 3, outcomes


def test_dense_coal_check_agrees_on_a_paper_trajectory(arm: PlanarArm) -> None:
    """Table 2's Test 1: the bound is tight (within tolerance) and below 100x denser Coal samples."""
    scene = Scene()
    obstacle = Obstacle.in_scene(0.30, 0.12, scene)
    trajectory = JointTrajectory(TABLE2_TEST1, desired_path(obstacle, scene).duration_s)
    certificate = certify_trajectory(trajectory, arm, obstacle, samples=300)
    t = np.linspace(0.0, trajectory.duration_s, 30_000)
    dense = float(np.min(CoalClearance(arm, obstacle).link_clearance(trajectory.q(t))))
    assert certificate.certified
    assert certificate.certified_clearance_m <= dense
    assert certificate.certified_clearance_m >= dense - COAL_DISTANCE_ERROR_M - 2 * certificate.tolerance_m


def test_decide_mode_and_budget_keep_the_bound_rigorous(arm: PlanarArm) -> None:
    trajectory, obstacle, _ = edge_graze(2e-4)
    dense = dense_analytic_min(trajectory, arm, obstacle, 100_001)
    full = certify_trajectory(trajectory, arm, obstacle, samples=11)
    decided = certify_trajectory(trajectory, arm, obstacle, samples=11, decide_above_m=0.0)
    starved = certify_trajectory(trajectory, arm, obstacle, samples=11, max_evaluations=0)
    assert decided.certified and decided.evaluations <= full.evaluations
    assert decided.certified_clearance_m <= dense and starved.certified_clearance_m <= dense
    assert not starved.converged and starved.evaluations == 11
    assert (
        not certify_trajectory(trajectory, arm, obstacle, samples=11, decide_above_m=1e-3).certified_clearance_m > 1e-3
    )


# --------------------------------------------------------------------------------------------
# Ingredients against brute force.


def test_reach_of_the_paper_arm(arm: PlanarArm) -> None:
    reach = LinkReach.from_arm(arm)
    assert reach.link1_radius_m == pytest.approx(L1 + R_LINK, abs=1e-12)
    assert reach.elbow_distance_m == pytest.approx(L1, abs=1e-12)
    assert reach.link2_radius_m == pytest.approx(L2 + R_LINK, abs=1e-12)


def test_reach_of_box_links_is_conservative(double_pendulum_urdf) -> None:
    """example-robot-data's double pendulum has box links: the AABB route bounds every box corner."""
    other = load_planar_arm(double_pendulum_urdf)
    reach = LinkReach.from_arm(other)
    data = other.model.createData()
    pin.forwardKinematics(other.model, data, np.zeros(2))
    bounds = (reach.link1_radius_m, reach.link2_radius_m)
    for joint_id, ids, bound in zip((1, 2), other.link_geometry_ids, bounds, strict=True):
        axis = data.oMi[joint_id].rotation.T @ other.axis  # joint axis in the joint frame
        for i in ids:
            geometry = other.collision_model.geometryObjects[i]
            half = np.asarray(geometry.geometry.halfSide)
            corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
            points = corners @ geometry.placement.rotation.T + geometry.placement.translation
            perp = np.linalg.norm(points - np.outer(points @ axis, axis), axis=1)
            assert np.all(perp <= bound + 1e-12)
            assert np.max(perp) >= 0.5 * bound  # and not absurdly loose


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.floats(-20.0, 20.0), st.floats(0.0, 8.0))
def test_closed_form_max_abs_cos(lo: float, width: float) -> None:
    hi = lo + width
    brute = float(np.max(np.abs(np.cos(np.linspace(lo, hi, 20_001)))))
    exact = float(_max_abs_cos(np.array([lo]), np.array([hi]))[0])
    assert brute <= exact + 1e-12
    assert exact <= brute + 1e-6


@settings(max_examples=40, deadline=None, derandomize=True)
@given(
    st.lists(st.floats(-1.5, 1.5), min_size=2, max_size=2),
    st.lists(st.floats(0.05, 3.0), min_size=2, max_size=2),
    st.lists(st.floats(-math.pi, math.pi), min_size=2, max_size=2),
    st.floats(0.0, 3.0),
    st.floats(0.001, 1.0),
)
def test_speed_bound_holds_for_every_point(arm: PlanarArm, amps, freqs, phases, ta: float, h: float) -> None:
    """The bound is above the true speed of capsule points (ends offset by the radius) over the interval."""
    params = (amps[0], freqs[0], phases[0], 0.3, amps[1], freqs[1], phases[1], 0.7)
    trajectory = JointTrajectory(params, 5.0)
    reach = LinkReach.from_arm(arm)
    bound = link_speed_bounds(trajectory, reach, np.array([ta]), np.array([ta + h]))[0]
    t = np.linspace(ta, ta + h, 2001)
    q, dq = trajectory.q(t), trajectory.dq(t)
    a1, a12 = q[:, 0], q[:, 0] + q[:, 1]
    w1, w12 = dq[:, 0], dq[:, 0] + dq[:, 1]
    elbow = L1 * np.stack([np.cos(a1), np.sin(a1)], -1)
    # Farthest points of each capsule along the link (end + radius): the fastest points.
    v_link1 = np.abs(w1) * (L1 + R_LINK)
    u = np.stack([np.cos(a12), np.sin(a12)], -1)
    v_elbow = w1[:, None] * np.stack([-elbow[:, 1], elbow[:, 0]], -1)
    v_tip = v_elbow + (w12[:, None] * (L2 + R_LINK)) * np.stack([-u[:, 1], u[:, 0]], -1)
    assert np.max(v_link1) <= bound[0] + 1e-12
    assert np.max(np.linalg.norm(v_tip, axis=1)) <= bound[1] + 1e-12
    assert np.max(np.linalg.norm(v_elbow, axis=1)) <= bound[1] + 1e-12


def test_default_sampling_resolves_a_millimetre(arm: PlanarArm) -> None:
    scene = Scene()
    obstacle = Obstacle.in_scene(0.30, 0.12, scene)
    trajectory = JointTrajectory(TABLE2_TEST1, desired_path(obstacle, scene).duration_s)
    n = samples_for_resolution(trajectory, LinkReach.from_arm(arm), 1e-3)
    t = np.linspace(0.0, trajectory.duration_s, n)
    q = trajectory.q(t)
    a1, a12 = q[:, 0], q[:, 0] + q[:, 1]
    tip = np.stack([L1 * np.cos(a1) + (L2 + R_LINK) * np.cos(a12), L1 * np.sin(a1) + (L2 + R_LINK) * np.sin(a12)], -1)
    assert np.max(np.linalg.norm(np.diff(tip, axis=0), axis=1)) <= 1e-3


def test_bad_settings_are_rejected(arm: PlanarArm) -> None:
    trajectory, obstacle, _ = edge_graze(1e-3)
    with pytest.raises(InvalidParameterError):
        certify_trajectory(trajectory, arm, obstacle, samples=1)
    with pytest.raises(InvalidParameterError):
        certify_trajectory(trajectory, arm, obstacle, route=route_from_name("exact"))
    with pytest.raises(InvalidParameterError):
        certify_trajectory(trajectory, arm, obstacle, tolerance_m=0.0)
    with pytest.raises(InvalidParameterError):
        certify(trajectory, lambda q: np.full((len(q), 2), np.nan), LinkReach.from_arm(arm), samples=5)
