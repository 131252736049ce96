"""The range certificate over (L, W, x, d), d the obstacle's far edge y (pipeline.certify.range_model,
clearance_bound, endpoints, range_certificate): the path moves with the obstacle (T does not
depend on d), the clearance bounds over boxes that move the obstacle vertically are below the
clearance sampled inside them (analytic route, and Coal), the endpoint and infeasibility bounds
hold against the moved P1 / P5 and obstacle, at d = d0 with no d extent the bounds are those over
(L, W, x), a coarse map over the four axes is below dense samples, and d is refused where y1 is
fixed.

Every motion here is built from the definitions, not by the online generator: the parameters
from the regression at (L, W, x, d), T from the moved path, the obstacle
``Obstacle.in_scene(L, W, replace(scene, centre_x_m=x, top_y_m=d))``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.build.config import BuildConfig
from pipeline.certify.clearance_bound import box_clearance_bounds
from pipeline.certify.endpoints import (
    endpoint_clearance_upper_bounds,
    endpoint_error_bounds,
    infeasibility_upper_bounds,
)
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.range_model import RangeModel
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance, analytic_link_clearance
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import constraint_points, desired_path
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.coefficients import Coefficients

TOLERANCE_M, MARGIN_M = 0.002, 0.01
D_RANGE = (0.55, 0.57)


@pytest.fixture(scope="module")
def eq9() -> Coefficients:
    return load_coefficients("paper")


@pytest.fixture(scope="module")
def eq9_xd(eq9: Coefficients, over_xd) -> Coefficients:
    return over_xd(eq9, d_range_m=D_RANGE, scale=0.2)


@pytest.fixture(scope="module")
def model_xd(eq9_xd: Coefficients) -> RangeModel:
    return RangeModel.from_coefficients(eq9_xd)


def moved_scene(coefficients: Coefficients, x: float, d: float) -> Scene:
    return replace(coefficients.scene, centre_x_m=x, top_y_m=d)


def motion(coefficients: Coefficients, L: float, W: float, x: float, d: float) -> tuple[JointTrajectory, Obstacle]:
    """The coefficients' trajectory at (L, W, x, d) (T of the moved path) and the moved obstacle."""
    scene = moved_scene(coefficients, x, d)
    obstacle = Obstacle.in_scene(L, W, scene)
    duration = desired_path(obstacle, scene).duration_s
    parameters = coefficients.family.expand(coefficients.predict_free(L, W, x=x, d=d), None)
    return JointTrajectory.trusted(tuple(float(p) for p in parameters), duration), obstacle


def clearance_at(coefficients: Coefficients, arm: PlanarArm, point: np.ndarray, coal: bool = False) -> float:
    """Clearance of both links at (L, W, x, d, s)."""
    L, W, x, d, s = point
    trajectory, obstacle = motion(coefficients, L, W, x, d)
    q = trajectory.q(s * trajectory.duration_s)
    if coal:
        return float(CoalClearance(arm, obstacle).link_clearance(q).min())
    return float(analytic_link_clearance(q, arm, obstacle).min())


def test_model_has_the_axes_and_box(model_xd: RangeModel) -> None:
    assert model_xd.axes.names == ("L", "W", "x", "d") and model_xd.k == 4
    assert (model_xd.x_column, model_xd.d_column) == (2, 3)
    np.testing.assert_allclose(model_xd.range_lo, [0.2, 0.08, -0.03, 0.55], atol=1e-15)
    np.testing.assert_allclose(model_xd.range_size, [0.1, 0.04, 0.06, 0.02], atol=1e-12)


def test_d_is_refused_where_the_start_height_is_fixed(eq9_xd: Coefficients) -> None:
    """With start_y_m set, P1 and P5 stay put while d moves the obstacle: no axis d (the model,
    and a build, which then writes no map)."""
    fixed = replace(eq9_xd, scene=replace(eq9_xd.scene, start_y_m=0.56))
    with pytest.raises(InvalidParameterError, match="y1 = d"):
        RangeModel.from_coefficients(fixed)
    vary = (("x", -0.03, 0.03), ("d", *D_RANGE))
    assert BuildConfig.from_settings(vary=vary).certifiable_axes
    assert BuildConfig.from_settings(vary=vary).certifiable_refit  # the refit's points move the obstacle by x and d
    assert not BuildConfig.from_settings(vary=vary, scene=Scene(start_y_m=0.56)).certifiable_axes
    assert not BuildConfig.from_settings(vary=vary, scene=Scene(start_y_m=0.56)).certifiable_refit


