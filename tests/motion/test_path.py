"""The desired path (pipeline.motion.path): quartic through the five constraint points, arc length
against scipy's quad, timing at constant speed, and unreachable obstacles."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.integrate import quad

from pipeline.exceptions import InvalidParameterError, UnreachableObstacleError
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import QuarticPath, constraint_points, desired_path
from pipeline.motion.trajectory import joint_angles

D, SPEED = 0.56, 0.2

# Obstacle sizes a little beyond the DOE range (L 0.20..0.30, W 0.08..0.12).
obstacle_sizes = st.tuples(st.floats(0.15, 0.35), st.floats(0.06, 0.14))


def path_for(length: float, width: float, scene: Scene | None = None) -> QuarticPath:
    scene = Scene() if scene is None else scene
    return desired_path(Obstacle.in_scene(length, width, scene), scene)


def quad_arc_length(path: QuarticPath, x_from: float, x_to: float) -> float:
    """Arc length of y(x) between x_from and x_to by adaptive quadrature, from the coefficients."""
    derivative = np.polyder(np.poly1d(path.coefficients))
    value, _ = quad(lambda x: math.sqrt(1.0 + derivative(x) ** 2), x_from, x_to, epsabs=1e-15, epsrel=1e-13, limit=200)
    return abs(value)


def test_constraint_points_of_test_1() -> None:
    """NOTES.md with y1 = d: P1 = (L/2 + 0.12, d), P2 = (L/2 + 0.03, d - W - 0.03), P3 = (0, d - W - 0.10)."""
    points = constraint_points(Obstacle.in_scene(0.30, 0.12, Scene()), Scene())
    expected = [[0.27, 0.56], [0.18, 0.41], [0.0, 0.34], [-0.18, 0.41], [-0.27, 0.56]]
    assert_allclose(points, expected, rtol=0, atol=1e-15)


def test_start_height_is_a_parameter() -> None:
    scene = Scene(start_y_m=0.0)  # the height the paper's text prints
    points = constraint_points(Obstacle.in_scene(0.30, 0.12, scene), scene)
    assert_allclose(points[[0, 4], 1], [0.0, 0.0], rtol=0, atol=0)
    assert_allclose(points[1:4], [[0.18, 0.41], [0.0, 0.34], [-0.18, 0.41]], rtol=0, atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(obstacle_sizes, st.one_of(st.none(), st.floats(0.3, 0.7)))
@example((0.30, 0.12), None)
@example((0.20, 0.08), None)
def test_quartic_through_the_five_points(size: tuple[float, float], start_y: float | None) -> None:
    scene = Scene(start_y_m=start_y)
    path = path_for(*size, scene)
    points = path.points_m
    assert_allclose(path.y(points[:, 0]), points[:, 1], rtol=0, atol=1e-12)
    assert_allclose(np.polyval(path.coefficients, points[:, 0]), points[:, 1], rtol=0, atol=1e-12)
    assert path.coefficients.shape == (5,)
    assert_allclose(path.points_m, constraint_points(Obstacle.in_scene(*size, scene), scene), rtol=0, atol=0)


@settings(max_examples=60, deadline=None)
@given(obstacle_sizes)
def test_path_is_symmetric(size: tuple[float, float]) -> None:
    path = path_for(*size)
    x = np.linspace(0.0, path.start_x_m, 50)
    assert_allclose(path.y(-x), path.y(x), rtol=0, atol=1e-12)
    assert_allclose(path.slope(-x), -path.slope(x), rtol=0, atol=1e-11)
    assert_allclose(path.coefficients[[1, 3]], [0.0, 0.0], rtol=0, atol=1e-10)  # no odd powers
    assert path.start_x_m > 0 > path.end_x_m
    assert_allclose(path.end_x_m, -path.start_x_m, rtol=0, atol=0)


def test_path_dips_below_the_obstacle(scene: Scene) -> None:
    """Between P2 and P4 the path stays at or below P2's height, under the obstacle's near side."""
    for length, width in ((0.30, 0.12), (0.20, 0.08)):
        path = path_for(length, width)
        x = np.linspace(-length / 2 - 0.03, length / 2 + 0.03, 201)
        assert np.all(path.y(x) <= scene.top_y_m - width - 0.03 + 1e-12)
        assert_allclose(path.y(0.0), scene.top_y_m - width - 0.10, rtol=0, atol=1e-15)


@settings(max_examples=50, deadline=None)
@given(obstacle_sizes, st.floats(0.0, 1.0))
@example((0.30, 0.12), 0.0)
@example((0.30, 0.12), 1.0)
def test_arc_length_equals_quad(size: tuple[float, float], fraction: float) -> None:
    path = path_for(*size)
    x = path.start_x_m + fraction * (path.end_x_m - path.start_x_m)
    assert_allclose(path.arc_length(x), quad_arc_length(path, x, path.start_x_m), rtol=1e-10, atol=1e-15)
    assert_allclose(path.length_m, quad_arc_length(path, path.end_x_m, path.start_x_m), rtol=1e-10, atol=0)


def test_arc_length_vectorised_and_monotone() -> None:
    path = path_for(0.25, 0.10)
    x = np.linspace(path.start_x_m, path.end_x_m, 101)
    s = path.arc_length(x)
    assert s.shape == (101,)
    assert_allclose(s[0], 0.0, rtol=0, atol=0)
    assert_allclose(s[-1], path.length_m, rtol=1e-14, atol=0)
    assert np.all(np.diff(s) > 0)
    assert_allclose(s[50], path.length_m / 2, rtol=1e-12, atol=0)  # symmetric path: x = 0 is half way
    # Outside [P5.x, P1.x] the arc length is clipped.
    assert_allclose(
        path.arc_length([path.start_x_m + 0.1, path.end_x_m - 0.1]), [0.0, path.length_m], rtol=1e-14, atol=0
    )


@settings(max_examples=60, deadline=None)
@given(obstacle_sizes, st.floats(0.0, 1.0))
@example((0.30, 0.12), 0.0)
@example((0.30, 0.12), 1.0)
@example((0.30, 0.12), 0.5)
def test_x_at_arc_length_inverts_arc_length(size: tuple[float, float], fraction: float) -> None:
    path = path_for(*size)
    x = path.start_x_m + fraction * (path.end_x_m - path.start_x_m)
    assert_allclose(path.x_at_arc_length(path.arc_length(x)), x, rtol=0, atol=1e-12)
    s = fraction * path.length_m
    assert_allclose(path.arc_length(path.x_at_arc_length(s)), s, rtol=0, atol=1e-12)


def test_x_at_arc_length_clips() -> None:
    path = path_for(0.25, 0.10)
    assert_allclose(path.x_at_arc_length([-1.0, 10.0]), [path.start_x_m, path.end_x_m], rtol=0, atol=1e-15)


@settings(max_examples=50, deadline=None)
@given(obstacle_sizes)
def test_position_at_start_and_end(size: tuple[float, float]) -> None:
    path = path_for(*size)
    assert_allclose(path.duration_s, path.length_m / SPEED, rtol=1e-15, atol=0)
    assert_allclose(path.position_at_time(0.0), path.points_m[0], rtol=0, atol=1e-12)
    assert_allclose(path.position_at_time(path.duration_s), path.points_m[-1], rtol=0, atol=1e-12)
    assert_allclose(path.time_at_x(path.end_x_m), path.duration_s, rtol=1e-14, atol=0)
    assert_allclose(path.time_at_x(path.start_x_m), 0.0, rtol=0, atol=0)


def test_duration_of_test_1_is_about_3_7_s() -> None:
    """NOTES.md: v = 0.2 m/s brings Test 1's end effector to P5 at about 3.7 s."""
    path = path_for(0.30, 0.12)
    assert 3.65 < path.duration_s < 3.80
    assert_allclose(path.speed_m_s, SPEED, rtol=0, atol=0)
    # Longer path around a larger obstacle takes longer.
    assert path.duration_s > path_for(0.25, 0.12).duration_s > path_for(0.20, 0.12).duration_s
    assert path.duration_s > path_for(0.30, 0.10).duration_s > path_for(0.30, 0.08).duration_s


