"""The range certificate (pipeline.certify) against independent references: the online
generator (its own T by the path module's quadrature), the analytic clearance route shown
equal to Coal through Pinocchio here, Pinocchio's forward kinematics for the endpoints, and a
direct sampling of the poses near P1 and P5 for the infeasibility certificate."""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline import load_coefficients
from pipeline.certify.certifiable_regression import clearance_at, clearance_grid
from pipeline.certify.certificate_settings import CertificateSettings
from pipeline.certify.clearance_bound import box_clearance_bounds
from pipeline.certify.endpoints import (
    endpoint_clearance_upper_bounds,
    endpoint_error_bounds,
    infeasibility_upper_bounds,
)
from pipeline.certify.map_files import load_region_map
from pipeline.certify.range_certificate import (
    PROGRESS_STAGES,
    RangeCertificateConfig,
    _run_tasks,
    _witnessed,
    certify_range,
    refine_leaves,
    sub_cell_bounds,
)
from pipeline.certify.range_model import RangeModel
from pipeline.certify.region_map import DEFAULT_MAP_NAME, STATUSES, region_map_text
from pipeline.certify.search import SearchSettings, cell_boxes, node_boxes, search
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance, analytic_link_clearance
from pipeline.io.executor import LocalPool
from pipeline.model.arm import PlanarArm
from pipeline.model.kinematics import inverse_kinematics
from pipeline.model.obstacle import Obstacle
from pipeline.motion.families import family_from_name
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import Coefficients, fit_coefficients, paper_data_path, save_coefficients
from pipeline.offline.doe import load_doe
from pipeline.offline.endpoint_regression import EndpointConstraint
from pipeline.online.generator import generate

#: Coarse cells keep the module fast; soundness does not depend on the cell size.
FAST = RangeCertificateConfig(min_cell=1 / 32, boundary_cell=1 / 16)


@pytest.fixture(scope="module")
def eq9() -> Coefficients:
    return load_coefficients("paper")


@pytest.fixture(scope="module")
def eq9_map(eq9: Coefficients):
    return certify_range(eq9, FAST)


def damaged(coefficients: Coefficients, shift_rad: float) -> Coefficients:
    """The coefficients with gamma2 shifted by ``shift_rad`` everywhere (link 2 swung into the box)."""
    parameters = dict(coefficients.parameters)
    gamma2 = list(parameters["gamma2"])
    gamma2[0] += shift_rad
    parameters["gamma2"] = tuple(gamma2)
    return dataclasses.replace(coefficients, parameters=parameters, source_sha256="damaged")


def exact_endpoints_from(coefficients: Coefficients) -> Coefficients:
    """An exact-endpoints coefficient set: the paper family's regressions of w1, phi1, A2, w2."""
    family = family_from_name("exact-endpoints")
    parameters = {name: coefficients.parameters[name] for name in family.free_parameter_names}
    return dataclasses.replace(coefficients, family=family, parameters=parameters, source_sha256="exact")


def random_points(coefficients: Coefficients, n: int, seed: int) -> np.ndarray:
    """n random (L, W, s) in the fitted range x [0, 1]."""
    rng = np.random.default_rng(seed)
    (l_lo, l_hi), (w_lo, w_hi) = coefficients.fitted_range_m["L"], coefficients.fitted_range_m["W"]
    return np.column_stack([rng.uniform(l_lo, l_hi, n), rng.uniform(w_lo, w_hi, n), rng.uniform(0.0, 1.0, n)])


def true_clearance(coefficients: Coefficients, arm: PlanarArm, points: np.ndarray, coal: bool = False) -> np.ndarray:
    """Clearance of both links at (L, W, s) from the online generator: analytic route, or Coal."""
    out = np.empty(points.shape[0])
    for k, (L, W, s) in enumerate(points):
        answer = generate(coefficients, L, W, out_of_range="ignore")
        q = answer.q(s * answer.duration_s)
        if coal:
            out[k] = CoalClearance(arm, answer.obstacle).link_clearance(q).min()
        else:
            out[k] = analytic_link_clearance(q, arm, answer.obstacle).min()
    return out


def _settings(margin_m: float, tolerance_m: float, max_depth: int, **more) -> CertificateSettings:
    return CertificateSettings(margin_m=margin_m, endpoint_tolerance_m=tolerance_m, max_depth=max_depth, **more)