def test_the_path_moves_with_d_and_keeps_its_duration(eq9_xd: Coefficients) -> None:
    """P1..P5 of the moved obstacle are those at d0 moved by (x, d - d0), and T is unchanged."""
    scene = eq9_xd.scene
    for L, W, x, d in [(0.2, 0.08, -0.03, 0.55), (0.3, 0.12, 0.03, 0.57), (0.25, 0.1, 0.01, 0.561)]:
        moved = moved_scene(eq9_xd, x, d)
        points = constraint_points(Obstacle.in_scene(L, W, moved), moved)
        base = constraint_points(Obstacle.in_scene(L, W, scene), scene)
        np.testing.assert_allclose(points, base + [x, d - scene.top_y_m], rtol=0, atol=1e-15)
        T = desired_path(Obstacle.in_scene(L, W, moved), moved).duration_s
        assert T == pytest.approx(desired_path(Obstacle.in_scene(L, W, scene), scene).duration_s, rel=1e-12)


@pytest.mark.parametrize("seed", [11, 12])
def test_box_bounds_are_below_the_sampled_clearance(
    eq9_xd: Coefficients, model_xd: RangeModel, arm: PlanarArm, seed: int, random_boxes
) -> None:
    center, radius = random_boxes(model_xd, 40, np.random.default_rng(seed))
    bounds = box_clearance_bounds(model_xd, center, radius)
    rng = np.random.default_rng(seed + 100)
    corners = np.array([[-1, -1, -1, -1, -1], [1, 1, 1, 1, 1], [1, -1, 1, -1, 1], [-1, 1, -1, 1, -1]], dtype=float)
    for k in range(center.shape[0]):
        inside = np.vstack([corners, rng.uniform(-1.0, 1.0, (10, 5)), np.zeros((1, 5))])
        lowest = min(clearance_at(eq9_xd, arm, center[k] + u * radius[k]) for u in inside)
        assert lowest >= bounds.lower_m[k] - 1e-12
    # The centre value is a clearance the box takes.
    np.testing.assert_allclose(bounds.center_m, [clearance_at(eq9_xd, arm, c) for c in center], atol=1e-9)
    assert np.mean(bounds.lower_m > 0.0) > 0.5  # not vacuous


def test_box_bounds_hold_against_coal(eq9_xd: Coefficients, model_xd: RangeModel, arm: PlanarArm, random_boxes) -> None:
    center, radius = random_boxes(model_xd, 30, np.random.default_rng(21))
    bounds = box_clearance_bounds(model_xd, center, radius).lower_m
    rng = np.random.default_rng(22)
    for k in range(center.shape[0]):
        for u in rng.uniform(-1.0, 1.0, (4, 5)):
            assert clearance_at(eq9_xd, arm, center[k] + u * radius[k], coal=True) >= bounds[k] - COAL_DISTANCE_ERROR_M


def test_moving_the_far_edge_under_the_same_motion_costs_clearance(eq9: Coefficients, over_xd, arm) -> None:
    """Without d terms the arm's motion ignores d (the path moves, the sinusoids do not): the bound
    over a box with a d extent is below the clearance at every d sampled in it, and below the
    bound without it."""
    flat = over_xd(eq9, scale=0.0, d_scale=0.0)
    model = RangeModel.from_coefficients(flat)
    s = np.linspace(0.0, 1.0, 11)
    c = np.column_stack([np.full(11, 0.25), np.full(11, 0.1), np.zeros(11), np.full(11, 0.56), s])
    r0 = np.tile([0.002, 0.001, 0.0, 0.0, 0.01], (11, 1))
    r1 = np.tile([0.002, 0.001, 0.0, 0.005, 0.01], (11, 1))
    b0, b1 = box_clearance_bounds(model, c, r0).lower_m, box_clearance_bounds(model, c, r1).lower_m
    assert np.all(b1 <= b0) and np.any(b1 < b0 - 1e-3)
    for k in range(11):
        for d in np.linspace(0.555, 0.565, 5):
            assert clearance_at(flat, arm, np.array([0.25, 0.1, 0.0, d, s[k]])) >= b1[k] - 1e-12


