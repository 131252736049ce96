"""The rounded obstacle (pipeline.model.obstacle): exact L x W footprint, rounded corners, bad input."""

from __future__ import annotations

import math

import coal
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pipeline.exceptions import InvalidParameterError
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene

D = 0.56  # the paper's d

_POINT = coal.Sphere(0.0)


def signed_distance(obstacle: Obstacle, xy: tuple[float, float], z: float = 0.0) -> float:
    """Coal's signed distance [m] from the point (x, y, z) to the obstacle placed in the scene."""
    placement = coal.Transform3s(np.eye(3), obstacle.center_m)
    point = coal.Transform3s(np.eye(3), np.array([xy[0], xy[1], z]))
    return coal.distance(obstacle.coal_shape(), placement, _POINT, point, coal.DistanceRequest(), coal.DistanceResult())


def footprint_aabb(obstacle: Obstacle) -> np.ndarray:
    """[[xmin, ymin, zmin], [xmax, ymax, zmax]] of the Coal shape, in the scene frame."""
    shape = obstacle.coal_shape()
    shape.computeLocalAABB()
    return np.array([shape.aabb_local.min_, shape.aabb_local.max_]) + obstacle.center_m


sizes = st.tuples(
    st.floats(0.05, 0.6),  # L
    st.floats(0.03, 0.3),  # W
    st.floats(0.0, 1.0),  # corner radius as a fraction of min(L, W) / 2
    st.floats(0.2, 0.8),  # d
)


@settings(max_examples=60, deadline=None)
@given(sizes)
@example((0.30, 0.12, 0.01 / 0.06, D))
@example((0.20, 0.08, 1.0, D))
@example((0.25, 0.10, 0.0, D))
def test_footprint_is_exactly_L_by_W(size: tuple[float, float, float, float]) -> None:
    length, width, fraction, d = size
    radius = fraction * min(length, width) / 2
    obstacle = Obstacle(length, width, top_y_m=d, corner_radius_m=radius)
    aabb = footprint_aabb(obstacle)
    assert_allclose(aabb[0, :2], [-length / 2, d - width], rtol=0, atol=1e-12)
    assert_allclose(aabb[1, :2], [length / 2, d], rtol=0, atol=1e-12)
    assert_allclose(aabb[:, 2], [-0.5, 0.5], rtol=0, atol=1e-12)  # height 1 m centred on the plane
    assert_allclose(obstacle.coal_shape().getSweptSphereRadius(), radius, rtol=0, atol=0)
    corners = obstacle.footprint_corners_m()
    assert_allclose(
        corners,
        [[length / 2, d - width], [length / 2, d], [-length / 2, d], [-length / 2, d - width]],
        rtol=0,
        atol=1e-15,
    )


@settings(max_examples=60, deadline=None)
@given(sizes, st.floats(1e-4, 0.05))
@example((0.30, 0.12, 0.01 / 0.06, D), 1e-3)
def test_probes_beside_each_side(size: tuple[float, float, float, float], gap: float) -> None:
    """A point ``gap`` outside the middle of each side is exactly ``gap`` away; inside, -gap."""
    length, width, fraction, d = size
    obstacle = Obstacle(length, width, top_y_m=d, corner_radius_m=fraction * min(length, width) / 2)
    middle_y = d - width / 2
    outward = {
        "right": ((length / 2, middle_y), (1, 0)),
        "left": ((-length / 2, middle_y), (-1, 0)),
        "far": ((0.0, d), (0, 1)),
        "near": ((0.0, d - width), (0, -1)),
    }
    for (x, y), (nx, ny) in outward.values():
        assert_allclose(signed_distance(obstacle, (x + gap * nx, y + gap * ny)), gap, rtol=0, atol=1e-9)
        inside = min(gap, width / 4, length / 4)
        assert_allclose(signed_distance(obstacle, (x - inside * nx, y - inside * ny)), -inside, rtol=0, atol=1e-9)


def test_paper_obstacle_hand_values() -> None:
    obstacle = Obstacle.in_scene(0.30, 0.12, Scene())
    assert_allclose(obstacle.center_m, [0.0, 0.50, 0.0], rtol=0, atol=1e-15)
    assert_allclose(obstacle.core_half_extents_m, [0.14, 0.05, 0.49], rtol=0, atol=1e-15)
    # 2 cm right of the right side, 3 cm below the near side: closest to the rounded corner.
    core_corner = np.array([0.14, 0.45])
    probe = np.array([0.17, 0.41])
    assert_allclose(signed_distance(obstacle, probe), np.linalg.norm(probe - core_corner) - 0.01, atol=1e-9, rtol=0)
    assert_allclose(signed_distance(obstacle, (0.0, 0.0)), 0.44, rtol=0, atol=1e-9)


