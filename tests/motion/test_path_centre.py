"""The desired path around an obstacle off the y axis (pipeline.motion.path): P1..P5 move with the
obstacle's centre x, the general quartic passes through them, its arc length agrees with scipy's
quad and with the centred path's, and with centre 0 every number is the symmetric route's."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.integrate import quad

from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import (
    QuarticPath,
    constraint_points,
    desired_path,
    quartic_length_m,
    symmetric_quartic,
    symmetric_quartic_length_m,
)

D, SPEED = 0.56, 0.2
CENTRES = [-0.05, -0.02, 0.013, 0.05]
SIZES = [(0.30, 0.12), (0.25, 0.10), (0.20, 0.08), (0.27, 0.09)]

#: The symmetric route's numbers for the paper's scene, as float.hex: length, duration, (c4, c2, c0)
#: and x at arc lengths 0.1 and 0.3 m.
GOLDEN = {
    (0.30, 0.12): (
        "0x1.7fc75ccdbfb7ep-1",
        "0x1.dfb934012fa5dp+1",
        ("0x1.52b3a64ad1edep+4", "0x1.7980e0bf08c6ep+0", "0x1.5c28f5c28f5c4p-2"),
        ("0x1.cea25b7a3409ap-3", "0x1.2f71d11847275p-4"),
    ),
    (0.25, 0.10): (
        "0x1.5565ca13fd921p-1",
        "0x1.aabf3c98fcf69p+1",
        ("0x1.73d58921eddf7p+3", "0x1.51362ac0343b6p+1", "0x1.70a3d70a3d70cp-2"),
        ("0x1.8bc01e9714019p-3", "0x1.102e4e656cea7p-5"),
    ),
    (0.20, 0.08): (
        "0x1.2ced6f8eafe2dp-1",
        "0x1.7828cb725bdb8p+1",
        ("-0x1.adb7c918a46dfp+3", "0x1.179cfc2be009bp+2", "0x1.851eb851eb852p-2"),
        ("0x1.447e2d030c8e9p-3", "-0x1.913ff22f2e1a7p-8"),
    ),
    (0.27, 0.09): (
        "0x1.5645bc8ecebc0p-1",
        "0x1.abd72bb2826b0p+1",
        ("0x1.28f662c163cc1p+3", "0x1.28c522f044b31p+1", "0x1.7ae147ae147b0p-2"),
        ("0x1.98929f43eb63ep-3", "0x1.1767e560c56a7p-5"),
    ),
}


def path_for(length: float, width: float, centre: float = 0.0) -> QuarticPath:
    scene = Scene(centre_x_m=centre)
    return desired_path(Obstacle.in_scene(length, width, scene), scene)


def quad_arc_length(path: QuarticPath, x_from: float, x_to: float) -> float:
    """Arc length of y(x) between x_from and x_to by adaptive quadrature, from the coefficients."""
    derivative = np.polyder(np.poly1d(path.coefficients))
    value, _ = quad(lambda x: math.sqrt(1.0 + derivative(x) ** 2), x_from, x_to, epsabs=1e-15, epsrel=1e-13, limit=200)
    return abs(value)


# --------------------------------------------------------------------------------------------
# Centre 0: the symmetric route, bit for bit.


@pytest.mark.parametrize("centre", [0.0, -0.0, 0])
@pytest.mark.parametrize("size", SIZES)
def test_centre_0_is_the_symmetric_route_bit_for_bit(size: tuple[float, float], centre: float) -> None:
    """Bit for bit against the symmetric closed form computed here, and within 2 ulp of the
    figures the symmetric route gave before the centre existed (GOLDEN: NumPy's dot products may
    differ in the last bit between builds, so the recorded figures hold to the ulp, not the bit)."""
    path = path_for(*size, centre)
    scene, (L, W) = Scene(), size
    bottom = scene.top_y_m - W
    x1, x2 = L / 2.0 + scene.start_dx_m, L / 2.0 + scene.approach_dx_m
    c4_now, c2_now, c0_now = symmetric_quartic(
        x1, scene.y1_m, x2, bottom - scene.approach_dy_m, bottom - scene.apex_dy_m
    )
    assert path.coefficients.tolist() == [c4_now, 0.0, c2_now, 0.0, c0_now]
    assert path.length_m == symmetric_quartic_length_m(x1, c4_now, c2_now)
    assert path.duration_s == path.length_m / scene.speed_m_s
    length, duration, (c4, c2, c0), xs = GOLDEN[size]
    recorded = [length, duration, c4, c2, c0, *xs]
    now = [path.length_m, path.duration_s, c4_now, c2_now, c0_now, *path.x_at_arc_length(np.array([0.1, 0.3]))]
    np.testing.assert_array_max_ulp(np.array(now), np.array([float.fromhex(v) for v in recorded]), maxulp=2)
    # ... and the closed form the online generator evaluates from the scene's numbers.
    half = size[0] / 2.0
    bottom = D - size[1]
    expected_points = [
        [half + 0.12, D],
        [half + 0.03, bottom - 0.03],
        [0.0, bottom - 0.10],
        [-(half + 0.03), bottom - 0.03],
        [-(half + 0.12), D],
    ]
    assert path.points_m.tolist() == expected_points
    c4_closed, c2_closed, _ = symmetric_quartic(half + 0.12, D, half + 0.03, bottom - 0.03, bottom - 0.10)
    assert path.length_m == symmetric_quartic_length_m(half + 0.12, c4_closed, c2_closed)


# --------------------------------------------------------------------------------------------
# The general quartic.


@pytest.mark.parametrize("centre", CENTRES)
@pytest.mark.parametrize("size", SIZES)
def test_general_quartic_through_the_five_points(size: tuple[float, float], centre: float) -> None:
    path = path_for(*size, centre)
    assert path.coefficients[1] != 0.0 and path.coefficients[3] != 0.0  # not the even quartic
    assert_allclose(path.y(path.points_m[:, 0]), path.points_m[:, 1], rtol=0, atol=1e-12)
    assert_allclose(path.position_at_time(0.0), path.points_m[0], rtol=0, atol=1e-12)
    assert_allclose(path.position_at_time(path.duration_s), path.points_m[-1], rtol=0, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-0.05, 0.05),
    st.sampled_from(SIZES),
    st.lists(st.floats(-0.02, 0.02), min_size=5, max_size=5),
    st.lists(st.floats(-0.01, 0.01), min_size=2, max_size=2),
)
def test_asymmetric_five_points(centre: float, size: tuple[float, float], dy: list[float], dx: list[float]) -> None:
    """Five points that are in general no mirror images about any line: a scene's P1..P5 with each
    height moved by up to 2 cm and P2, P4 moved sideways by up to 1 cm. The quartic passes through each
    point, and its length by the fixed rule agrees with quad."""
    scene = Scene(centre_x_m=centre)
    points = constraint_points(Obstacle.in_scene(*size, scene), scene)
    points[:, 1] += dy
    points[[1, 3], 0] += dx
    path = QuarticPath(points, SPEED)
    assert_allclose(path.y(points[:, 0]), points[:, 1], rtol=0, atol=1e-12)
    reference = quad_arc_length(path, path.end_x_m, path.start_x_m)
    assert path.length_m == pytest.approx(reference, rel=1e-9, abs=0)


@pytest.mark.parametrize("centre", CENTRES)
@pytest.mark.parametrize("size", SIZES)
def test_general_length_equals_quad(size: tuple[float, float], centre: float) -> None:
    path = path_for(*size, centre)
    reference = quad_arc_length(path, path.end_x_m, path.start_x_m)
    assert path.length_m == pytest.approx(reference, rel=1e-9, abs=0)
    assert path.duration_s == path.length_m / SPEED
    # Partial arc lengths (the 64-panel table) against quad too, and their inverse.
    x = np.linspace(path.start_x_m, path.end_x_m, 13)
    expected = [quad_arc_length(path, xi, path.start_x_m) for xi in x]
    assert_allclose(path.arc_length(x), expected, rtol=0, atol=1e-12)
    assert path.arc_length(path.end_x_m) == pytest.approx(path.length_m, rel=1e-14, abs=0)
    assert_allclose(path.x_at_arc_length(np.array(expected)), x, rtol=0, atol=1e-12)


def test_quartic_length_splits_at_the_apex() -> None:
    """The general rule on a shifted even quartic is the closed form's, and with any split point
    inside the span it still measures the whole span."""
    c4, c2, c0 = symmetric_quartic(0.27, 0.56, 0.18, 0.43, 0.36)
    symmetric = symmetric_quartic_length_m(0.27, c4, c2)
    assert quartic_length_m(np.array([c4, 0.0, c2, 0.0, c0]), 0.27, 0.0, -0.27) == pytest.approx(symmetric, rel=1e-15)
    off_centre = quartic_length_m(np.array([c4, 0.0, c2, 0.0, c0]), 0.27, 0.05, -0.27)
    assert off_centre == pytest.approx(symmetric, rel=1e-12)


# --------------------------------------------------------------------------------------------
# Moving the obstacle moves the path.


@settings(max_examples=100, deadline=None)
@given(st.floats(-0.05, 0.05), st.sampled_from(SIZES))
@example(0.05, (0.30, 0.12))
@example(-0.05, (0.20, 0.08))
@example(1e-12, (0.25, 0.10))
def test_shift_moves_the_points_and_footprint_by_x_and_keeps_the_length(
    centre: float, size: tuple[float, float]
) -> None:
    scene, moved_scene = Scene(), Scene(centre_x_m=centre)
    centred, moved = Obstacle.in_scene(*size, scene), Obstacle.in_scene(*size, moved_scene)
    shift = np.array([centre, 0.0])
    assert constraint_points(moved, moved_scene).tolist() == (constraint_points(centred, scene) + shift).tolist()
    assert moved.footprint_corners_m().tolist() == (centred.footprint_corners_m() + shift).tolist()
    base, path = desired_path(centred, scene), desired_path(moved, moved_scene)
    assert path.length_m == pytest.approx(base.length_m, rel=1e-12, abs=0)
    assert path.duration_s == pytest.approx(base.duration_s, rel=1e-12, abs=0)
    # The same curve, moved: heights at moved abscissae and positions at equal times.
    x = np.linspace(base.start_x_m, base.end_x_m, 21)
    assert_allclose(path.y(x + centre), base.y(x), rtol=0, atol=1e-12)
    t = np.linspace(0.0, base.duration_s, 9)
    assert_allclose(path.position_at_time(t), base.position_at_time(t) + shift, rtol=0, atol=1e-11)


def test_the_symmetric_route_is_taken_only_at_centre_0() -> None:
    assert path_for(0.25, 0.10)._symmetric
    assert not path_for(0.25, 0.10, 1e-9)._symmetric
    assert "_panels" not in vars(path_for(0.25, 0.10, 0.02))  # the length needs no panel table