def test_at_d0_without_d_extent_the_bounds_are_those_over_length_width_and_x(
    eq9: Coefficients, over_x, model_xd: RangeModel
) -> None:
    """At d = d0 (the scene's) with no d extent, the (L, W, x, d) lift gives the (L, W, x) lift's
    parameters, and its clearance, endpoint and infeasibility bounds are the (L, W, x) ones (to
    rounding: the d terms are written out in the basis)."""
    model3 = RangeModel.from_coefficients(over_x(eq9, scale=0.2))
    model4 = model_xd
    d0 = eq9.scene.top_y_m
    rng = np.random.default_rng(31)
    n = 200
    c3 = np.column_stack(
        [rng.uniform(0.21, 0.29, n), rng.uniform(0.085, 0.115, n), rng.uniform(-0.02, 0.02, n), rng.uniform(0, 1, n)]
    )
    r3 = np.tile([0.004, 0.002, 0.003, 0.02], (n, 1))
    c4 = np.column_stack([c3[:, :3], np.full(n, d0), c3[:, 3]])
    r4 = np.column_stack([r3[:, :3], np.zeros(n), r3[:, 3]])
    b3, b4 = box_clearance_bounds(model3, c3, r3), box_clearance_bounds(model4, c4, r4)
    np.testing.assert_allclose(b4.lower_m, b3.lower_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b4.center_m, b3.center_m, rtol=0, atol=1e-12)
    cells3, half3 = c3[:, :3], r3[:, :3] / 4
    cells4, half4 = c4[:, :4], r4[:, :4] / 4
    np.testing.assert_allclose(
        endpoint_error_bounds(model4, cells4, half4), endpoint_error_bounds(model3, cells3, half3), rtol=0, atol=1e-12
    )
    # Cells of the top band of W (where the end poses lose the margin), at a margin of 10.2 mm
    # that splits them.
    margin = 0.0102
    half = np.array([0.1 / 512, 0.04 / 512, 0.06 / 256])
    band = np.array(
        [[L, 0.12 - half[1] * (1 + 2 * j), x] for L in (0.21, 0.25, 0.29) for j in (0, 4) for x in (0, 0.02)]
    )
    band4 = np.column_stack([band, np.full(band.shape[0], d0)])
    radius4 = np.tile([*half, 0.0], (band.shape[0], 1))
    upper3 = endpoint_clearance_upper_bounds(model3, band, np.tile(half, (band.shape[0], 1)), TOLERANCE_M, margin)
    upper4 = endpoint_clearance_upper_bounds(model4, band4, radius4, TOLERANCE_M, margin)
    np.testing.assert_allclose(upper4, upper3, rtol=0, atol=1e-12)
    assert np.any(upper3 < margin) and np.any(upper3 >= margin)