def test_analytic_route_equals_coal_along_certified_motions(eq9: Coefficients, arm: PlanarArm) -> None:
    """The bulk checks below use the analytic route; here it equals Coal through Pinocchio."""
    points = random_points(eq9, 300, seed=1)
    analytic = true_clearance(eq9, arm, points)
    coal = true_clearance(eq9, arm, points, coal=True)
    assert np.max(np.abs(analytic - coal)) < 2e-6
    assert np.min(analytic) > 0.0  # these motions are all clear: the comparison is of distances


def test_map_bound_is_sound_at_ten_thousand_points(eq9: Coefficients, eq9_map, arm: PlanarArm) -> None:
    points = random_points(eq9, 10_000, seed=2)
    values = true_clearance(eq9, arm, points)
    bounds = eq9_map.cells_at(points[:, 0], points[:, 1])["clearance_bound_m"]
    assert np.all(np.isfinite(bounds))
    assert np.all(values >= bounds - 1e-12)
    assert np.all(bounds > 0.0)  # Eq. 9 is certified collision-free everywhere


def test_map_bound_is_sound_against_coal(eq9: Coefficients, eq9_map, arm: PlanarArm) -> None:
    points = random_points(eq9, 400, seed=3)
    values = true_clearance(eq9, arm, points, coal=True)
    bounds = eq9_map.cells_at(points[:, 0], points[:, 1])["clearance_bound_m"]
    assert np.all(values >= bounds - COAL_DISTANCE_ERROR_M)


def test_map_minimum_is_below_every_sampled_motion(eq9: Coefficients, eq9_map, arm: PlanarArm) -> None:
    """Dense in t at a few obstacles: each motion's minimum lies above its cell's bound, and the
    cells whose motion dips below the margin are not marked "margin"."""
    rng = np.random.default_rng(4)
    certified = []
    for L, W in zip(rng.uniform(0.2, 0.3, 25), rng.uniform(0.08, 0.12, 25), strict=True):
        answer = generate(eq9, L, W)
        lowest = analytic_link_clearance(answer.q(np.linspace(0.0, answer.duration_s, 2001)), arm, answer.obstacle)
        cell = eq9_map.cell_at(L, W)
        assert lowest.min() >= cell.clearance_bound_m - 1e-12
        if lowest.min() < eq9_map.margin_m:
            assert cell.status != "margin"
        if lowest.min() > eq9_map.margin_m + 0.003:
            certified.append(cell.status == "margin")
    # Not vacuous: the search stops at the margin, yet motions clearly above it are certified so.
    assert np.mean(certified) > 0.8


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), exact=st.booleans())
def test_box_bounds_hold_at_points_of_random_boxes(eq9: Coefficients, arm: PlanarArm, seed: int, exact: bool) -> None:
    """Any box, any family: every sampled point of a box clears at least the box's bound."""
    coefficients = exact_endpoints_from(eq9) if exact else eq9
    model = RangeModel.from_coefficients(coefficients)
    rng = np.random.default_rng(seed)
    radius = np.column_stack([rng.uniform(1e-5, 5e-3, 6), rng.uniform(1e-5, 2e-3, 6), rng.uniform(1e-5, 0.05, 6)])
    lo = np.array([0.2, 0.08, 0.0]) + radius
    hi = np.array([0.3, 0.12, 1.0]) - radius
    center = lo + (hi - lo) * rng.uniform(size=(6, 3))
    bounds = box_clearance_bounds(model, center, radius).lower_m
    for k in range(6):
        points = center[k] + radius[k] * rng.uniform(-1.0, 1.0, (8, 3))
        points = np.vstack([points, center[k] + radius[k] * np.array([[1, 1, 1], [-1, -1, -1], [1, -1, 1]])])
        assert np.all(true_clearance(coefficients, arm, points) >= bounds[k] - 1e-12)


def test_exact_endpoints_parameter_jets_contain_the_family_expansion(eq9: Coefficients) -> None:
    coefficients = exact_endpoints_from(eq9)
    model = RangeModel.from_coefficients(coefficients)
    radius = np.array([[2e-3, 1e-3, 0.0]] * 30)
    points = random_points(coefficients, 30, seed=5)
    points[:, :2] = np.clip(points[:, :2], [0.2 + 2e-3, 0.08 + 1e-3], [0.3 - 2e-3, 0.12 - 1e-3])
    jets = model.parameter_jets(model.variables(points, radius), model.duration.jet(points, radius))
    rng = np.random.default_rng(6)
    for k in range(30):
        for u, v in points[k, :2] + radius[k, :2] * rng.uniform(-1, 1, (5, 2)):
            expected = generate(coefficients, u, v).trajectory.parameters
            for p, jet in zip(expected, jets, strict=True):
                assert jet.value.lo[k] - 1e-9 <= p <= jet.value.hi[k] + 1e-9


