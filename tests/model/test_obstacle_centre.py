"""The obstacle's centre x (pipeline.model.obstacle): the box, its footprint and its Coal placement
move by exactly the centre x; at 0 they are the paper's; Coal's distances to the moved box equal
a planar point/segment-to-rounded-box distance written out here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import CoalClearance, PinocchioCoalClearance
from pipeline.model.arm import PlanarArm
from pipeline.model.kinematics import inverse_kinematics
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import desired_path

D = 0.56
SIZES = [(0.30, 0.12), (0.25, 0.10), (0.20, 0.08)]


def test_at_centre_0_the_box_is_the_papers() -> None:
    """x in [-L/2, L/2], y in [d - W, d]: the same floats as the obstacle without a centre x."""
    for length, width in SIZES:
        obstacle = Obstacle.in_scene(length, width, Scene())
        assert obstacle.centre_x_m == 0.0
        assert obstacle == Obstacle(length, width, D, 0.01, 1.0)
        half = length / 2
        assert obstacle.center_m.tolist() == [0.0, D - width / 2.0, 0.0]
        expected = [[half, D - width], [half, D], [-half, D], [-half, D - width]]
        assert obstacle.footprint_corners_m().tolist() == expected
        assert np.array(obstacle.placement.translation).tolist() == [0.0, D - width / 2.0, 0.0]


@settings(max_examples=100, deadline=None)
@given(st.floats(-0.05, 0.05), st.floats(0.15, 0.35), st.floats(0.06, 0.14))
@example(0.05, 0.30, 0.12)
@example(-0.05, 0.20, 0.08)
@example(1e-300, 0.25, 0.10)
def test_the_centre_moves_the_box_by_exactly_x(centre: float, length: float, width: float) -> None:
    base = Obstacle.in_scene(length, width, Scene())
    moved = Obstacle.in_scene(length, width, Scene(centre_x_m=centre))
    assert moved.centre_x_m == centre
    assert moved.center_m.tolist() == (base.center_m + [centre, 0.0, 0.0]).tolist()
    assert moved.footprint_corners_m().tolist() == (base.footprint_corners_m() + [centre, 0.0]).tolist()
    assert np.array(moved.placement.translation).tolist() == moved.center_m.tolist()
    # Only the placement moves: the shape in its own frame is the same.
    assert moved.core_half_extents_m.tolist() == base.core_half_extents_m.tolist()


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_centre_must_be_finite(bad: float) -> None:
    with pytest.raises(InvalidParameterError) as info:
        Obstacle(0.25, 0.10, centre_x_m=bad)
    assert info.value.name == "centre_x_m"


# --------------------------------------------------------------------------------------------
# Coal against a planar distance written out here.


def point_rectangle_distance(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """Distance from the point p to the closed axis-aligned rectangle [lo, hi]."""
    return float(np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0)))


def point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    s = min(max(float(np.dot(p - a, ab) / np.dot(ab, ab)), 0.0), 1.0)
    return float(np.linalg.norm(a + s * ab - p))


def segment_rounded_box_distance(a: np.ndarray, b: np.ndarray, obstacle: Obstacle) -> float:
    """Distance from segment a-b to the rounded box: to its core rectangle, less the corner radius.

    For a segment that does not meet the rectangle the nearest pair has an end of the segment or
    a corner of the rectangle in it."""
    centre, half = obstacle.center_m[:2], obstacle.core_half_extents_m[:2]
    lo, hi = centre - half, centre + half
    corners = [np.array([x, y]) for x in (lo[0], hi[0]) for y in (lo[1], hi[1])]
    core = min(
        point_rectangle_distance(a, lo, hi),
        point_rectangle_distance(b, lo, hi),
        *(point_segment_distance(c, a, b) for c in corners),
    )
    return core - obstacle.corner_radius_m


def poses_along_the_path(arm: PlanarArm, obstacle: Obstacle, scene: Scene) -> np.ndarray:
    """Configurations whose tip lies on the moved path at a few times (IK, elbow up)."""
    path = desired_path(obstacle, scene)
    times = np.linspace(0.0, path.duration_s, 9)
    return np.array([inverse_kinematics(p, arm.link_lengths_m, 1) for p in path.position_at_time(times)])


@pytest.mark.parametrize("centre", [-0.05, -0.012, 0.03, 0.05])
@pytest.mark.parametrize("size", SIZES)
def test_coal_distance_to_the_moved_box_is_the_planar_distance(
    arm: PlanarArm, centre: float, size: tuple[float, float]
) -> None:
    scene = Scene(centre_x_m=centre)
    obstacle = Obstacle.in_scene(*size, scene)
    poses = poses_along_the_path(arm, obstacle, scene)
    l1, l2 = arm.link_lengths_m
    coal_route = CoalClearance(arm, obstacle).link_clearance(poses)
    pinocchio_route = PinocchioCoalClearance(arm, obstacle).link_clearance(poses)
    assert_allclose(pinocchio_route, coal_route, rtol=0, atol=1e-12)
    for q, measured in zip(poses, coal_route, strict=True):
        elbow = np.array([l1 * math.cos(q[0]), l1 * math.sin(q[0])])
        tip = elbow + np.array([l2 * math.cos(q[0] + q[1]), l2 * math.sin(q[0] + q[1])])
        expected = [
            segment_rounded_box_distance(np.zeros(2), elbow, obstacle) - arm.link_radii_m[0],
            segment_rounded_box_distance(elbow, tip, obstacle) - arm.link_radii_m[1],
        ]
        assert min(expected) > 0  # the formula holds where the links clear the box
        assert_allclose(measured, expected, rtol=0, atol=1e-9)