def test_over_length_width_and_d_the_bounds_are_those_at_x_zero(eq9_xd: Coefficients, model_xd: RangeModel) -> None:
    """Coefficients over (L, W, d) (the (L, W, x, d) lift's terms without x: the same parameters
    at x = 0) have the clearance, endpoint and infeasibility bounds of the (L, W, x, d) lift on
    boxes at x = 0 with no x extent (the route without an x axis against the one with it)."""
    from pipeline.offline.variables import Variables

    lwd = Variables(("L", "W", "d"))
    keep = [eq9_xd.variables.basis.index(term) for term in lwd.basis]
    parameters = {name: tuple(np.asarray(b)[keep].tolist()) for name, b in eq9_xd.parameters.items()}
    ranges = {name: eq9_xd.fitted_range_m[name] for name in lwd.names}
    over_d = replace(eq9_xd, parameters=parameters, fitted_range_m=ranges, variables=lwd)
    model3, model4 = RangeModel.from_coefficients(over_d), model_xd
    assert model3.x_column is None and model3.d_column == 2
    rng = np.random.default_rng(41)
    n = 150
    c3 = np.column_stack(
        [rng.uniform(0.21, 0.29, n), rng.uniform(0.085, 0.115, n), rng.uniform(0.552, 0.568, n), rng.uniform(0, 1, n)]
    )
    r3 = np.tile([0.004, 0.002, 0.002, 0.02], (n, 1))
    c4 = np.column_stack([c3[:, :2], np.zeros(n), c3[:, 2:]])
    r4 = np.column_stack([r3[:, :2], np.zeros(n), r3[:, 2:]])
    b3, b4 = box_clearance_bounds(model3, c3, r3), box_clearance_bounds(model4, c4, r4)
    np.testing.assert_allclose(b3.lower_m, b4.lower_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        endpoint_error_bounds(model3, c3[:, :3], r3[:, :3] / 4),
        endpoint_error_bounds(model4, c4[:, :4], r4[:, :4] / 4),
        rtol=0,
        atol=1e-12,
    )
    center4, radius4 = _band_cells((0.552, 0.56), 0.02 / 256)
    first = np.flatnonzero(center4[:, 2] == -0.02)[::3]  # one x of the two, moved to x = 0 with no extent
    center4, radius4 = center4[first], radius4[first]
    center4[:, 2], radius4[:, 2] = 0.0, 0.0
    center3, radius3 = np.delete(center4, 2, axis=1), np.delete(radius4, 2, axis=1)
    upper3 = infeasibility_upper_bounds(model3, center3, radius3, TOLERANCE_M, MARGIN_M, levels=3)
    upper4 = infeasibility_upper_bounds(model4, center4, radius4, TOLERANCE_M, MARGIN_M, levels=3)
    np.testing.assert_allclose(upper3, upper4, rtol=0, atol=1e-12)
    assert np.any(np.isfinite(upper3)) and not np.all(np.isfinite(upper3))


def test_endpoint_error_bound_holds_at_the_end_poses(
    eq9_xd: Coefficients, model_xd: RangeModel, arm: PlanarArm, random_cells, points_in
) -> None:
    """At corners, centre and random points of random cells of (L, W, x, d), the distance from the
    tip (Pinocchio) at t = 0 and t = T to the moved P1 and P5 stays within the bound; on small
    cells the bound is tight."""
    center, radius = random_cells(model_xd, 20, np.random.default_rng(1), depths=(0, 2, 4, 6))
    bounds = endpoint_error_bounds(model_xd, center, radius)
    assert bounds.shape == (20, 2) and np.all(np.isfinite(bounds))
    rng = np.random.default_rng(2)
    for k in range(center.shape[0]):
        for L, W, x, d in points_in(center[k], radius[k], rng, 3):
            trajectory, obstacle = motion(eq9_xd, L, W, x, d)
            points = constraint_points(obstacle, moved_scene(eq9_xd, x, d))
            start = np.linalg.norm(arm.end_effector_position(trajectory.q(0.0))[:2] - points[0])
            end = np.linalg.norm(arm.end_effector_position(trajectory.q(trajectory.duration_s))[:2] - points[-1])
            assert start <= bounds[k, 0] + 1e-12
            assert end <= bounds[k, 1] + 1e-12
    for d in (0.551, 0.56, 0.568):
        bound = endpoint_error_bounds(model_xd, np.array([[0.23, 0.11, 0.01, d]]), np.full((1, 4), 1e-5))[0]
        trajectory, obstacle = motion(eq9_xd, 0.23, 0.11, 0.01, d)
        points = constraint_points(obstacle, moved_scene(eq9_xd, 0.01, d))
        tips = [arm.end_effector_position(trajectory.q(t))[:2] for t in (0.0, trajectory.duration_s)]
        errors = [np.linalg.norm(tips[0] - points[0]), np.linalg.norm(tips[1] - points[-1])]
        for error, b in zip(errors, bound, strict=True):
            assert error <= b < error + 1e-4


