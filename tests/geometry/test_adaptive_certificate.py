"""The fast Coal route and the adaptive certificate (pipeline.geometry.clearance, sinusoid_certificate).

* The direct ``coal.ComputeDistance`` route equals ``pin.computeDistances`` over the Pinocchio geometry
  model (the paper's capsule arm and the double pendulum's boxes), in and out of contact.
* On a few hundred random cases the adaptive certificate's bound is never above the minimum of a
  100x denser Coal sampling, and within 0.05 mm of the former dense-grid bound; in decide mode its
  verdict agrees with the dense bound's wherever that is more than 0.05 mm from the margin.
"""

from __future__ import annotations

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.exceptions import ArmMismatchError
from pipeline.geometry.clearance import COAL, CoalClearance, PinocchioCoalClearance
from pipeline.geometry.sinusoid_certificate import certify_trajectory
from pipeline.model.arm import PlanarArm, load_planar_arm
from pipeline.model.obstacle import Obstacle
from pipeline.online.arm_check import check_arm_matches
from pipeline.online.generator import generate
from pipeline.online.repair import generate_certified

CLOSE_M = 5e-5  # adaptive vs dense bound [m]


def random_obstacles_and_configurations(seed: int, count: int) -> list[tuple[Obstacle, np.ndarray]]:
    rng = np.random.default_rng(seed)
    cases = []
    for _ in range(count):
        obstacle = Obstacle(rng.uniform(0.03, 0.4), rng.uniform(0.03, 0.2), top_y_m=rng.uniform(0.2, 0.7))
        cases.append((obstacle, rng.uniform(-np.pi, np.pi, (60, 2))))
    return cases


def test_direct_coal_route_equals_the_pinocchio_geometry_route(arm: PlanarArm) -> None:
    contacts = 0
    for obstacle, q in random_obstacles_and_configurations(0, 40):
        fast, reference = CoalClearance(arm, obstacle), PinocchioCoalClearance(arm, obstacle)
        a, b = fast.link_clearance(q), reference.link_clearance(q)
        assert np.max(np.abs(a - b)) <= 1e-12
        assert fast.queries == reference.queries == q.shape[0] * 2
        for link in (0, 1):
            assert np.max(np.abs(fast.link_distances(q, link) - b[:, link])) <= 1e-12
        assert np.max(np.abs(fast.link_clearance(q[3]) - b[3])) <= 1e-12
        contacts += int(np.sum(b <= 0.0))
    assert contacts > 20  # penetration depths are compared too


def test_direct_coal_route_on_box_links(double_pendulum_urdf) -> None:
    """The double pendulum's links are boxes with offsets: the placements come from the model, not from capsules."""
    pendulum = load_planar_arm(double_pendulum_urdf)
    for obstacle, q in random_obstacles_and_configurations(1, 20):
        shifted = Obstacle(obstacle.length_m, obstacle.width_m, top_y_m=obstacle.top_y_m / 3)
        a = CoalClearance(pendulum, shifted).link_clearance(q)
        b = PinocchioCoalClearance(pendulum, shifted).link_clearance(q)
        assert np.max(np.abs(a - b)) <= 1e-12


def sweep_cases(count: int, seed: int) -> list[tuple[float, float]]:
    """(L, W) of the paper's Eq. 9 range widened by 20 % each side (clearances from ~0 to ~40 mm)."""
    rng = np.random.default_rng(seed)
    return list(zip(rng.uniform(0.18, 0.32, count).tolist(), rng.uniform(0.072, 0.128, count).tolist(), strict=True))


@pytest.fixture(scope="module")
def paper():
    return load_coefficients("paper")


def test_adaptive_bound_is_sound_and_as_tight_as_the_dense_one(arm: PlanarArm, paper) -> None:
    margin = paper.scene.margin_m
    below_margin = 0
    totals = np.zeros(3)  # evaluations: adaptive, adaptive deciding, dense
    for L, W in sweep_cases(300, 5):
        answer = generate(paper, L, W, out_of_range="ignore")
        trajectory, obstacle = answer.trajectory, answer.obstacle
        adaptive = certify_trajectory(trajectory, arm, obstacle)
        decided = certify_trajectory(trajectory, arm, obstacle, decide_above_m=margin)
        dense = certify_trajectory(trajectory, arm, obstacle, initial="dense")
        t = np.linspace(0.0, trajectory.duration_s, 100 * adaptive.initial_samples)
        denser = float(np.min(CoalClearance(arm, obstacle).link_clearance(trajectory.q(t))))
        assert adaptive.certified_clearance_m <= denser
        assert decided.certified_clearance_m <= denser
        assert abs(adaptive.certified_clearance_m - dense.certified_clearance_m) <= CLOSE_M
        assert adaptive.initial_samples < dense.initial_samples / 20  # a coarse start ...
        totals += np.array([adaptive.evaluations, decided.evaluations, dense.evaluations])
        if abs(dense.certified_clearance_m - margin) > CLOSE_M:
            assert (decided.certified_clearance_m > margin) == (dense.certified_clearance_m > margin)
        below_margin += dense.certified_clearance_m < margin
    assert below_margin >= 10  # the sample includes cases the margin refuses
    assert totals[0] < totals[2] / 2 and totals[1] < totals[2] / 20, totals