@pytest.mark.parametrize("radius", [0.0, 0.005, 0.01, 0.03, 0.04])
def test_corner_radius(radius: float) -> None:
    length, width = 0.20, 0.08
    obstacle = Obstacle(length, width, top_y_m=D, corner_radius_m=radius)
    core = np.array([length / 2 - radius, D - radius])  # centre of the far right corner's arc
    diagonal = np.array([1.0, 1.0]) / math.sqrt(2.0)
    # The sharp corner of the footprint lies outside the rounded shape by r (sqrt 2 - 1).
    assert_allclose(signed_distance(obstacle, (length / 2, D)), radius * (math.sqrt(2) - 1), rtol=0, atol=1e-9)
    # Along the diagonal, distances are measured from the arc: |p - centre| - r.
    for gap in (1e-3, 0.01, 0.05):
        probe = core + (radius + gap) * diagonal
        assert_allclose(signed_distance(obstacle, probe), gap, rtol=0, atol=1e-9)
    # Every corner behaves the same (the shape is symmetric about its centre).
    for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        sharp = (sx * length / 2, D - width / 2 + sy * width / 2)
        assert_allclose(signed_distance(obstacle, sharp), radius * (math.sqrt(2) - 1), rtol=0, atol=1e-9)


def test_largest_corner_radius_is_allowed() -> None:
    """r = min(L, W) / 2 makes a stadium: flat long sides, semicircular ends."""
    obstacle = Obstacle(0.20, 0.08, top_y_m=D, corner_radius_m=0.04)
    assert_allclose(obstacle.core_half_extents_m[:2], [0.06, 0.0], rtol=0, atol=1e-15)
    assert_allclose(footprint_aabb(obstacle)[:, :2], [[-0.10, D - 0.08], [0.10, D]], rtol=0, atol=1e-12)
    assert_allclose(signed_distance(obstacle, (0.11, D - 0.04)), 0.01, rtol=0, atol=1e-9)


def test_in_scene_takes_the_scene_settings() -> None:
    scene = Scene(top_y_m=0.5, corner_radius_m=0.02, obstacle_height_m=0.4)
    obstacle = Obstacle.in_scene(0.25, 0.10, scene)
    assert (obstacle.length_m, obstacle.width_m, obstacle.top_y_m) == (0.25, 0.10, 0.5)
    assert (obstacle.corner_radius_m, obstacle.height_m) == (0.02, 0.4)
    assert_allclose(footprint_aabb(obstacle), [[-0.125, 0.4, -0.2], [0.125, 0.5, 0.2]], rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------------
# InvalidParameterError.

bad_sizes = st.one_of(
    st.floats(max_value=0.0, allow_nan=False),  # zero, negative, -inf
    st.just(math.nan),
    st.just(math.inf),
    st.just(-math.inf),
)


@settings(max_examples=60, deadline=None)
@given(bad_sizes)
def test_bad_length(value: float) -> None:
    with pytest.raises(InvalidParameterError) as info:
        Obstacle(value, 0.10)
    assert info.value.name.startswith("L")


@settings(max_examples=60, deadline=None)
@given(bad_sizes)
def test_bad_width(value: float) -> None:
    with pytest.raises(InvalidParameterError) as info:
        Obstacle(0.25, value)
    assert info.value.name.startswith("W")


@pytest.mark.parametrize("value", ["abc", None, [0.3]])
def test_non_numeric_length(value: object) -> None:
    with pytest.raises(InvalidParameterError):
        Obstacle(value, 0.10)  # type: ignore[arg-type]


@settings(max_examples=60, deadline=None)
@given(st.floats(0.02, 0.6), st.floats(0.02, 0.3), st.floats(1e-9, 1.0))
def test_corner_radius_above_half_the_smaller_side(length: float, width: float, excess: float) -> None:
    limit = min(length, width) / 2
    radius = limit * (1 + excess)
    if radius <= limit:  # rounding of a tiny excess
        radius = np.nextafter(limit, np.inf)
    with pytest.raises(InvalidParameterError) as info:
        Obstacle(length, width, corner_radius_m=radius)
    assert info.value.name == "corner_radius_m"


@pytest.mark.parametrize("radius", [-1e-6, -0.01, math.nan, math.inf])
def test_corner_radius_negative_or_not_finite(radius: float) -> None:
    with pytest.raises(InvalidParameterError):
        Obstacle(0.25, 0.10, corner_radius_m=radius)


@pytest.mark.parametrize("top", [math.nan, math.inf, -math.inf])
def test_top_y_not_finite(top: float) -> None:
    with pytest.raises(InvalidParameterError):
        Obstacle(0.25, 0.10, top_y_m=top)


def test_invalid_parameter_error_reports_the_value() -> None:
    with pytest.raises(InvalidParameterError, match=r"-0\.3") as info:
        Obstacle(-0.3, 0.10)
    assert info.value.value == -0.3
    assert isinstance(info.value, ValueError)