def test_exact_endpoints_are_certified_pinned_where_a1_is_not_clamped(eq9: Coefficients, arm: PlanarArm) -> None:
    coefficients = exact_endpoints_from(eq9)
    model = RangeModel.from_coefficients(coefficients)
    centers = random_points(coefficients, 40, seed=9)[:, :2]
    radius = np.full((40, 2), 1e-3)
    centers = np.clip(centers, [0.2 + 1e-3, 0.08 + 1e-3], [0.3 - 1e-3, 0.12 - 1e-3])
    bounds = endpoint_error_bounds(model, centers, radius)
    pinned = model.endpoints_pinned(centers, radius)
    assert np.mean(pinned) > 0.5
    for (L, W), bound in zip(centers[pinned], bounds[pinned], strict=True):
        answer = generate(coefficients, L, W)
        start = np.linalg.norm(arm.end_effector_position(answer.q(0.0))[:2] - answer.path.points_m[0])
        end = np.linalg.norm(arm.end_effector_position(answer.q(answer.duration_s))[:2] - answer.path.points_m[-1])
        assert max(start, end) <= bound.max() <= 1e-8


def test_bound_gap_shrinks_quadratically(eq9: Coefficients, arm: PlanarArm) -> None:
    """Near the obstacle (link 2 passing a corner at the end of the motion): halving the box divides
    the gap between the sampled minimum over the box and the bound by about 4."""
    model = RangeModel.from_coefficients(eq9)
    center = np.array([0.21, 0.118, 0.9])
    gaps = []
    for h in (2e-3, 1e-3, 5e-4, 2.5e-4):
        radius = np.array([h, 0.4 * h, 2 * h])
        grid = [np.linspace(c - r, c + r, 7) for c, r in zip(center, radius, strict=True)]
        points = np.array(np.meshgrid(*grid, indexing="ij")).reshape(3, -1).T
        lowest = true_clearance(eq9, arm, points).min()
        bound = box_clearance_bounds(model, center[None], radius[None]).lower_m[0]
        assert bound <= lowest
        gaps.append(lowest - bound)
    ratios = np.array(gaps[:-1]) / np.array(gaps[1:])
    assert np.all(ratios > 3.0), ratios


def test_damaged_coefficients_are_not_certified_where_they_collide(eq9: Coefficients, arm: PlanarArm) -> None:
    broken = damaged(eq9, -0.05)
    region_map = certify_range(broken, FAST)
    points = random_points(broken, 3000, seed=7)
    values = true_clearance(broken, arm, points)
    cells = region_map.cells_at(points[:, 0], points[:, 1])
    hits = values <= 0.0
    assert 0.01 < np.mean(hits) < 0.95  # the damage collides in part of the range only
    assert np.all(cells["clearance_bound_m"][hits] <= 0.0)
    assert np.all(cells["status"][hits] == STATUSES.index("undecided"))
    assert np.all(values >= cells["clearance_bound_m"] - 1e-12)
    assert region_map.summary()["certified_collision_free_fraction"] > 0.3


def test_paper_eq9_gets_an_honest_map(eq9_map) -> None:
    """Collision-free everywhere (as the sweep finds), the margin missed near W = 0.12 m, and the
    endpoint errors of Eq. 9 (up to 7.8 mm on a grid) not hidden."""
    summary = eq9_map.summary()
    assert summary["certified_collision_free_fraction"] == 1.0
    assert 0.5 < summary["area_fraction"]["margin"] < 0.95
    near = eq9_map.cells_at(np.linspace(0.2, 0.3, 50), np.full(50, 0.1195))
    assert np.all(near["status"] != STATUSES.index("margin"))
    assert summary["endpoint_bound_max_m"] > 0.0078
    assert summary["endpoint_within_tolerance_fraction"] == 0.0