def test_adaptive_bound_on_grazing_random_motions(arm: PlanarArm) -> None:
    """Table 2 Test 1 perturbed, against obstacles placed so that the arm passes within +-2 mm."""
    rng = np.random.default_rng(3)
    base = np.array((-0.816, 0.953, 0.378, 1.068, 1.633, 0.768, 0.131, 0.445))
    collided = 0
    for _ in range(40):
        from pipeline.motion.trajectory import JointTrajectory

        trajectory = JointTrajectory(tuple(base * (1 + rng.normal(0, 0.05, 8))), rng.uniform(3.0, 4.0))
        length, width = rng.uniform(0.2, 0.3), rng.uniform(0.08, 0.12)
        probe = Obstacle(length, width)
        t = np.linspace(0.0, trajectory.duration_s, 4001)
        closest = float(np.min(CoalClearance(arm, probe).link_clearance(trajectory.q(t))))
        obstacle = Obstacle(length, width, top_y_m=probe.top_y_m - closest + rng.uniform(-2e-3, 2e-3))
        adaptive = certify_trajectory(trajectory, arm, obstacle)
        dense = certify_trajectory(trajectory, arm, obstacle, initial="dense")
        t = np.linspace(0.0, trajectory.duration_s, 100 * adaptive.initial_samples)
        denser = float(np.min(CoalClearance(arm, obstacle).link_clearance(trajectory.q(t))))
        assert adaptive.certified_clearance_m <= denser
        if denser <= 0.0:
            assert not adaptive.certified
            collided += 1
        else:
            assert abs(adaptive.certified_clearance_m - dense.certified_clearance_m) <= CLOSE_M
    assert collided >= 5


def test_route_objects_give_both_functions(arm: PlanarArm) -> None:
    obstacle = Obstacle(0.25, 0.1)
    both, one = COAL.functions(arm, obstacle)
    q = np.random.default_rng(2).uniform(-3, 3, (20, 2))
    assert np.array_equal(both(q)[:, 1], one(q, 1))


# --------------------------------------------------------------------------------------------
# One arm check in the online layer.


def test_generate_certified_refuses_another_arm(paper, double_pendulum_urdf) -> None:
    pendulum = load_planar_arm(double_pendulum_urdf)
    with pytest.raises(ArmMismatchError) as info:
        generate_certified(paper, 0.25, 0.1, pendulum)
    message = str(info.value)
    assert "0.3, 0.35 m" in message and "0.1, 0.2 m" in message and str(pendulum.urdf_path) in message
    with pytest.raises(ArmMismatchError):
        check_arm_matches(paper, pendulum)


def test_radii_are_checked_too(paper, arm: PlanarArm) -> None:
    from dataclasses import replace

    check_arm_matches(paper, arm)  # the paper's arm passes
    thick = replace(paper, link_radii_m=(0.005, 0.006))
    with pytest.raises(ArmMismatchError, match=r"radii 0\.005, 0\.006 m"):
        generate_certified(thick, 0.25, 0.1, arm)


def test_adaptive_speed_bounds_hold_for_every_point(arm: PlanarArm) -> None:
    """The adaptive route's interval speed bounds against brute force: finite differences of every
    point of both capsules (ends and surface points) at 2001 times per interval."""
    from pipeline.geometry.clearance import link_segments
    from pipeline.geometry.sinusoid_certificate import _AdaptiveCertificate, arm_reach
    from pipeline.motion.trajectory import JointTrajectory

    rng = np.random.default_rng(8)
    reach = arm_reach(arm)
    radius = arm.link_radii_m[1]
    for _ in range(200):
        parameters = rng.uniform([-2, -3, -3, -3, -2, -3, -3, -3], [2, 3, 3, 3, 2, 3, 3, 3])
        trajectory = JointTrajectory(tuple(parameters), 10.0)
        core = _AdaptiveCertificate(trajectory, reach)
        ta = rng.uniform(0.0, 8.0)
        h = rng.choice([1e-3, 0.05, 0.5, 2.0])
        v1, v2 = core.speeds(np.array([ta]), np.array([ta + h]))
        t = np.linspace(ta, ta + h, 2001)
        elbow, tip = link_segments(trajectory.q(t), arm.link_lengths_m)
        direction = (tip - elbow) / np.linalg.norm(tip - elbow, axis=1)[:, None]
        normal = np.stack([-direction[:, 1], direction[:, 0]], -1)
        far_tip = tip + direction * radius + normal * radius  # a surface point of link 2's capsule
        step = t[1] - t[0]
        for points, bound in ((elbow * (1 + arm.link_radii_m[0] / arm.link_lengths_m[0]), v1[0]), (far_tip, v2[0])):
            speeds = np.linalg.norm(np.diff(points, axis=0), axis=1) / step
            assert np.max(speeds) <= bound * (1 + 1e-6) + 1e-9
