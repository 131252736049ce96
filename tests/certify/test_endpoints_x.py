"""The end-of-motion certificate (pipeline.certify.endpoints) over cells of (L, W, x), x the
obstacle's centre: the endpoint-error bound against the online generator's end poses and the
moved P1 / P5 of the path module (forward kinematics by Pinocchio), and the infeasibility
certificate against a dense sampling of the poses whose tip lies within the tolerance of the
moved P1 / P5, each against its own moved obstacle (the analytic clearance)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.endpoints import (
    _SubCellSearch,
    _upper_bounds_and_witnesses,
    end_frame_cells,
    endpoint_clearance_upper_bounds,
    endpoint_error_bounds,
    infeasibility_upper_bounds,
)
from pipeline.certify.range_model import RangeModel
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import analytic_link_clearance
from pipeline.model.arm import PlanarArm
from pipeline.model.kinematics import inverse_kinematics_batch
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import constraint_points
from pipeline.offline.coefficients import Coefficients
from pipeline.offline.variables import Variables
from pipeline.online.generator import generate

LWX = Variables(("L", "W", "x"))
X_RANGE = (-0.03, 0.03)
TOLERANCE_M, MARGIN_M = 0.002, 0.01


@pytest.fixture(scope="module")
def eq9() -> Coefficients:
    return load_coefficients("paper")


@pytest.fixture(scope="module")
def eq9_x(eq9: Coefficients, over_x) -> Coefficients:
    return over_x(eq9)


def moved_obstacle(coefficients: Coefficients, L: float, W: float, x: float) -> Obstacle:
    return Obstacle.in_scene(L, W, replace(coefficients.scene, centre_x_m=x))


def best_end_clearance(end_pose_clearance, coefficients: Coefficients, arm: PlanarArm, L: float, W: float, x: float):
    """The shared dense end-pose sampling (``end_pose_clearance``) at the obstacle (L, W, x)."""
    scene = replace(coefficients.scene, centre_x_m=x)
    return end_pose_clearance(coefficients, arm, moved_obstacle(coefficients, L, W, x), scene, TOLERANCE_M)


def test_endpoint_error_bound_holds_at_the_generators_end_poses(
    eq9_x: Coefficients, arm: PlanarArm, random_cells, points_in
) -> None:
    """At the corners, centre and random points of random cells of (L, W, x), the distance from
    the tip (Pinocchio) at t = 0 and t = T to the moved P1 and P5 stays within the bound."""
    model = RangeModel.from_coefficients(eq9_x)
    center, radius = random_cells(model, 24, np.random.default_rng(1), depths=(0, 2, 4, 6, 8))
    bounds = endpoint_error_bounds(model, center, radius)
    assert bounds.shape == (24, 2) and np.all(np.isfinite(bounds))
    rng = np.random.default_rng(2)
    for k in range(center.shape[0]):
        for L, W, x in points_in(center[k], radius[k], rng, 3):
            answer = generate(eq9_x, L, W, x=x, out_of_range="ignore", region_map=None)
            points = constraint_points(moved_obstacle(eq9_x, L, W, x), replace(eq9_x.scene, centre_x_m=x))
            start = np.linalg.norm(arm.end_effector_position(answer.q(0.0))[:2] - points[0])
            end = np.linalg.norm(arm.end_effector_position(answer.q(answer.duration_s))[:2] - points[-1])
            assert start <= bounds[k, 0] + 1e-12
            assert end <= bounds[k, 1] + 1e-12


def test_endpoint_error_bound_is_tight_on_small_cells_and_follows_x(eq9_x: Coefficients, arm: PlanarArm) -> None:
    model = RangeModel.from_coefficients(eq9_x)
    for x in (-0.025, 0.0, 0.02):
        bound = endpoint_error_bounds(model, np.array([[0.23, 0.11, x]]), np.full((1, 3), 1e-4))[0]
        answer = generate(eq9_x, 0.23, 0.11, x=x, region_map=None)
        tips = [arm.end_effector_position(answer.q(t))[:2] for t in (0.0, answer.duration_s)]
        errors = [np.linalg.norm(tips[0] - answer.path.points_m[0]), np.linalg.norm(tips[1] - answer.path.points_m[-1])]
        for error, b in zip(errors, bound, strict=True):
            assert error <= b < error + 2e-4


def test_with_x_fixed_at_zero_the_bounds_are_those_over_length_and_width(eq9: Coefficients, over_x) -> None:
    """Coefficients constant in x, cells of x = 0 with no x extent: the (L, W, x) bounds equal the
    (L, W) ones (the end-pose certificate depends on the geometry alone: the endpoint errors to
    the bit, the infeasibility, bounded in each end's frame over (L, W, x), to rounding)."""
    model2 = RangeModel.from_coefficients(eq9)
    model3 = RangeModel.from_coefficients(over_x(eq9, scale=0.0))
    half = np.array([0.1, 0.04]) / 512
    L = 0.2 + half[0] * (2 * np.arange(0, 256, 23) + 1)
    W = 0.12 - half[1] * (1 + 2 * np.arange(0, 8))
    center2 = np.array([[a, b] for a in L for b in W])
    radius2 = np.tile(half, (center2.shape[0], 1))
    center3 = np.column_stack([center2, np.zeros(center2.shape[0])])
    radius3 = np.column_stack([radius2, np.zeros(center2.shape[0])])
    errors2 = endpoint_error_bounds(model2, center2, radius2)
    np.testing.assert_allclose(endpoint_error_bounds(model3, center3, radius3), errors2, rtol=0, atol=1e-15)
    upper2 = infeasibility_upper_bounds(model2, center2, radius2, TOLERANCE_M, MARGIN_M)
    upper3 = infeasibility_upper_bounds(model3, center3, radius3, TOLERANCE_M, MARGIN_M)
    assert np.any(np.isfinite(upper2))
    # Over (L, W, x) each end is bounded in its own frame (cells formed in floating point): the
    # same cells proven, the bounds equal to rounding.
    assert np.array_equal(np.isfinite(upper2), np.isfinite(upper3))
    finite = np.isfinite(upper2)
    np.testing.assert_allclose(upper3[finite], upper2[finite], rtol=0, atol=1e-15)


def test_cells_are_refused_with_the_wrong_number_of_axes(eq9_x: Coefficients) -> None:
    model = RangeModel.from_coefficients(eq9_x)
    with pytest.raises(InvalidParameterError):
        endpoint_error_bounds(model, np.array([[0.25, 0.1]]), np.array([[1e-3, 1e-3]]))
    with pytest.raises(InvalidParameterError):
        endpoint_clearance_upper_bounds(model, np.array([[0.25, 0.1]]), np.array([[1e-3, 1e-3]]), 0.002, 0.01)


def _band_cells(model: RangeModel, x_centres, x_half: float) -> tuple[np.ndarray, np.ndarray]:
    """Cells of 1/256 of the range in L and W in the top band of W (where the end poses lose the
    margin), across L, at the given x centres with half width ``x_half``."""
    half = np.array([0.1, 0.04]) / 512
    L = 0.2 + half[0] * (2 * np.arange(0, 256, 37) + 1)
    W = 0.12 - half[1] * (1 + 2 * np.arange(0, 10, 2))
    center = np.array([[a, b, x] for a in L for b in W for x in x_centres])
    radius = np.tile([*half, x_half], (center.shape[0], 1))
    return center, radius


@pytest.mark.parametrize("x_half", [0.06 / 512, 0.06 / 128])
def test_infeasibility_bound_holds_against_sampled_end_poses(
    eq9_x: Coefficients, arm: PlanarArm, x_half, points_in, end_pose_clearance
) -> None:
    """Where a cell's end is proven (bound below the margin), no sampled pose near that end's P
    clears more than the bound, at the corners, centre and random points of the cell, each
    against its own moved obstacle; where the sub-cell bound proves the cell, the smaller of the
    two ends' sampled values stays below it at every such point. Some cells are proven, some not."""
    model = RangeModel.from_coefficients(eq9_x)
    center, radius = _band_cells(model, (-0.02, 0.0, 0.025), x_half)
    direct = endpoint_clearance_upper_bounds(model, center, radius, TOLERANCE_M, MARGIN_M)
    refined = infeasibility_upper_bounds(model, center, radius, TOLERANCE_M, MARGIN_M)
    assert np.all(np.isinf(refined) | (refined < MARGIN_M))
    proven = np.isfinite(refined)
    assert 5 <= np.count_nonzero(proven) < center.shape[0]
    assert np.count_nonzero(proven) > np.count_nonzero(direct.min(axis=1) < MARGIN_M)  # the sub-cells help
    rng = np.random.default_rng(3)
    checked = 0
    for k in range(center.shape[0]):
        if not (proven[k] or np.any(direct[k] < MARGIN_M) or rng.uniform() < 0.1):
            continue  # the rest make no claim; a tenth of them is still sampled
        for L, W, x in points_in(center[k], radius[k], rng, 2):
            sampled = best_end_clearance(end_pose_clearance, eq9_x, arm, L, W, x)
            for column in (0, 1):
                if direct[k, column] < MARGIN_M:
                    assert sampled[column] <= direct[k, column] + 1e-12
            if proven[k]:
                assert sampled.min() <= refined[k] + 1e-12
            checked += 1
    assert checked > 100


def test_an_ends_frame_cell_holds_its_end_points_and_an_obstacle_inside_every_obstacle(
    eq9_x: Coefficients, random_cells, points_in
) -> None:
    """At the corners, centre and random points of random cells: P1 (P5) lies within h_x + h_L / 2
    of the frame cell's P1 (P5) at its centre, along x, and the frame cell's O* (length
    L0 - 2 (h_x + h_L / 2), centre x'_c) lies inside the point's own obstacle [x - L / 2, x + L / 2]."""
    model = RangeModel.from_coefficients(eq9_x)
    center, radius = random_cells(model, 60, np.random.default_rng(11), depths=(0, 2, 5, 8))
    dx1 = eq9_x.scene.start_dx_m
    rng = np.random.default_rng(12)
    for side in (1.0, -1.0):
        frame_c, frame_r = end_frame_cells(model, center, radius, side)
        assert np.all(frame_r[:, :2] == 0.0) and np.allclose(frame_r[:, 2], radius[:, 2] + radius[:, 0] / 2)
        L0, xc, hu = frame_c[:, 0], frame_c[:, 2], frame_r[:, 2]
        p_centre = xc + side * (L0 / 2 + dx1)
        near, far = xc - L0 / 2 + hu, xc + L0 / 2 - hu  # O*'s x extent
        for k in range(center.shape[0]):
            assert frame_c[k, 1] == center[k, 1] - radius[k, 1]
            for L, _W, x in points_in(center[k], radius[k], rng, 3):
                assert abs(x + side * (L / 2 + dx1) - p_centre[k]) <= hu[k] + 1e-15
                assert x - L / 2 <= near[k] + 1e-15 and far[k] <= x + L / 2 + 1e-15


def test_the_ends_frame_proves_band_cells_the_cells_own_sub_cells_do_not(eq9_x: Coefficients) -> None:
    """On cells of the top band with an x extent, bounding each end in its frame proves cells that
    halving the cell along L and x (both ends per sub-cell, the bound without the frame) leaves open,
    and none of those."""
    model = RangeModel.from_coefficients(eq9_x)
    center, radius = _band_cells(model, (-0.02, 0.0, 0.025), 0.06 / 512)
    framed = np.isfinite(infeasibility_upper_bounds(model, center, radius, TOLERANCE_M, MARGIN_M))
    search = _SubCellSearch(model, (TOLERANCE_M, MARGIN_M), levels=5, polar_depth=9)
    nested = np.isfinite(search.run(center, radius, (0, 1)))
    assert np.count_nonzero(framed & ~nested) >= 3
    assert not np.any(nested & ~framed)


def test_infeasibility_bound_holds_over_random_cells(
    eq9_x: Coefficients, arm: PlanarArm, random_cells, points_in, end_pose_clearance
) -> None:
    """Random cells of the whole range (mostly feasible at their corners): the same check, and a
    cell where a sampled point keeps the margin at both ends is never proven infeasible."""
    model = RangeModel.from_coefficients(eq9_x)
    center, radius = random_cells(model, 40, np.random.default_rng(4), depths=(3, 5, 7, 9))
    direct = endpoint_clearance_upper_bounds(model, center, radius, TOLERANCE_M, MARGIN_M)
    refined = infeasibility_upper_bounds(model, center, radius, TOLERANCE_M, MARGIN_M)
    rng = np.random.default_rng(5)
    feasible = 0
    for k in range(center.shape[0]):
        for L, W, x in points_in(center[k], radius[k], rng, 1):
            sampled = best_end_clearance(end_pose_clearance, eq9_x, arm, L, W, x)
            assert np.all((direct[k] >= MARGIN_M) | (sampled <= direct[k] + 1e-12))
            assert sampled.min() <= refined[k] + 1e-12
            feasible += bool(sampled.min() >= MARGIN_M)
    assert feasible > 0


def test_witnesses_clear_an_actual_obstacle_of_the_cell(
    eq9_x: Coefficients, arm: PlanarArm, end_pose_clearance
) -> None:
    """The early stop's witness is a pose near P(L0, x0) clearing the margin against the corner's
    own obstacle O(L0, W0, x0), not against the obstacle O* (length L0 - 2 h_x, centre x_c) that
    every obstacle of the cell contains: where one is reported, the sampling at the corner finds
    the margin (to its resolution), and none is reported at corners that miss it by 0.5 mm
    although the pose at P5(L0, x0) clears the margin against O* (cells of a wide x extent; the
    margin 10.5 mm puts the corners of the top band below it)."""
    model = RangeModel.from_coefficients(eq9_x)
    margin = 0.0105
    center, radius = _band_cells(model, (0.0, 0.02), 0.004)
    _, found = _upper_bounds_and_witnesses(model, center, radius, TOLERANCE_M, margin, 9)
    corners = center - radius
    misled = 0  # corners where a witness against O* would exist but none against the corner's obstacle
    for k in range(center.shape[0]):
        L0, W0, x0 = corners[k]
        sampled = best_end_clearance(end_pose_clearance, eq9_x, arm, L0, W0, x0)
        assert np.all(~found[k] | (sampled >= margin - 2e-4))
        p5 = np.array([x0 - (L0 / 2 + eq9_x.scene.start_dx_m), eq9_x.scene.y1_m])
        q = inverse_kinematics_batch(p5, arm.link_lengths_m, eq9_x.elbow)
        inner = moved_obstacle(eq9_x, L0 - 2 * radius[k, 2], W0, center[k, 2])
        clears_inner = analytic_link_clearance(q, arm, inner).min() >= margin
        misled += bool(clears_inner and sampled[1] < margin - 5e-4)
    assert misled > 0


def test_a_cell_without_a_common_obstacle_gets_no_bound(eq9_x: Coefficients) -> None:
    """With L0 - 2 h_x <= 2 r the obstacles of the cell need not share a rounded rectangle: no bound."""
    model = RangeModel.from_coefficients(eq9_x)
    center = np.array([[0.201, 0.119, 0.0], [0.201, 0.119, 0.0]])
    radius = np.array([[0.001, 0.001, 0.0951], [0.001, 0.001, 0.08]])  # L* = 0.0098 m, 0.04 m; 2 r = 0.02 m
    upper = endpoint_clearance_upper_bounds(model, center, radius, TOLERANCE_M, MARGIN_M)
    assert np.all(np.isinf(upper[0])) and np.all(np.isfinite(upper[1]))
    assert np.isinf(infeasibility_upper_bounds(model, center[:1], radius[:1], TOLERANCE_M, MARGIN_M, levels=1)[0])