def test_table_2_follows_this_timing(table2: np.ndarray) -> None:
    """The paper's own Table 2 parameters put the end effector within 1 cm of P1 at t = 0 and
    of P5 at t = T, and within 3.5 cm of the timed path throughout, for all nine tests.

    This fails if the timing (v = 0.2 m/s) or the start height (y1 = d) were wrong.
    """
    for row in table2:
        path = path_for(row[8], row[9])
        t = np.linspace(0.0, path.duration_s, 201)
        q = joint_angles(row[:8], t)
        actual = np.column_stack(
            [
                0.30 * np.cos(q[:, 0]) + 0.35 * np.cos(q[:, 0] + q[:, 1]),
                0.30 * np.sin(q[:, 0]) + 0.35 * np.sin(q[:, 0] + q[:, 1]),
            ]
        )
        error = np.linalg.norm(actual - path.position_at_time(t), axis=1)
        assert error[0] < 0.01 and error[-1] < 0.01, (row[8:], error[0], error[-1])
        assert error.max() < 0.035, (row[8:], error.max())


@settings(max_examples=40, deadline=None)
@given(obstacle_sizes, st.floats(0.001, 0.999))
@example((0.30, 0.12), 0.5)
def test_speed_along_the_path_is_v(size: tuple[float, float], fraction: float) -> None:
    """Finite-difference cross-check: |d position / dt| = v everywhere along the path."""
    path = path_for(*size)
    t = fraction * path.duration_s
    h = 1e-5
    velocity = (path.position_at_time(t + h) - path.position_at_time(t - h)) / (2 * h)
    assert_allclose(np.linalg.norm(velocity), SPEED, rtol=1e-6, atol=0)
    # ... and it points along the path's tangent, from P1 towards P5 (x decreasing).
    tangent = -np.array([1.0, path.slope(path.position_at_time(t)[0])])
    assert_allclose(velocity, SPEED * tangent / np.linalg.norm(tangent), rtol=0, atol=1e-6)


