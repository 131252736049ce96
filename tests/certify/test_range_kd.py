"""The range certificate over (L, W, x) (pipeline.certify.range_model, clearance_bound, search,
range_certificate): bounds over boxes that move the obstacle are below the clearance sampled
inside them (analytic route, and Coal), the search's leaves tile the box, and with the x terms
set to zero the bounds at x = 0 are those of the (L, W) certificate."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.certify.clearance_bound import box_clearance_bounds
from pipeline.certify.range_model import RangeModel
from pipeline.certify.search import SearchSettings, cell_boxes, search
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance, analytic_link_clearance
from pipeline.model.arm import PlanarArm
from pipeline.offline.coefficients import Coefficients
from pipeline.online.generator import generate
from pipeline.online.loading import load_coefficients


@pytest.fixture(scope="module")
def eq9() -> Coefficients:
    return load_coefficients("paper")


@pytest.fixture(scope="module")
def eq9_x(eq9: Coefficients, over_x) -> Coefficients:
    return over_x(eq9, scale=0.2)


def clearance_at(coefficients: Coefficients, arm: PlanarArm, point: np.ndarray, coal: bool = False) -> float:
    """Clearance of both links at (L, W, x, s), the obstacle moved to x (online generator)."""
    L, W, x, s = point
    answer = generate(coefficients, L, W, x=x, out_of_range="ignore")
    q = answer.q(s * answer.duration_s)
    if coal:
        return float(CoalClearance(arm, answer.obstacle).link_clearance(q).min())
    return float(analytic_link_clearance(q, arm, answer.obstacle).min())


def test_model_has_the_axes_and_box(eq9_x: Coefficients) -> None:
    model = RangeModel.from_coefficients(eq9_x)
    assert model.axes.names == ("L", "W", "x") and model.k == 3
    np.testing.assert_allclose(model.range_lo, [0.2, 0.08, -0.03], atol=1e-15)
    np.testing.assert_allclose(model.range_size, [0.1, 0.04, 0.06], atol=1e-15)


@pytest.mark.parametrize("seed", [11, 12])
def test_box_bounds_are_below_the_sampled_clearance(
    eq9_x: Coefficients, arm: PlanarArm, seed: int, random_boxes
) -> None:
    model = RangeModel.from_coefficients(eq9_x)
    center, radius = random_boxes(model, 60, np.random.default_rng(seed))
    bounds = box_clearance_bounds(model, center, radius)
    rng = np.random.default_rng(seed + 100)
    lowest = np.full(center.shape[0], np.inf)
    for k in range(center.shape[0]):
        corners = np.array([[-1, -1, -1, -1], [1, 1, 1, 1], [1, -1, 1, -1], [-1, 1, -1, 1]], dtype=float)
        inside = np.vstack([corners, rng.uniform(-1.0, 1.0, (12, 4)), np.zeros((1, 4))])
        for u in inside:
            lowest[k] = min(lowest[k], clearance_at(eq9_x, arm, center[k] + u * radius[k]))
    assert np.all(lowest >= bounds.lower_m - 1e-12)
    # The centre value is a clearance the box takes.
    np.testing.assert_allclose(bounds.center_m, [clearance_at(eq9_x, arm, c) for c in center], atol=1e-9)
    # Not vacuous: most of these boxes are proven collision-free.
    assert np.mean(bounds.lower_m > 0.0) > 0.5


def test_box_bounds_hold_against_coal(eq9_x: Coefficients, arm: PlanarArm, random_boxes) -> None:
    model = RangeModel.from_coefficients(eq9_x)
    center, radius = random_boxes(model, 40, np.random.default_rng(21))
    bounds = box_clearance_bounds(model, center, radius).lower_m
    rng = np.random.default_rng(22)
    for k in range(center.shape[0]):
        for u in rng.uniform(-1.0, 1.0, (4, 4)):
            assert clearance_at(eq9_x, arm, center[k] + u * radius[k], coal=True) >= bounds[k] - COAL_DISTANCE_ERROR_M


def test_bounds_at_x_zero_match_the_size_only_certificate(eq9: Coefficients, over_x) -> None:
    """Without x terms and at x = 0 with no x extent, the (L, W, x) bounds are the (L, W) ones."""
    flat = over_x(eq9, scale=0.0)
    model2, model3 = RangeModel.from_coefficients(eq9), RangeModel.from_coefficients(flat)
    rng = np.random.default_rng(31)
    c2 = np.column_stack([rng.uniform(0.21, 0.29, 200), rng.uniform(0.085, 0.115, 200), rng.uniform(0.05, 0.95, 200)])
    r2 = np.column_stack([np.full(200, 0.004), np.full(200, 0.002), np.full(200, 0.02)])
    c3 = np.column_stack([c2[:, :2], np.zeros(200), c2[:, 2]])
    r3 = np.column_stack([r2[:, :2], np.zeros(200), r2[:, 2]])
    b2, b3 = box_clearance_bounds(model2, c2, r2), box_clearance_bounds(model3, c3, r3)
    np.testing.assert_allclose(b3.lower_m, b2.lower_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b3.center_m, b2.center_m, rtol=0, atol=1e-12)


def test_moving_the_obstacle_under_the_same_motion_costs_clearance(eq9: Coefficients, over_x, arm: PlanarArm) -> None:
    """Without x terms the arm's motion ignores x: the bound over a box with an x extent is below
    the clearance of every obstacle position sampled in it, and below the bound without it."""
    flat = over_x(eq9, scale=0.0)
    model = RangeModel.from_coefficients(flat)
    s = np.linspace(0.0, 1.0, 11)
    c = np.column_stack([np.full(11, 0.25), np.full(11, 0.1), np.zeros(11), s])
    r0 = np.tile([0.002, 0.001, 0.0, 0.01], (11, 1))
    r1 = np.tile([0.002, 0.001, 0.01, 0.01], (11, 1))
    b0, b1 = box_clearance_bounds(model, c, r0).lower_m, box_clearance_bounds(model, c, r1).lower_m
    assert np.all(b1 <= b0) and np.any(b1 < b0 - 1e-3)
    for k in range(11):
        for x in np.linspace(-0.01, 0.01, 5):
            assert clearance_at(flat, arm, np.array([0.25, 0.1, x, s[k]])) >= b1[k] - 1e-12


@pytest.mark.parametrize("extra", [0, 2])
def test_search_leaves_tile_the_box_and_bound_the_clearance(eq9_x: Coefficients, arm: PlanarArm, extra: int) -> None:
    """With an extra depth, leaves go deeper than the smallest cell along some axis, never beyond
    it, and never below the smallest cell's volume by more than one cut."""
    model = RangeModel.from_coefficients(eq9_x)
    settings = SearchSettings(
        margin_m=0.01,
        max_depth_lw=3,
        extra_depth_lw=extra,
        boundary_depth_lw=2,
        initial_depth_lw=1,
        max_depth_s=10,
        resolution_m=2e-3,
    )
    found = search(model, settings)
    levels, index, bound = found.levels, found.index, found.bound_m
    assert index.shape == levels.shape == (bound.size, 3)
    assert levels.max() <= 3 + extra and (levels.max() > 3) == (extra > 0)
    assert levels.sum(axis=1).max() <= 3 * 3
    assert np.sum(2.0 ** -levels.sum(axis=1).astype(float)) == pytest.approx(1.0, abs=1e-12)
    centre, half = cell_boxes(model, levels, index)
    rng = np.random.default_rng(41)
    points = model.range_lo + rng.uniform(0.0, 1.0, (150, 3)) * model.range_size
    inside = np.all(np.abs(points[:, None, :] - centre[None]) <= half[None] * (1 + 1e-12), axis=2)
    assert np.all(inside.sum(axis=1) >= 1)  # every point in a leaf (boundaries in two)
    for p, row in zip(points, inside, strict=True):
        leaf = np.flatnonzero(row)[0]
        lowest = min(clearance_at(eq9_x, arm, np.append(p, s)) for s in np.linspace(0.0, 1.0, 41))
        assert lowest >= bound[leaf] - 1e-12


