"""The clearance bound's second-order form (pipeline.certify.clearance_bound, ``second_order``;
pipeline.certify.interval.lower_bound): over (L, W), (L, W, x) and (L, W, x, d) boxes it stays
below the clearance sampled in the box (analytic route from the online generator, and Coal), it
is never looser than the mean-value form, its gap to the sampled minimum shrinks quadratically
and is a fraction of the mean-value form's, and the search with it tiles the box with leaves
whose bounds hold."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline import load_coefficients
from pipeline.certify.clearance_bound import box_clearance_bounds
from pipeline.certify.interval import Jet, lower_bound, upper_bound
from pipeline.certify.range_model import RangeModel
from pipeline.certify.search import SearchSettings, cell_boxes, search
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance, analytic_link_clearance
from pipeline.model.arm import PlanarArm
from pipeline.offline.coefficients import Coefficients
from pipeline.online.generator import generate

D_RANGE = (0.55, 0.57)


@pytest.fixture(scope="module")
def eq9() -> Coefficients:
    return load_coefficients("paper")


@pytest.fixture(scope="module", params=["LW", "LWx", "LWxd"])
def lifted(request, eq9: Coefficients, over_x, over_xd) -> Coefficients:
    """Eq. 9 over (L, W), lifted to (L, W, x) and to (L, W, x, d) with x (and d) terms."""
    if request.param == "LW":
        return eq9
    if request.param == "LWx":
        return over_x(eq9, scale=0.2)
    return over_xd(eq9, d_range_m=D_RANGE, scale=0.2)


def clearance_at(coefficients: Coefficients, arm: PlanarArm, point: np.ndarray, coal: bool = False) -> float:
    """Clearance of both links at (the coefficients' variables, s), the obstacle moved by x and d."""
    names = coefficients.variables.names
    moves = {name: float(point[names.index(name)]) for name in ("x", "d") if name in names}
    answer = generate(coefficients, float(point[0]), float(point[1]), **moves, out_of_range="ignore")
    q = answer.q(float(point[-1]) * answer.duration_s)
    if coal:
        return float(CoalClearance(arm, answer.obstacle).link_clearance(q).min())
    return float(analytic_link_clearance(q, arm, answer.obstacle).min())


def corners_and_inside(k: int, rng: np.random.Generator, inside: int) -> np.ndarray:
    """Offsets in [-1, 1]^k: the two opposite corners, two of alternating sign, the centre and
    ``inside`` random points."""
    alternate = np.where(np.arange(k) % 2 == 0, 1.0, -1.0)
    fixed = np.array([np.ones(k), -np.ones(k), alternate, -alternate, np.zeros(k)])
    return np.vstack([fixed, rng.uniform(-1.0, 1.0, (inside, k))])


@settings(max_examples=4, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_second_order_bounds_are_below_the_sampled_clearance(
    lifted: Coefficients, arm: PlanarArm, random_boxes, seed: int
) -> None:
    """Any boxes, every axis set: each sampled point clears at least the box's bound, and the
    bound is at least the mean-value form's."""
    model = RangeModel.from_coefficients(lifted)
    rng = np.random.default_rng(seed)
    center, radius = random_boxes(model, 12, rng)
    first = box_clearance_bounds(model, center, radius).lower_m
    second = box_clearance_bounds(model, center, radius, second_order=True).lower_m
    assert np.all(second >= first - 1e-12)
    for k in range(center.shape[0]):
        for u in corners_and_inside(center.shape[1], rng, 6):
            assert clearance_at(lifted, arm, center[k] + u * radius[k]) >= second[k] - 1e-12


def test_second_order_bounds_hold_against_coal(lifted: Coefficients, arm: PlanarArm, random_boxes) -> None:
    model = RangeModel.from_coefficients(lifted)
    rng = np.random.default_rng(41)
    center, radius = random_boxes(model, 10, rng)
    bounds = box_clearance_bounds(model, center, radius, second_order=True).lower_m
    for k in range(center.shape[0]):
        for u in rng.uniform(-1.0, 1.0, (3, center.shape[1])):
            value = clearance_at(lifted, arm, center[k] + u * radius[k], coal=True)
            assert value >= bounds[k] - COAL_DISTANCE_ERROR_M


def test_second_order_gap_is_a_fraction_of_the_mean_value_gap_and_shrinks_quadratically(
    eq9: Coefficients, arm: PlanarArm
) -> None:
    """At one (L, W, s) point where the links stay clear, cubes halved three times: the gap below
    the clearance's minimum on a 7^3 grid of each box falls by more than 3 per halving with the
    second-order form, and stays below a third of the mean-value form's."""
    model = RangeModel.from_coefficients(eq9)
    center = np.array([0.26, 0.095, 0.45])
    first_gaps, second_gaps = [], []
    for h in (4e-3, 2e-3, 1e-3, 5e-4):
        radius = np.array([h, 0.4 * h, 2 * h])
        grid = [np.linspace(c - r, c + r, 7) for c, r in zip(center, radius, strict=True)]
        points = np.array(np.meshgrid(*grid, indexing="ij")).reshape(3, -1).T
        lowest = min(clearance_at(eq9, arm, p) for p in points)
        first = box_clearance_bounds(model, center[None], radius[None]).lower_m[0]
        second = box_clearance_bounds(model, center[None], radius[None], second_order=True).lower_m[0]
        assert second <= lowest
        first_gaps.append(lowest - first)
        second_gaps.append(lowest - second)
    ratios = np.array(second_gaps[:-1]) / np.array(second_gaps[1:])
    assert np.all(ratios > 3.0), ratios
    assert np.all(np.array(second_gaps) < np.array(first_gaps) / 3.0), (first_gaps, second_gaps)


def test_taylor_forms_of_a_quadratic_by_hand() -> None:
    """f(x, y) = x^2 + 3 y on [1, 3] x [-1, 1] takes [-2, 12]. At the centre f = 4, grad f = (4, 3),
    H = diag(2, 0): the second-order form gives 4 -+ (4 + 3 + 1) = [-4, 12], the mean-value form
    4 -+ (max |2x| + 3) = 4 -+ 9 = [-5, 13]; each bound is the tighter of the two where the box's
    jet carries a Hessian, the mean-value one where it does not."""
    center, radius = np.array([2.0, 0.0]), np.array([1.0, 1.0])

    def f(r: np.ndarray, order: int) -> Jet:
        x = Jet.variable(center[0:1], r[0:1], 0, 2, order)
        y = Jet.variable(center[1:2], r[1:2], 1, 2, order)
        return x.square() + y * 3.0

    point, box = f(np.zeros(2), 1), f(radius, 2)
    low = lower_bound(point, box, radius[None])[0]
    high = upper_bound(point, box, radius[None])[0]
    assert low == pytest.approx(-4.0, abs=1e-12) and high == pytest.approx(12.0, abs=1e-12)
    box1 = f(radius, 1)
    assert lower_bound(point, box1, radius[None])[0] == pytest.approx(-5.0, abs=1e-12)
    assert upper_bound(point, box1, radius[None])[0] == pytest.approx(13.0, abs=1e-12)


def test_search_with_the_second_order_form_tiles_the_box_and_its_bounds_hold(
    eq9: Coefficients, over_x, arm: PlanarArm
) -> None:
    """Over (L, W, x): the leaves tile the box, every sampled point clears its leaf's bound, and
    the margin is proven on at least the volume the mean-value form proves."""
    lifted = over_x(eq9, scale=0.2)
    model = RangeModel.from_coefficients(lifted)
    common = {"max_depth_lw": 4, "boundary_depth_lw": 3, "max_depth_s": 10, "initial_depth_lw": 1}
    first = search(model, SearchSettings(**common))
    second = search(model, SearchSettings(**common, second_order=True))
    for leaves in (first, second):
        np.testing.assert_allclose(np.sum(2.0 ** -leaves.levels.sum(axis=1)), 1.0, rtol=0, atol=1e-12)
    margin_volume = [np.sum(2.0 ** -leaves.levels.sum(axis=1)[leaves.bound_m >= 0.01]) for leaves in (first, second)]
    assert margin_volume[1] >= margin_volume[0]
    rng = np.random.default_rng(43)
    centres, halves = cell_boxes(model, second.levels, second.index)
    for k in rng.choice(centres.shape[0], 25, replace=False):
        for u in rng.uniform(-1.0, 1.0, (4, 3)):
            point = np.append(centres[k] + u * halves[k], rng.uniform())
            assert clearance_at(lifted, arm, point) >= second.bound_m[k] - 1e-12