def test_speed_is_v_on_a_dense_grid() -> None:
    path = path_for(0.30, 0.12)
    h = 1e-5
    t = np.linspace(h, path.duration_s - h, 400)
    velocity = (path.position_at_time(t + h) - path.position_at_time(t - h)) / (2 * h)
    assert_allclose(np.linalg.norm(velocity, axis=1), SPEED, rtol=1e-6, atol=0)


def test_other_speed() -> None:
    scene = Scene(speed_m_s=0.1)
    slow, fast = path_for(0.30, 0.12, scene), path_for(0.30, 0.12)
    assert_allclose(slow.duration_s, 2 * fast.duration_s, rtol=1e-14, atol=0)
    assert_allclose(slow.position_at_time(2.0), fast.position_at_time(1.0), rtol=0, atol=1e-13)


def test_samples_are_uniform_in_x() -> None:
    path = path_for(0.25, 0.10)
    times, positions = path.samples(21)
    assert times.shape == (21,) and positions.shape == (21, 2)
    assert_allclose(positions[:, 0], np.linspace(path.start_x_m, path.end_x_m, 21), rtol=0, atol=1e-15)
    assert_allclose(positions[:, 1], path.y(positions[:, 0]), rtol=0, atol=0)
    assert_allclose(times[[0, -1]], [0.0, path.duration_s], rtol=1e-14, atol=1e-15)
    assert np.all(np.diff(times) > 0)
    assert_allclose(path.position_at_time(times), positions, rtol=0, atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(size=obstacle_sizes, n=st.integers(2, 900))
def test_uniform_samples_equal_samples_and_quad(size: tuple[float, float], n: int) -> None:
    """The segment-by-segment arc length gives the panel route's points and times (and quad's)."""
    path = path_for(*size)
    times, positions = path.uniform_samples(n)
    x = np.linspace(path.start_x_m, path.end_x_m, n)
    assert_allclose(positions, np.stack([x, path.y(x)], -1), rtol=0, atol=0)
    # A running sum of up to 900 segments: rounding up to about n * eps * S (3e-13 s at n = 900).
    slack_s = 4 * n * np.finfo(float).eps * path.duration_s
    assert_allclose(times, path.time_at_x(x), rtol=0, atol=slack_s)
    assert times[0] == 0.0 and np.all(np.diff(times) > 0)
    assert times[-1] == pytest.approx(path.duration_s, abs=slack_s)
    middle = n // 2
    length = quad_arc_length(path, x[middle], path.start_x_m)
    assert times[middle] * path.speed_m_s == pytest.approx(length, abs=1e-13 + slack_s * path.speed_m_s)


def test_the_panel_table_is_built_only_when_needed() -> None:
    path = path_for(0.25, 0.10)
    path.uniform_samples(50)
    _ = path.length_m, path.duration_s
    assert "_panels" not in vars(path)  # the symmetric length is closed form
    path.arc_length(0.1)
    assert "_panels" in vars(path)


@pytest.mark.parametrize("n", [6, 0, -3, 7.0, True])
def test_samples_needs_at_least_seven_points(n: object) -> None:
    with pytest.raises(InvalidParameterError):
        path_for(0.25, 0.10).samples(n)  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------
# Reach.


def test_paper_obstacles_are_reachable(arm: PlanarArm, table2: np.ndarray) -> None:
    for length, width in table2[:, 8:]:
        path = desired_path(Obstacle.in_scene(length, width, Scene()), Scene(), arm.reach_m)
        radii = np.hypot(*path.points_m.T)
        assert np.all((radii > arm.reach_m[0]) & (radii < arm.reach_m[1]))


def test_long_obstacle_puts_P1_out_of_reach(arm: PlanarArm) -> None:
    obstacle = Obstacle.in_scene(1.2, 0.10, Scene())
    with pytest.raises(UnreachableObstacleError, match="P1") as info:
        desired_path(obstacle, Scene(), arm.reach_m)
    assert info.value.point_name == "P1"
    assert_allclose(info.value.radius_m, math.hypot(0.6 + 0.12, D), rtol=1e-12, atol=0)
    assert_allclose(info.value.reach_m, (0.05, 0.65), rtol=0, atol=1e-12)
    # Without a reach to check against, the path is still built.
    assert_allclose(desired_path(obstacle, Scene()).points_m[0], [0.72, D], rtol=0, atol=1e-15)


def test_wide_obstacle_puts_P3_inside_the_inner_radius(arm: PlanarArm) -> None:
    """W = 0.42: P3 = (0, 0.56 - 0.42 - 0.10) = (0, 0.04), inside |l1 - l2| = 0.05."""
    with pytest.raises(UnreachableObstacleError) as info:
        desired_path(Obstacle.in_scene(0.30, 0.42, Scene()), Scene(), arm.reach_m)
    assert info.value.point_name == "P3"
    assert_allclose(info.value.radius_m, 0.04, rtol=0, atol=1e-12)