def test_unsupported_axes_and_families_are_refused(eq9: Coefficients, over_x) -> None:
    from dataclasses import replace

    from pipeline.motion.families import family_from_name
    from pipeline.offline.variables import Variables

    lifted = over_x(eq9)
    with pytest.raises(InvalidParameterError, match="paper family"):
        RangeModel.from_coefficients(replace(lifted, family=family_from_name("exact-endpoints")))
    model = RangeModel.from_coefficients(lifted)
    with pytest.raises(InvalidParameterError, match="axes"):  # d with a fixed y1 (tests/certify/test_range_d.py)
        replace(
            model,
            axes=Variables(("L", "W", "d")),
            extra_ranges_m=((0.5, 0.6),),
            scene=replace(model.scene, start_y_m=0.5),
        )


_X_MAPS = {
    "cubes": {},
    "extra-depth": {"extra_depth": 2},
    "merged": {"merge_spread_m": 0.05},
}  # Eq. 9: endpoint errors of cm


def _x_map(eq9_x: Coefficients, **fields):
    from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range

    return certify_range(eq9_x, RangeCertificateConfig(min_cell=1 / 8, boundary_cell=1 / 4, max_depth_s=12, **fields))


@pytest.fixture(scope="module", params=list(_X_MAPS))
def eq9_x_map(eq9_x: Coefficients, request):
    return _x_map(eq9_x, **_X_MAPS[request.param])