def _band_cells(d_centres, d_half: float) -> tuple[np.ndarray, np.ndarray]:
    """Cells of 1/256 of the (L, W) range in the top band of W (where the end poses lose the
    margin), at x in {-0.02, 0.02} with half width 0.06 / 512, at the given d centres with half
    width ``d_half``."""
    half = np.array([0.1, 0.04]) / 512
    L = 0.2 + half[0] * (2 * np.arange(0, 256, 51) + 1)
    W = 0.12 - half[1] * (1 + 2 * np.arange(0, 10, 3))
    center = np.array([[a, b, x, d] for a in L for b in W for x in (-0.02, 0.02) for d in d_centres])
    radius = np.tile([*half, 0.06 / 512, d_half], (center.shape[0], 1))
    return center, radius


@pytest.mark.parametrize("d_half", [0.02 / 512, 0.02 / 64])
def test_infeasibility_bound_holds_against_sampled_end_poses(
    eq9_xd: Coefficients, model_xd: RangeModel, arm: PlanarArm, d_half, points_in, end_pose_clearance
) -> None:
    """Where a cell's end is proven (bound below the margin), no sampled pose near that end's P
    clears more than the bound, at the corners, centre and random points of the cell, each
    against its own moved obstacle; where the sub-cell bound proves the cell, the smaller of the
    two ends' sampled values stays below it. Some cells are proven, some not."""
    center, radius = _band_cells((0.552, 0.56, 0.568), d_half)
    direct = endpoint_clearance_upper_bounds(model_xd, center, radius, TOLERANCE_M, MARGIN_M)
    refined = infeasibility_upper_bounds(model_xd, center, radius, TOLERANCE_M, MARGIN_M, levels=3)
    assert np.all(np.isinf(refined) | (refined < MARGIN_M))
    proven = np.isfinite(refined)
    assert 3 <= np.count_nonzero(proven) < center.shape[0]
    rng = np.random.default_rng(3)
    checked = 0
    for k in range(center.shape[0]):
        if not (proven[k] or np.any(direct[k] < MARGIN_M) or rng.uniform() < 0.1):
            continue  # the rest make no claim; a tenth of them is still sampled
        for L, W, x, d in points_in(center[k], radius[k], rng, 1):
            scene = moved_scene(eq9_xd, x, d)
            sampled = end_pose_clearance(eq9_xd, arm, Obstacle.in_scene(L, W, scene), scene, TOLERANCE_M)
            for column in (0, 1):
                if direct[k, column] < MARGIN_M:
                    assert sampled[column] <= direct[k, column] + 1e-12
            if proven[k]:
                assert sampled.min() <= refined[k] + 1e-12
            checked += 1
    assert checked > 40


def test_a_cell_without_a_common_obstacle_gets_no_bound(model_xd: RangeModel) -> None:
    """With W0 - 2 h_d <= 2 r the obstacles of the cell need not share a rounded rectangle: no bound."""
    center = np.array([[0.25, 0.081, 0.0, 0.56], [0.25, 0.081, 0.0, 0.56]])
    radius = np.array([[0.001, 0.001, 0.001, 0.0301], [0.001, 0.001, 0.001, 0.02]])  # W* = 0.0178, 0.038 m
    upper = endpoint_clearance_upper_bounds(model_xd, center, radius, TOLERANCE_M, MARGIN_M)
    assert np.all(np.isinf(upper[0])) and np.all(np.isfinite(upper[1]))


@pytest.fixture(scope="module")
def eq9_xd_map(eq9_xd: Coefficients):
    return certify_range(eq9_xd, RangeCertificateConfig(min_cell=1 / 8, boundary_cell=1 / 4, max_depth_s=12))


