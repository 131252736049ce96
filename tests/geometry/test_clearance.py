"""Link-to-obstacle clearance (pipeline.geometry.clearance): the Pinocchio + Coal route against an
independent planar computation written here, the fast analytic route against Coal, hand-made
configurations, and the query counter."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.optimize import minimize_scalar

from pipeline.exceptions import RobotModelError
from pipeline.geometry.clearance import CoalClearance, analytic_link_clearance, check_fast_route, link_box_clearance
from pipeline.model.arm import PlanarArm, load_planar_arm
from pipeline.model.obstacle import Obstacle

# The paper's arm and link thickness, written here independently of the model.
L1, L2, LINK_RADIUS = 0.30, 0.35, 0.005


# --------------------------------------------------------------------------------------------
# Independent reference: capsule (segment + radius) against a rounded rectangle, by minimising
# the exact point-to-rounded-rectangle distance along the segment.


def point_to_rounded_rectangle(p: np.ndarray, lo: np.ndarray, hi: np.ndarray, radius: float) -> float:
    """Distance [m] from p to the rectangle [lo, hi] inflated by ``radius`` (<= -radius inside)."""
    nearest = np.minimum(np.maximum(p, lo), hi)  # projection onto the core rectangle
    return float(math.hypot(*(p - nearest))) - radius


def capsule_to_rounded_rectangle(a: np.ndarray, b: np.ndarray, capsule_radius: float, obstacle: Obstacle) -> float:
    """Distance [m] between the capsule a -> b and the obstacle's rounded footprint.

    The distance to a convex set is convex along the segment, so a bounded 1-D minimisation
    finds the global minimum; a dense sampling of the segment guards it.
    """
    r = obstacle.corner_radius_m
    lo = np.array([-obstacle.length_m / 2 + r, obstacle.top_y_m - obstacle.width_m + r])
    hi = np.array([obstacle.length_m / 2 - r, obstacle.top_y_m - r])

    def along(s: float) -> float:
        return point_to_rounded_rectangle(a + s * (b - a), lo, hi, r)

    result = minimize_scalar(along, bounds=(0.0, 1.0), method="bounded", options={"xatol": 1e-12})
    best = min(result.fun, along(0.0), along(1.0))  # the minimum may sit at an end
    assert best <= min(along(s) for s in np.linspace(0.0, 1.0, 201)) + 1e-12  # nothing lower
    return best - capsule_radius


def reference_clearance(q: np.ndarray, obstacle: Obstacle) -> np.ndarray:
    """(link 1, link 2) clearance [m] of the paper's arm at q, from Eq. 2's joint positions."""
    base = np.zeros(2)
    elbow = L1 * np.array([math.cos(q[0]), math.sin(q[0])])
    tip = elbow + L2 * np.array([math.cos(q[0] + q[1]), math.sin(q[0] + q[1])])
    return np.array(
        [
            capsule_to_rounded_rectangle(base, elbow, LINK_RADIUS, obstacle),
            capsule_to_rounded_rectangle(elbow, tip, LINK_RADIUS, obstacle),
        ]
    )


def random_obstacle(rng: np.random.Generator) -> Obstacle:
    length, width = rng.uniform(0.10, 0.40), rng.uniform(0.05, 0.20)
    radius = rng.uniform(0.0, min(0.03, min(length, width) / 2))
    return Obstacle(length, width, top_y_m=rng.uniform(0.30, 0.70), corner_radius_m=radius)


# --------------------------------------------------------------------------------------------
# Coal route against the independent reference.


def test_coal_route_matches_independent_planar_distance(arm: PlanarArm) -> None:
    rng = np.random.default_rng(7)
    compared = near = 0
    for _ in range(15):
        obstacle = random_obstacle(rng)
        clearance = CoalClearance(arm, obstacle)
        qs = rng.uniform(-np.pi, np.pi, size=(400, 2))
        coal_values = clearance.link_clearance(qs)
        # Every configuration where some link is within 5 cm, plus a few far ones.
        close = np.flatnonzero(np.any(coal_values < 0.05, axis=1))
        chosen = np.concatenate([close[:40], np.arange(10)])
        for row in chosen:
            reference = reference_clearance(qs[row], obstacle)
            positive = coal_values[row] > 0
            decided = np.abs(reference) > 1e-9
            assert np.array_equal((reference > 0)[decided], positive[decided])
            assert_allclose(coal_values[row][positive], reference[positive], rtol=0, atol=1e-6)
            compared += int(positive.sum())
            near += int(np.sum(positive & (coal_values[row] < 0.05)))
    assert near > 100, "too few configurations near the obstacle to mean anything"
    assert compared > 300


def test_coal_route_matches_reference_on_the_paper_obstacles(arm: PlanarArm) -> None:
    """Test 1 and Test 9 obstacles, arm sweeping over the obstacle at a fixed elbow angle."""
    for length, width in ((0.30, 0.12), (0.20, 0.08)):
        obstacle = Obstacle(length, width)
        clearance = CoalClearance(arm, obstacle)
        for q1 in np.linspace(0.0, np.pi, 40):
            q = np.array([q1, 0.9])
            coal_values = clearance.link_clearance(q)
            reference = reference_clearance(q, obstacle)
            positive = coal_values > 0
            assert_allclose(coal_values[positive], reference[positive], rtol=0, atol=1e-6)
            assert np.all(reference[~positive] <= 1e-9)


# --------------------------------------------------------------------------------------------
# Fast analytic route against Coal.

q_angles = st.floats(-math.pi, math.pi)


@settings(max_examples=100, deadline=None, derandomize=True)
@given(q_angles, q_angles, st.floats(0.10, 0.40), st.floats(0.05, 0.20), st.floats(0.0, 1.0))
@example(math.pi / 2, 0.0, 0.30, 0.12, 1 / 6)  # straight up through the paper's obstacle
@example(0.0, 0.0, 0.30, 0.12, 1 / 6)  # straight along +x, far away
@example(1.2, 0.9, 0.20, 0.08, 0.25)
def test_analytic_route_equals_coal(
    arm: PlanarArm, q1: float, q2: float, length: float, width: float, radius_fraction: float
) -> None:
    obstacle = Obstacle(length, width, corner_radius_m=radius_fraction * min(0.03, min(length, width) / 2))
    q = np.array([q1, q2])
    coal_values = CoalClearance(arm, obstacle).link_clearance(q)
    analytic = analytic_link_clearance(q, arm, obstacle)
    positive = coal_values > 0
    assert_allclose(analytic[positive], coal_values[positive], rtol=0, atol=1e-9)
    decided = (np.abs(coal_values) > 1e-9) & (np.abs(analytic) > 1e-9)
    assert np.array_equal(np.sign(analytic[decided]), np.sign(coal_values[decided]))


def test_analytic_route_equals_coal_in_batches(arm: PlanarArm) -> None:
    rng = np.random.default_rng(11)
    for _ in range(6):
        obstacle = random_obstacle(rng)
        qs = rng.uniform(-np.pi, np.pi, size=(3000, 2))
        coal_values = CoalClearance(arm, obstacle).link_clearance(qs)
        analytic = analytic_link_clearance(qs, arm, obstacle)
        assert analytic.shape == coal_values.shape == (3000, 2)
        positive = coal_values > 0
        assert positive.sum() > 1000 and (~positive).sum() > 0
        assert_allclose(analytic[positive], coal_values[positive], rtol=0, atol=1e-9)
        decided = (np.abs(coal_values) > 1e-9) & (np.abs(analytic) > 1e-9)
        assert np.array_equal(np.sign(analytic[decided]), np.sign(coal_values[decided]))


def test_analytic_route_broadcasts(arm: PlanarArm) -> None:
    obstacle = Obstacle(0.25, 0.10)
    qs = np.random.default_rng(5).uniform(-np.pi, np.pi, size=(4, 6, 2))
    batch = analytic_link_clearance(qs, arm, obstacle)
    assert batch.shape == (4, 6, 2)
    single = np.array([[analytic_link_clearance(q, arm, obstacle) for q in row] for row in qs])
    assert_allclose(batch, single, rtol=0, atol=0)


def test_link_box_clearance_per_row_equals_the_analytic_route_and_coal(arm: PlanarArm) -> None:
    """A box per configuration (the certifiable regression's use): each row equals
    analytic_link_clearance of its own obstacle bitwise, and Coal where positive (1e-9 m)."""
    rng = np.random.default_rng(23)
    radius = 0.01
    obstacles = [Obstacle(rng.uniform(0.15, 0.35), rng.uniform(0.06, 0.15), corner_radius_m=radius) for _ in range(40)]
    qs = rng.uniform(-np.pi, np.pi, size=(40, 2))
    center = np.array([o.center_m[:2] for o in obstacles])
    half = np.array([o.core_half_extents_m[:2] for o in obstacles])
    rows = link_box_clearance(qs, arm.link_lengths_m, arm.link_radii_m, center, half, radius)
    assert rows.shape == (40, 2)
    by_obstacle = np.array([analytic_link_clearance(q, arm, o) for q, o in zip(qs, obstacles, strict=True)])
    assert np.array_equal(rows, by_obstacle)
    coal_values = np.array([CoalClearance(arm, o).link_clearance(q) for q, o in zip(qs, obstacles, strict=True)])
    positive = coal_values > 0
    assert positive.sum() > 20
    assert_allclose(rows[positive], coal_values[positive], rtol=0, atol=1e-9)


# --------------------------------------------------------------------------------------------
# Hand-made configurations.


def test_arm_straight_along_x_below_an_obstacle(arm: PlanarArm) -> None:
    """q = 0: link 1 on [0, 0.30] x {0}, link 2 on [0.30, 0.65] x {0}.

    Obstacle x in [-0.10, 0.10], y in [0.20, 0.30], corner radius 0.01: link 1 is under the
    flat near side (0.20 away); link 2 is nearest the rounded corner centred at (0.09, 0.21),
    from its end (0.30, 0).
    """
    obstacle = Obstacle(0.20, 0.10, top_y_m=0.30, corner_radius_m=0.01)
    expected = [0.20 - 0.005, math.hypot(0.30 - 0.09, 0.21) - 0.01 - 0.005]
    q = np.zeros(2)
    assert_allclose(CoalClearance(arm, obstacle).link_clearance(q), expected, rtol=0, atol=1e-9)
    assert_allclose(analytic_link_clearance(q, arm, obstacle), expected, rtol=0, atol=1e-12)
    assert_allclose(reference_clearance(q, obstacle), expected, rtol=0, atol=1e-9)


def test_arm_with_vertical_second_link_beside_an_obstacle(arm: PlanarArm) -> None:
    """q = (0, pi/2): link 2 on {0.30} x [0, 0.35], 0.10 right of the side x = 0.20."""
    obstacle = Obstacle(0.40, 0.10, top_y_m=0.30, corner_radius_m=0.01)
    expected = [0.195, 0.095]
    q = np.array([0.0, np.pi / 2])
    assert_allclose(CoalClearance(arm, obstacle).link_clearance(q), expected, rtol=0, atol=1e-9)
    assert_allclose(analytic_link_clearance(q, arm, obstacle), expected, rtol=0, atol=1e-12)


def test_arm_straight_up_through_the_paper_obstacle(arm: PlanarArm) -> None:
    """q = (pi/2, 0): link 1 ends 0.14 below the obstacle (y from 0.44); link 2 crosses it."""
    obstacle = Obstacle(0.30, 0.12)
    q = np.array([np.pi / 2, 0.0])
    coal_values = CoalClearance(arm, obstacle).link_clearance(q)
    analytic = analytic_link_clearance(q, arm, obstacle)
    assert_allclose(coal_values[0], 0.44 - 0.30 - 0.005, rtol=0, atol=1e-9)
    assert_allclose(analytic[0], 0.44 - 0.30 - 0.005, rtol=0, atol=1e-12)
    assert coal_values[1] < 0
    assert_allclose(analytic[1], -0.005 - 0.01, rtol=0, atol=1e-12)  # minus both radii


def test_arm_just_touching_the_margin(arm: PlanarArm) -> None:
    """Link 2 vertical at x = L/2 + 0.015: exactly 1 cm of clearance to the obstacle's side."""
    obstacle = Obstacle(0.30, 0.12)
    x = 0.15 + 0.015
    # Elbow at (x, y_e) on the circle of radius 0.30 with link 2 pointing straight up.
    q1 = math.acos(x / L1)
    q = np.array([q1, np.pi / 2 - q1])
    assert_allclose(CoalClearance(arm, obstacle).link_clearance(q)[1], 0.01, rtol=0, atol=1e-9)
    assert_allclose(analytic_link_clearance(q, arm, obstacle)[1], 0.01, rtol=0, atol=1e-12)


def test_coal_clearance_is_exact_for_a_link_passing_below_a_corner(arm: PlanarArm) -> None:
    """BUG (pipeline/clearance.py, CoalClearance): Coal's GJK is left at its default
    ``gjk_tolerance`` of 1e-6, so the canonical route overestimates clearance (the unsafe
    side) by up to about 1.4e-6 m, and it does not equal the analytic route to 1e-9 as the
    module promises. Setting ``gjk_tolerance = 1e-10`` on every request of
    ``_geometry_data.distanceRequests`` makes the two agree to 1e-15 at no cost.

    q1 = 0.02: link 1 runs from the origin at 0.02 rad above +x; the nearest point of the
    paper's obstacle is its rounded corner centred at (0.14, 0.45), whose distance to the
    line of link 1 is 0.45 cos 0.02 - 0.14 sin 0.02 (the foot of the perpendicular lies
    inside the link). Link 1's clearance cannot depend on q2; sweeping q2 changes only the
    GJK warm start, and Coal's answer drifts by about 1.2e-6 m.
    """
    obstacle = Obstacle(0.30, 0.12)
    qs = np.column_stack([np.full(61, 0.02), np.linspace(-np.pi, np.pi, 61)])
    by_hand = 0.45 * math.cos(0.02) - 0.14 * math.sin(0.02) - 0.01 - 0.005
    assert_allclose(analytic_link_clearance(qs, arm, obstacle)[:, 0], by_hand, rtol=0, atol=1e-12)
    assert_allclose(reference_clearance(qs[0], obstacle)[0], by_hand, rtol=0, atol=1e-12)
    assert_allclose(CoalClearance(arm, obstacle).link_clearance(qs)[:, 0], by_hand, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------------------------
# The query counter.


def test_queries_counter(arm: PlanarArm) -> None:
    clearance = CoalClearance(arm, Obstacle(0.25, 0.10))
    assert clearance.queries == 0
    clearance.link_clearance(np.zeros(2))
    assert clearance.queries == 2  # one per link
    clearance.link_clearance(np.zeros((7, 2)))
    assert clearance.queries == 2 + 14
    clearance.link_clearance(np.zeros((0, 2)))
    assert clearance.queries == 16
    analytic_link_clearance(np.zeros((5, 2)), arm, clearance.obstacle)
    assert clearance.queries == 16  # the analytic route does not query Coal
    other = CoalClearance(arm, Obstacle(0.25, 0.10))
    other.link_clearance(np.zeros((3, 2)))
    assert (clearance.queries, other.queries) == (16, 6)


def test_coal_clearance_shapes(arm: PlanarArm) -> None:
    clearance = CoalClearance(arm, Obstacle(0.25, 0.10))
    assert clearance.link_clearance(np.array([0.3, 0.2])).shape == (2,)
    assert clearance.link_clearance(np.zeros((5, 2))).shape == (5, 2)


def test_coal_clearance_leaves_the_arm_alone(arm: PlanarArm) -> None:
    before = arm.collision_model.ngeoms
    CoalClearance(arm, Obstacle(0.25, 0.10)).link_clearance(np.zeros(2))
    assert arm.collision_model.ngeoms == before == 2


# --------------------------------------------------------------------------------------------
# When the fast route applies.


def test_check_fast_route(arm: PlanarArm, double_pendulum_urdf: Path) -> None:
    check_fast_route(arm)  # the paper's arm: capsules in the xy plane
    with pytest.raises(RobotModelError, match="CoalClearance"):
        check_fast_route(load_planar_arm(double_pendulum_urdf))


_FLIPPED_ARM = """<?xml version="1.0"?>
<robot name="flipped">
  <link name="base_link"/>
  <link name="link1"><collision><origin xyz="0.15 0 0" rpy="0 1.5707963267948966 0"/>
    <geometry><cylinder radius="0.005" length="0.30"/></geometry></collision></link>
  <link name="link2"><collision><origin xyz="0.175 0 0" rpy="0 1.5707963267948966 0"/>
    <geometry><cylinder radius="0.005" length="0.35"/></geometry></collision></link>
  <link name="end_effector"/>
  <joint name="joint1" type="revolute"><parent link="base_link"/><child link="link1"/>
    <origin xyz="0 0 0" rpy="3.141592653589793 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="3"/></joint>
  <joint name="joint2" type="revolute"><parent link="link1"/><child link="link2"/>
    <origin xyz="0.30 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="3"/></joint>
  <joint name="ee" type="fixed"><parent link="link2"/><child link="end_effector"/>
    <origin xyz="0.35 0 0"/></joint>
</robot>
"""


def test_fast_route_is_exact_or_refused_for_an_arm_turning_about_minus_z(tmp_path: Path) -> None:
    """BUG (pipeline/robot.py PlanarArm.is_horizontal_xy + pipeline/clearance.py).

    This arm's first joint frame is turned by pi about x, so both joints turn about -z in the
    base frame: it moves in the xy plane, but clockwise for positive q (plane_y = -y).
    ``is_horizontal_xy`` compares ``np.abs(axis)`` with z, so ``check_fast_route`` accepts the
    arm, while ``analytic_link_clearance`` (``link_segments``) places the links as if they
    turned about +z: it computes the clearance of the arm mirrored about the x axis. Either
    the fast route must refuse this arm, or it must agree with Coal.
    """
    path = tmp_path / "flipped.urdf"
    path.write_text(_FLIPPED_ARM)
    flipped = load_planar_arm(path)
    assert_allclose(flipped.axis, [0, 0, -1], rtol=0, atol=1e-12)
    q = np.array([np.pi / 2, 0.0])
    # Pointing "up" in joint space, the arm points down (-y) in the base frame, away from the obstacle.
    assert_allclose(flipped.end_effector_position(q)[:2], [0.0, -0.65], rtol=0, atol=1e-12)
    obstacle = Obstacle(0.30, 0.12)
    coal_values = CoalClearance(flipped, obstacle).link_clearance(q)
    assert_allclose(coal_values, [0.435, 0.735], rtol=0, atol=1e-9)
    try:
        check_fast_route(flipped)
    except RobotModelError:
        return  # refused: fine
    assert_allclose(analytic_link_clearance(q, flipped, obstacle), coal_values, rtol=0, atol=1e-9)