def test_cells_that_miss_the_tolerance_all_over_are_refined_only_to_the_resolution(eq9: Coefficients) -> None:
    """Eq. 9 misses the 2 mm tolerance everywhere. Its leaves (here a 4 x 4 grid whose clearance
    is taken as certified, so that only the endpoint rule cuts) stop being cut where the error at
    the centre, less the bound's gap above it, exceeds the tolerance and that gap is within
    0.5 mm; before, every leaf went down to the smallest cell. With a 10 mm tolerance, which Eq. 9
    meets at some centres, the leaves that can still come within it are cut to the bottom."""
    model = RangeModel.from_coefficients(eq9)
    i, j = np.meshgrid(np.arange(4), np.arange(4), indexing="ij")
    grid = [np.full((16, 2), 2), np.column_stack([i.ravel(), j.ravel()]), np.full(16, np.inf)]
    max_depth = 8
    for tolerance_m in (0.002, 0.008):
        (levels, index, _), endpoint, _ = refine_leaves(model, grid, _settings(0.01, tolerance_m, max_depth))
        assert math.isclose(float(np.sum(2.0 ** -levels.sum(axis=1).astype(float))), 1.0)
        depth = np.min(levels, axis=1)  # a leaf is cut along its widest axis until every axis is at max_depth
        center, radius = cell_boxes(model, levels, index)
        assert np.array_equal(endpoint, np.max(endpoint_error_bounds(model, center, radius), axis=1))
        at_centre = np.max(endpoint_error_bounds(model, center, np.zeros_like(radius)), axis=1)
        missed = (2 * at_centre - endpoint > tolerance_m) & (endpoint - at_centre <= 5e-4)
        assert np.all((endpoint <= tolerance_m) | missed | (depth == max_depth))
        if tolerance_m == 0.002:
            assert np.all(missed) and np.all(depth < max_depth) and depth.size < 4**max_depth / 10
        else:
            assert np.any(endpoint <= tolerance_m) and np.any(~missed & (depth == max_depth))


def test_endpoint_bound_holds_against_pinocchio(eq9: Coefficients, eq9_map, arm: PlanarArm) -> None:
    rng = np.random.default_rng(8)
    for L, W in zip(rng.uniform(0.2, 0.3, 300), rng.uniform(0.08, 0.12, 300), strict=True):
        answer = generate(eq9, L, W)
        start = np.linalg.norm(arm.end_effector_position(answer.q(0.0))[:2] - answer.path.points_m[0])
        end = np.linalg.norm(arm.end_effector_position(answer.q(answer.duration_s))[:2] - answer.path.points_m[-1])
        assert max(start, end) <= eq9_map.cell_at(L, W).endpoint_bound_m


def test_endpoint_bound_is_tight_on_small_cells(eq9: Coefficients, arm: PlanarArm) -> None:
    model = RangeModel.from_coefficients(eq9)
    center = np.array([[0.23, 0.11]])
    bound = endpoint_error_bounds(model, center, np.array([[1e-4, 1e-4]]))[0]
    answer = generate(eq9, 0.23, 0.11)
    end = np.linalg.norm(arm.end_effector_position(answer.q(answer.duration_s))[:2] - answer.path.points_m[-1])
    assert end <= bound[1] < end + 2e-4