def test_map_over_x_and_d_names_its_axes_and_tiles_the_box(eq9_xd_map) -> None:
    from pipeline.certify.region_map import RegionMap

    assert eq9_xd_map.axes == ("L", "W", "x", "d")
    assert eq9_xd_map.ranges_m[2:] == ((-0.03, 0.03), D_RANGE)
    assert sum(eq9_xd_map.summary()["area_fraction"].values()) == pytest.approx(1.0, abs=1e-12)
    assert np.sum(eq9_xd_map.leaf_sizes_m().prod(axis=1)) == pytest.approx(0.1 * 0.04 * 0.06 * 0.02, rel=1e-9)
    again = RegionMap.from_json(eq9_xd_map.to_json())
    assert again.to_json() == eq9_xd_map.to_json()


def test_map_over_x_and_d_is_below_every_sampled_motion(eq9_xd: Coefficients, eq9_xd_map, arm: PlanarArm) -> None:
    """Dense in t at random (L, W, x, d), and at a random point of some of the leaves proven
    collision-free: each motion's minimum lies above its leaf's bound, a motion that dips below
    the margin is never in a "margin" leaf, and the end poses are within the leaf's endpoint bound."""
    rng = np.random.default_rng(51)
    ranges = np.array(eq9_xd_map.ranges_m)
    lo, size = ranges[:, 0], ranges[:, 1] - ranges[:, 0]
    proven = np.flatnonzero(eq9_xd_map.clearance_bound_m > 0.0)
    assert proven.size > 0
    leaves = rng.choice(proven, min(10, proven.size), replace=False)
    centres, sides = eq9_xd_map.leaf_centres_m()[leaves], eq9_xd_map.leaf_sizes_m()[leaves]
    inside = centres + rng.uniform(-0.5, 0.5, (leaves.size, 4)) * sides
    points = np.vstack([lo + rng.uniform(0.0, 1.0, (20, 4)) * size, inside])
    for L, W, x, d in points:
        trajectory, obstacle = motion(eq9_xd, L, W, x, d)
        q = trajectory.q(np.linspace(0.0, trajectory.duration_s, 1001))
        lowest = analytic_link_clearance(q, arm, obstacle).min()
        cell = eq9_xd_map.cell_at(L, W, x, d)
        assert cell.ranges_m[3][0] <= d <= cell.ranges_m[3][1]
        assert lowest >= cell.clearance_bound_m - 1e-12
        if lowest < eq9_xd_map.margin_m:
            assert cell.status != "margin"
        points = constraint_points(obstacle, moved_scene(eq9_xd, x, d))
        tips = [arm.end_effector_position(trajectory.q(t))[:2] for t in (0.0, trajectory.duration_s)]
        error = max(np.linalg.norm(tips[0] - points[0]), np.linalg.norm(tips[1] - points[-1]))
        assert error <= cell.endpoint_bound_m + 1e-12


def test_execution_bounds_over_x_and_d_hold_along_sampled_motions(eq9_xd: Coefficients, eq9_xd_map, arm) -> None:
    """Each leaf's joint-speed bound (paper timing) is above the speeds sampled at obstacles in it."""
    from pipeline.certify.map_for_coefficients import with_execution_bounds
    from pipeline.model.dynamics import identify_dynamics
    from pipeline.model.limits import ArmLimits

    mapped = with_execution_bounds(eq9_xd_map, eq9_xd, identify_dynamics(arm), ArmLimits.from_arm(arm, (5.0, 5.0)))
    assert mapped.execution is not None and mapped.execution.size == eq9_xd_map.size
    rng = np.random.default_rng(61)
    lo, hi = np.array([0.2, 0.08, -0.03, D_RANGE[0]]), np.array([0.3, 0.12, 0.03, D_RANGE[1]])
    for L, W, x, d in lo + rng.uniform(0.0, 1.0, (15, 4)) * (hi - lo):
        trajectory, _ = motion(eq9_xd, L, W, x, d)
        speed = np.abs(trajectory.dq(np.linspace(0.0, trajectory.duration_s, 801))).max(axis=0)
        bound = mapped.execution.paper_speed_rad_s[mapped.leaf_at(L, W, x, d)]
        assert np.all(speed <= bound + 1e-12)