def test_merged_leaves_keep_every_status_volume_with_fewer_leaves(eq9_x: Coefficients) -> None:
    """Merging siblings whose bounds agree (pipeline.certify.leaf_merge) keeps each status's
    volume exactly and never raises a point's clearance bound or lowers its endpoint bound."""
    plain, merged = _x_map(eq9_x), _x_map(eq9_x, **_X_MAPS["merged"])
    assert merged.size < plain.size
    assert merged.summary()["area_fraction"] == plain.summary()["area_fraction"]
    rng = np.random.default_rng(7)
    points = [rng.uniform(lo, hi, 2000) for lo, hi in plain.ranges_m]
    a, b = plain.leaf_indices(*points), merged.leaf_indices(*points)
    assert np.all(np.asarray(merged.clearance_bound_m)[b] <= np.asarray(plain.clearance_bound_m)[a])
    assert np.all(np.asarray(merged.clearance_bound_m)[b] >= np.asarray(plain.clearance_bound_m)[a] - 0.05)
    assert np.all(np.asarray(merged.endpoint_bound_m)[b] >= np.asarray(plain.endpoint_bound_m)[a])
    assert np.all(np.asarray(merged.status)[b] == np.asarray(plain.status)[a])


def test_map_over_x_names_its_axes_and_tiles_the_box(eq9_x: Coefficients, eq9_x_map) -> None:
    from pipeline.certify.region_map import RegionMap

    assert eq9_x_map.axes == ("L", "W", "x")
    assert eq9_x_map.ranges_m[2:] == ((-0.03, 0.03),)
    assert eq9_x_map.belongs_to(eq9_x) or eq9_x.source_sha256 == ""
    summary = eq9_x_map.summary()
    assert sum(summary["area_fraction"].values()) == pytest.approx(1.0, abs=1e-12)
    again = RegionMap.from_json(eq9_x_map.to_json())
    assert again.to_json() == eq9_x_map.to_json()


def test_map_over_x_is_below_every_sampled_motion(eq9_x: Coefficients, eq9_x_map, arm: PlanarArm) -> None:
    """Dense in t at random (L, W, x): each motion's minimum lies above its leaf's bound, and a
    motion that dips below the margin is never in a "margin" leaf."""
    rng = np.random.default_rng(51)
    for L, W, x in zip(
        rng.uniform(0.2, 0.3, 30), rng.uniform(0.08, 0.12, 30), rng.uniform(-0.03, 0.03, 30), strict=True
    ):
        answer = generate(eq9_x, L, W, x=x)
        lowest = analytic_link_clearance(answer.q(np.linspace(0.0, answer.duration_s, 1001)), arm, answer.obstacle)
        cell = eq9_x_map.cell_at(L, W, x)
        assert cell.ranges_m[2][0] <= x <= cell.ranges_m[2][1]
        assert lowest.min() >= cell.clearance_bound_m - 1e-12
        if lowest.min() < eq9_x_map.margin_m:
            assert cell.status != "margin"


def test_execution_bounds_over_x_hold_along_sampled_motions(eq9_x: Coefficients, eq9_x_map, arm: PlanarArm) -> None:
    """Each leaf's joint-speed bound (paper timing) is above the speeds sampled at obstacles in it."""
    from pipeline.certify.map_for_coefficients import with_execution_bounds
    from pipeline.model.dynamics import identify_dynamics
    from pipeline.model.limits import ArmLimits

    mapped = with_execution_bounds(eq9_x_map, eq9_x, identify_dynamics(arm), ArmLimits.from_arm(arm, (5.0, 5.0)))
    assert mapped.execution is not None and mapped.execution.size == eq9_x_map.size
    rng = np.random.default_rng(61)
    for L, W, x in zip(
        rng.uniform(0.2, 0.3, 20), rng.uniform(0.08, 0.12, 20), rng.uniform(-0.03, 0.03, 20), strict=True
    ):
        answer = generate(eq9_x, L, W, x=x)
        t = np.linspace(0.0, answer.duration_s, 801)
        speed = np.abs(answer.dq(t)).max(axis=0)
        bound = mapped.execution.paper_speed_rad_s[mapped.leaf_at(L, W, x)]
        assert np.all(speed <= bound + 1e-12)