def test_endpoint_regression_is_proven_within_tolerance_over_the_whole_range(arm: PlanarArm) -> None:
    """The endpoint-constrained fit of Table 2 (the build's regression, default settings) keeps
    the tolerance over every cell of the range, not only at its grid points: the endpoint
    refinement of the certificate proves <= 2 mm everywhere with cells of 1/256 of the side at
    the finest; Pinocchio's endpoints at random (L, W) lie within their leaf's bound."""
    fitted, _ = fit_coefficients(load_doe(paper_data_path("paper_table2_doe.json")), None, EndpointConstraint())
    model = RangeModel.from_coefficients(fitted)
    n = 8
    i, j = (k.ravel() for k in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    leaves = [np.full((n * n, 2), 3), np.column_stack([i, j]), np.full(n * n, np.inf)]  # clearance not asked: +inf
    (levels, index, _), endpoint, _ = refine_leaves(model, leaves, _settings(0.01, 0.002, max_depth=8))
    i_l, i_w = index.T
    assert np.all(endpoint <= 0.002)
    assert math.isclose(float(np.sum(2.0 ** -levels.sum(axis=1).astype(float))), 1.0)
    rng = np.random.default_rng(11)
    lo, size = model.range_lo, model.range_size
    for L, W in zip(rng.uniform(0.2, 0.3, 100), rng.uniform(0.08, 0.12, 100), strict=True):
        answer = generate(fitted, L, W)
        ends = [arm.end_effector_position(answer.q(t))[:2] for t in (0.0, answer.duration_s)]
        error = max(
            np.linalg.norm(ends[0] - answer.path.points_m[0]), np.linalg.norm(ends[1] - answer.path.points_m[-1])
        )
        u, v = (np.array([L, W]) - lo) / size
        leaf = np.flatnonzero(
            (i_l <= u * 2.0 ** levels[:, 0])
            & (u * 2.0 ** levels[:, 0] <= i_l + 1)
            & (i_w <= v * 2.0 ** levels[:, 1])
            & (v * 2.0 ** levels[:, 1] <= i_w + 1)
        )
        assert error <= endpoint[leaf].min() <= 0.002


def _best_clearance_near(point: np.ndarray, tolerance_m: float, obstacle: Obstacle, arm: PlanarArm) -> float:
    """Largest Coal clearance over IK poses (elbow +1) whose tip is within the tolerance of ``point``."""
    best = -np.inf
    coal = CoalClearance(arm, obstacle)
    for radius in np.linspace(0.0, tolerance_m, 6):
        for angle in np.linspace(0.0, 2 * np.pi, 48, endpoint=False):
            q = inverse_kinematics(point + radius * np.array([np.cos(angle), np.sin(angle)]), arm.link_lengths_m, 1)
            best = max(best, float(coal.link_clearance(q).min()))
    return best


def test_infeasibility_certificate_near_w_012(eq9: Coefficients, arm: PlanarArm) -> None:
    """At (0.20, 0.12) m the pose at P5 leaves about 8 mm: with a 2 mm tolerance no pose within it
    reaches the 1 cm margin (certified, and every sampled pose agrees), with 3 mm one does."""
    model = RangeModel.from_coefficients(eq9)
    center, radius = np.array([[0.2 + 5e-5, 0.12 - 5e-5]]), np.array([[5e-5, 5e-5]])
    upper2 = endpoint_clearance_upper_bounds(model, center, radius, 0.002, 0.01)[0]
    upper3 = endpoint_clearance_upper_bounds(model, center, radius, 0.003, 0.01)[0]
    assert upper2[1] < 0.01 <= upper3[1]
    assert upper2[0] > 0.05  # at P1 the arm is far from the box
    obstacle = Obstacle.in_scene(0.2, 0.12, eq9.scene)
    p5 = np.array([-(0.1 + eq9.scene.start_dx_m), eq9.scene.y1_m])
    sampled = _best_clearance_near(p5, 0.002, obstacle, arm)
    assert sampled <= upper2[1]
    assert _best_clearance_near(p5, 0.003, obstacle, arm) >= 0.01


def test_infeasible_cells_of_a_fine_map_hold_no_feasible_pose(eq9: Coefficients, arm: PlanarArm) -> None:
    """A fine map over the top strip: each infeasible cell's poses near P5 all miss the margin."""
    strip = dataclasses.replace(eq9, fitted_range_m={"L": (0.2, 0.21), "W": (0.118, 0.12)})
    region_map = certify_range(strip, RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8))
    infeasible = np.flatnonzero(region_map.status == STATUSES.index("infeasible"))
    assert infeasible.size > 0
    for leaf in infeasible[:: max(1, infeasible.size // 6)]:
        cell = region_map.cell(int(leaf))
        L, W = np.mean(cell.range_of("L")), np.mean(cell.range_of("W"))
        obstacle = Obstacle.in_scene(L, W, eq9.scene)
        p5 = np.array([-(L / 2 + eq9.scene.start_dx_m), eq9.scene.y1_m])
        assert _best_clearance_near(p5, region_map.endpoint_tolerance_m, obstacle, arm) < region_map.margin_m


def test_sub_cells_prove_more_cells_infeasible_and_stay_sound(eq9: Coefficients, arm: PlanarArm) -> None:
    """Cells of 1/256 of the default range, the fifth row below W = 0.12 m: the sub-cell bound proves cells the
    cell's own bound cannot, and at the corners and centre of every cell it proves, no sampled
    pose near P5 reaches its bound."""
    model = RangeModel.from_coefficients(eq9)
    half = np.array([0.1, 0.04]) / 512
    L = 0.2 + half[0] * (2 * np.arange(0, 180, 6) + 1)
    center = np.column_stack([L, np.full(L.size, 0.12 - 9 * half[1])])
    radius = np.tile(half, (L.size, 1))
    direct = endpoint_clearance_upper_bounds(model, center, radius, 0.002, 0.01).min(axis=1)
    refined = infeasibility_upper_bounds(model, center, radius, 0.002, 0.01)
    assert np.all(np.isinf(refined) | (refined < 0.01))
    gained = np.flatnonzero(np.isfinite(refined) & (direct >= 0.01))
    assert gained.size >= 3
    for k in gained[:: max(1, gained.size // 4)]:
        for du, dv in [(0, 0), (-1, -1), (-1, 1), (1, -1), (1, 1)]:
            L_k, W_k = center[k] + np.array([du, dv]) * half
            p5 = np.array([-(L_k / 2 + eq9.scene.start_dx_m), eq9.scene.y1_m])
            sampled = _best_clearance_near(p5, 0.002, Obstacle.in_scene(L_k, W_k, eq9.scene), arm)
            assert sampled <= refined[k] + COAL_DISTANCE_ERROR_M


def test_config_takes_keywords_only() -> None:
    """RangeCertificateConfig(1 / 16, 1 / 8) once set a 62.5 mm margin silently; now it is refused."""
    with pytest.raises(TypeError):
        RangeCertificateConfig(1 / 16, 1 / 8)  # type: ignore[misc]
    assert RangeCertificateConfig(min_cell=1 / 16).min_cell == 1 / 16


def test_infeasibility_bound_holds_at_the_cells_roomiest_corner_and_reaches_the_boundary(
    eq9: Coefficients, arm: PlanarArm
) -> None:
    """The end-pose bound is taken against the obstacle of the cell's smallest corner (L0, W0),
    which every obstacle of the cell contains. Columns of cells of 1/256 of the default range
    across the strip where the end poses lose the margin: wherever a cell is proven infeasible,
    no sampled pose near P5(L0) clears more than the bound against O(L0, W0), the cell's
    roomiest obstacle; and the proof reaches cells whose corner keeps 9.97 mm or more, where a
    bound taken against the centre's obstacle (0.05 mm less room at this size) would lie below
    that sampling."""
    model = RangeModel.from_coefficients(eq9)
    half = np.array([0.1, 0.04]) / 512
    L = 0.2 + half[0] * (2 * np.array([5, 35, 70]) + 1)
    W = 0.12 - half[1] * (1 + 0.5 * np.arange(24))  # cells a quarter of their height apart
    center = np.array([[length, width] for length in L for width in W])
    radius = np.tile(half, (center.shape[0], 1))
    upper = infeasibility_upper_bounds(model, center, radius, 0.002, 0.01)
    proven = np.flatnonzero(np.isfinite(upper))
    assert np.all(upper[proven] < 0.01)
    assert 6 <= proven.size < center.shape[0]
    corner_room = []
    for k in proven:
        L0, W0 = center[k] - half
        p5 = np.array([-(L0 / 2 + eq9.scene.start_dx_m), eq9.scene.y1_m])
        sampled = _best_clearance_near(p5, 0.002, Obstacle.in_scene(L0, W0, eq9.scene), arm)
        assert sampled <= upper[k] + COAL_DISTANCE_ERROR_M
        corner_room.append(sampled)
    assert max(corner_room) > 0.00997


def test_the_search_resolves_the_margins_contour_at_its_smallest_cell(eq9: Coefficients) -> None:
    """Eq. 9 on a sub-range its 1 cm contour crosses, with a coarse resolution (5 mm: every node
    whose centre misses the margin counts as resolved at the boundary depth): a node left below
    the margin coarser than the smallest cell holds no obstacle that keeps the margin (5 x 5
    (L, W) per node, the clearance's minimum over 401 times; the analytic clearance of
    ``clearance_at``, tested equal to the generator's), so the contour is resolved at the
    smallest cell. When nodes were closed at the boundary depth wherever their centre missed
    the margin, coarse nodes straddled the contour and this failed."""
    strip = dataclasses.replace(eq9, fitted_range_m={"L": (0.2, 0.225), "W": (0.108, 0.116)})
    model = RangeModel.from_coefficients(strip)
    settings = SearchSettings(margin_m=0.01, max_depth_lw=5, boundary_depth_lw=2, resolution_m=5e-3)
    found = search(model, settings, keep_nodes=True)
    levels, index, node_bound = found.nodes
    smallest = np.all(levels == settings.max_depth_lw, axis=1)
    coarse = np.flatnonzero((node_bound < settings.margin_m) & ~smallest)
    assert coarse.size >= 3 and np.any(found.bound_m >= settings.margin_m)
    centre, half = cell_boxes(model, levels[coarse], index[coarse])
    offsets = np.array([[u, v] for u in np.linspace(-1, 1, 5) for v in np.linspace(-1, 1, 5)])
    sizes = (centre[:, None, :] + offsets[None] * half[:, None, :]).reshape(-1, 2)
    s = np.linspace(0.0, 1.0, 401)
    data = clearance_grid(strip, sizes, s)
    b = np.stack([strip.parameters[name] for name in PARAMETER_NAMES], -1).ravel()
    per_obstacle = clearance_at(b, data, strip).reshape(len(sizes), s.size).min(axis=1)
    assert np.all(per_obstacle < settings.margin_m)


def test_pinned_endpoint_bound_is_sound_where_the_pose_meets_the_margin(eq9: Coefficients, arm: PlanarArm) -> None:
    """Tolerance 0 (the exact-endpoints family): the pose with its tip exactly at P5(L) over cells
    of 1/1024 straddling the W where that pose's clearance crosses the 1 cm margin. Every proven
    bound (below the margin) lies above the pose's clearance at 25 obstacles of its cell (Coal),
    with the polar sub-boxes stopped at 1 um (they went to 1e-10 m), and the proof still reaches
    cells next to the margin's crossing."""
    model = RangeModel.from_coefficients(eq9)
    scene = eq9.scene

    def pose_clearance(length_m: float, width_m: float) -> float:
        p5 = np.array([-(length_m / 2 + scene.start_dx_m), scene.y1_m])
        q = inverse_kinematics(p5, arm.link_lengths_m, eq9.elbow)
        return float(CoalClearance(arm, Obstacle.in_scene(length_m, width_m, scene)).link_clearance(q).min())

    length = 0.25
    lo, hi = 0.10, 0.12  # the clearance at P5 falls with W through the margin in between
    assert pose_clearance(length, lo) > 0.01 > pose_clearance(length, hi)
    for _ in range(50):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if pose_clearance(length, mid) > 0.01 else (lo, mid)
    crossing = lo
    half = np.array([0.1, 0.04]) / 2048
    offsets = np.arange(-6, 7)
    center = np.column_stack([np.full(offsets.size, length), crossing + 2 * half[1] * offsets])
    radius = np.tile(half, (offsets.size, 1))
    upper = endpoint_clearance_upper_bounds(model, center, radius, 0.0, 0.01)[:, 1]
    proven = upper < 0.01
    assert np.any(proven) and not np.all(proven)
    grid = np.linspace(-1.0, 1.0, 5)
    for k in np.flatnonzero(proven):
        worst = max(pose_clearance(*(center[k] + radius[k] * [u, v])) for u in grid for v in grid)
        assert worst <= upper[k] + COAL_DISTANCE_ERROR_M
    # The proof reaches close to the crossing: the first proven cell's roomiest corner misses the
    # margin by less than 0.1 mm (the bound's own first-order term in L is about 40 um here).
    first = np.flatnonzero(proven)[0]
    assert pose_clearance(*(center[first] - radius[first])) > 0.01 - 1e-4


# --------------------------------------------------------------------------------------------
# Progress: what certify_range reports while it works, and that it changes nothing.

#: The paper's Eq. 9 at 1/16 (900 leaves, about 3 s): every stage but the sub-cells has work.
COARSE = RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8)


def _check_progress(calls: list[tuple[str, int, int]]) -> dict[str, int]:
    """Each stage reported in the order of PROGRESS_STAGES, once, from 0 up to its total, never
    going back; returns the total of each stage."""
    stages = [stage for stage, _, _ in calls]
    runs = [stage for k, stage in enumerate(stages) if k == 0 or stages[k - 1] != stage]
    assert runs == sorted(set(runs), key=PROGRESS_STAGES.index)
    totals = {}
    for stage in runs:
        mine = [(done, total) for name, done, total in calls if name == stage]
        assert mine[0][0] == 0 and mine[-1][0] == mine[-1][1] > 0
        assert all(0 <= done <= total for done, total in mine)
        assert all(b[0] >= a[0] and b[1] >= a[1] for a, b in itertools.pairwise(mine))
        totals[stage] = mine[-1][1]
    return totals


def test_progress_reports_every_stage_and_changes_no_byte(eq9: Coefficients) -> None:
    """With a callback, and with two worker processes whose tasks are collected as they finish,
    the map is byte for byte the one made without either."""
    plain = region_map_text(certify_range(eq9, COARSE))
    serial: list[tuple[str, int, int]] = []
    pooled: list[tuple[str, int, int]] = []
    assert region_map_text(certify_range(eq9, COARSE, progress=lambda *call: serial.append(call))) == plain
    pooled_map = certify_range(eq9, dataclasses.replace(COARSE, jobs=2), progress=lambda *call: pooled.append(call))
    assert region_map_text(pooled_map) == plain
    totals = _check_progress(serial)
    assert _check_progress(pooled) == totals
    assert list(totals) == ["range map: search", "range map: refine", "range map: strips"]
    assert [call for call in pooled if call[0] == "range map: search"] == [
        ("range map: search", k, 4) for k in range(5)
    ]
    # The refine stage counts leaves bounded; its total grows by the children of each round's cuts.
    strips = np.count_nonzero(np.diff(pooled_map.subpaving.levels, axis=1))
    assert totals["range map: refine"] >= 256 and totals["range map: strips"] == strips


def test_chunked_bounds_in_a_pool_are_the_serial_ones_and_count_leaves(eq9: Coefficients) -> None:
    """Three chunks of sub-cell bounds on two processes: the same bounds, in order, and the leaves
    of each chunk reported as it finishes."""
    model = RangeModel.from_coefficients(eq9)
    index = np.arange(300)
    c, r = node_boxes(model, np.full(300, 5), np.column_stack([index // 32, index % 32]))
    calls: list[tuple[str, int, int]] = []
    pooled_settings = _settings(0.01, 0.002, 5, run_on=LocalPool(2))
    pooled = sub_cell_bounds(model, c, r, pooled_settings, progress=lambda *call: calls.append(call))
    np.testing.assert_array_equal(pooled, sub_cell_bounds(model, c, r, _settings(0.01, 0.002, 5)))
    assert _check_progress(calls) == {"range map: sub-cells": 300}
    tried = 300 - int(np.count_nonzero(_witnessed(model, c, r, pooled_settings)))  # the others done at once
    steps = sorted(b[1] - a[1] for a, b in itertools.pairwise(calls))
    assert steps == sorted([300 - tried, *(min(128, tried - k) for k in range(0, tried, 128))])
    assert calls[1][1] == 300 - tried


def test_tasks_are_collected_in_order_and_an_error_stops_them() -> None:
    finished: list[int] = []
    assert _run_tasks(pow, [(k, 2) for k in range(12)], 2, finished.append) == [k**2 for k in range(12)]
    assert sorted(finished) == list(range(12))
    with pytest.raises(ValueError, match="math domain error"):
        _run_tasks(math.sqrt, [(4.0,), (-1.0,), (9.0,)], 2)


def test_the_command_line_replaces_a_broken_map_and_draws_no_bar_off_a_terminal(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, eq9: Coefficients
) -> None:
    """``python -m pipeline.certify_range`` does not read the map it replaces (a broken one beside
    the coefficients neither stops nor warns); its progress bars go to stderr only on a terminal,
    and ``--no-progress`` is accepted."""
    from pipeline.commands.certify_range import main

    source = tmp_path / "coefficients.json"
    save_coefficients(eq9, source)
    (tmp_path / DEFAULT_MAP_NAME).write_text("{not json")
    options = ["--min-cell", "0.0625", "--boundary-cell", "0.125", "--json", str(tmp_path / "summary.json")]
    for extra in ([], ["--no-progress"]):
        assert main([str(source), *options, *extra]) == 0
        out, err = capsys.readouterr()
        assert err == "" and f"wrote {tmp_path / DEFAULT_MAP_NAME}" in out
        written = load_region_map(tmp_path / DEFAULT_MAP_NAME)
        assert written.belongs_to(load_coefficients(source, region_map=None))
        assert json.loads((tmp_path / "summary.json").read_text())["cells"] == written.size
