"""The compiled core of a query (pipeline.online.kernel) against the NumPy routes: T and the
regression within the rounding bounds its docstring derives (bounds small enough for the
certificate's slack), the region map's leaf exactly (random trees over 2, 3 and 4 axes, deeper
than the dense index, strips along W, points on cell edges), and the first unreachable point."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.certify.interval import FLOAT_SLACK_M
from pipeline.exceptions import InvalidParameterError
from pipeline.model.kinematics import reach_annulus_m
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import constraint_points
from pipeline.offline.variables import Variables
from pipeline.online.generator import generate
from pipeline.online.kernel import NO_TABLES, _duration, query_core, query_core_entry
from pipeline.online.query_state import state_of

X_RANGE = (-0.03, 0.03)
D_RANGE = (0.55, 0.57)


@pytest.fixture(scope="module")
def paper_x(paper, over_x):
    return over_x(paper, X_RANGE, seed=3, scale=0.05)


@pytest.fixture(scope="module")
def paper_xd(paper, over_xd):
    return over_xd(paper, X_RANGE, D_RANGE, seed=3, scale=0.05)


def core_arguments(coefficients, L, W, x=None, d=None, tables=NO_TABLES) -> tuple:
    """query_core's arguments for one query, made as the generator makes them."""
    plan = state_of(coefficients).plan
    c = plan.centre_x if x is None else x
    top = plan.top if d is None else d
    y1 = top if plan.y1_is_top else plan.y1
    given = {"x": x, "d": d}
    beyond = (*(given[name] for name in plan.extra), math.nan, math.nan)
    return (L, W, c, top, y1, beyond[0], beyond[1], *plan.core, *tables)


def core(coefficients, L, W, x=None, d=None, tables=NO_TABLES):
    """query_core's answer for one query, its arguments made as the generator makes them."""
    return query_core(*core_arguments(coefficients, L, W, x, d, tables))


def same_bits(a, b) -> bool:
    """True if two of the core's answers hold the same values, bit for bit (NaN equal to NaN)."""
    flat = [np.array(v if isinstance(v, tuple) else [v], dtype=float) for v in (*a, *b)]
    half = len(flat) // 2
    return all(
        np.array_equal(u.view(np.int64), v.view(np.int64)) for u, v in zip(flat[:half], flat[half:], strict=True)
    )


@settings(max_examples=100, deadline=None)
@given(st.floats(0.1, 0.4), st.floats(0.05, 0.15), st.floats(*X_RANGE), st.floats(*D_RANGE))
def test_the_compiled_entry_is_the_dispatchers_core(paper, paper_x, paper_xd, L, W, x, d) -> None:
    """The generator's route into the core (query_core_entry, past the dispatcher's type matching)
    gives the dispatcher's answer, bit for bit, and is not the dispatcher itself."""
    assert query_core_entry is not query_core
    for coefficients, given_values in ((paper, {}), (paper_x, {"x": x}), (paper_xd, {"x": x, "d": d})):
        arguments = core_arguments(coefficients, L, W, **given_values)
        assert all(a.flags.c_contiguous for a in arguments if isinstance(a, np.ndarray))
        assert same_bits(query_core_entry(*arguments), query_core(*arguments))


@settings(max_examples=200, deadline=None)
@given(st.floats(0.1, 0.3), st.floats(0.01, 0.1), st.floats(0.1, 0.5), st.floats(0.05, 0.4), st.floats(0.1, 0.5))
def test_t_is_its_source_run_by_the_interpreter(paper, x1, gap, y1, y3, rise) -> None:
    """The compiled T is the rule's sum as its source writes it (left to right, no operation fused or
    reordered by the compiler): equal, bit for bit, to the same function run by Python."""
    k, plan = state_of(paper).plan.core
    x2 = x1 - gap if x1 > gap else x1 / 2.0
    arguments = (plan, k, x1, x2, y3 + rise, y3, y1, paper.scene.speed_m_s)
    compiled, interpreted = _duration(*arguments), float(_duration.py_func(*arguments))
    assert np.array_equal(np.array(compiled).view(np.int64), np.array(interpreted).view(np.int64))


@settings(max_examples=200, deadline=None)
@given(st.floats(0.2, 0.3), st.floats(0.08, 0.12), st.floats(*X_RANGE), st.floats(*D_RANGE))
def test_t_and_the_regression_are_the_numpy_routes_to_rounding(paper, paper_x, paper_xd, rounding, L, W, x, d):
    for coefficients, given_values in ((paper, {}), (paper_x, {"x": x}), (paper_xd, {"x": x, "d": d})):
        answer = generate(coefficients, L, W, **given_values)
        reference, bound = rounding.regression(coefficients, L, W, **given_values)
        assert np.all(np.abs(np.subtract(answer.trajectory.parameters, reference)) <= bound)
        duration, duration_bound = rounding.duration(answer.scene, L, W)
        assert abs(answer.duration_s - duration) <= duration_bound
        # Small enough for the certificate's slack (pipeline.online.kernel's docstring).
        assert bound.max() < 1e-12 and duration_bound < 1e-12 < FLOAT_SLACK_M


def random_tree(k: int, rng: np.random.Generator, deepest: int) -> tuple[np.ndarray, np.ndarray]:
    """Leaves (depth (n,), index (n, k)) of a random 2^k-tree: a node is cut with probability
    3 / 2^k (always above depth 2, and the first node of every level), down to ``deepest``."""
    leaves, pending = [], [(0, (0,) * k)]
    while pending:
        depth, index = pending.pop()
        if depth < deepest and (depth < 2 or not any(index) or rng.random() < 3.0 / 2**k):
            for child in range(2**k):
                bits = [(child >> (k - 1 - a)) & 1 for a in range(k)]
                pending.append((depth + 1, tuple(2 * i + b for i, b in zip(index, bits, strict=True))))
        else:
            leaves.append((depth, index))
    return np.array([d for d, _ in leaves]), np.array([i for _, i in leaves])


def strips(depth: np.ndarray, index: np.ndarray, rng: np.random.Generator):
    """Cut some of the deepest quadtree leaves into 2 or 4 strips along W."""
    top = depth.max()
    rows, split = [], []
    for d, (i, j) in zip(depth, index, strict=True):
        e = int(rng.integers(0, 3)) if d == top else 0
        for s in range(2**e):
            rows.append((d, i, (j << e) + s))
            split.append(e)
    rows = np.array(rows)
    return rows[:, 0], rows[:, 1:], np.array(split)


def points_to_check(map_, rng: np.random.Generator, n: int) -> np.ndarray:
    """Random points of the map's box, and points on the edges of its deepest cells and on the box's faces."""
    ranges = np.array(map_.ranges_m)
    lo, hi = ranges[:, 0], ranges[:, 1]
    cells = 2**map_.subpaving.top
    random = lo + (hi - lo) * rng.random((n, lo.size))
    edges = lo + (hi - lo) * rng.integers(0, cells + 1, (n, lo.size)) / cells
    return np.vstack([random, edges, lo, hi])


@pytest.mark.parametrize("axes", [("L", "W"), ("L", "W", "x"), ("L", "W", "x", "d")])
def test_the_leaf_is_the_maps(paper, paper_x, paper_xd, leaf_map, axes) -> None:
    """Trees deeper than the dense index of k > 2 axes (depth 9 > 7 for k = 3, 6 > 5 for k = 4)."""
    coefficients = {2: paper, 3: paper_x, 4: paper_xd}[len(axes)]
    rng = np.random.default_rng(len(axes))
    k = len(axes)
    depth, index = random_tree(k, rng, {2: 7, 3: 9, 4: 6}[k])
    assert depth.max() == {2: 7, 3: 9, 4: 6}[k]
    split = None
    if k == 2:
        depth, index, split = strips(depth, index, rng)
    n = depth.size
    extra = tuple(tuple(coefficients.fitted_range_m[name]) for name in axes[2:])
    clearance, status = rng.uniform(0.0, 0.02, n), rng.integers(0, 4, n)
    map_ = leaf_map(coefficients, depth, index, clearance, status, axes, extra, split)
    points = points_to_check(map_, rng, 1500)
    expected = map_.leaf_indices(*points.T)
    assert np.all(expected >= 0)
    tables = map_.lookup_tables
    assert tables.index.flags.c_contiguous and tables.bounds.flags.c_contiguous  # as query_core_entry reads them
    found, bounds = [], []
    for point in points.tolist():
        L, W, *rest = point
        values = dict(zip(axes[2:], rest, strict=True))
        answer = core(coefficients, L, W, tables=tables, **values)
        found.append(answer[4])
        bounds.append(answer[5:8])
    np.testing.assert_array_equal(found, expected)
    # The leaf's bounds and status, as the map stores them.
    stored = np.column_stack([map_.clearance_bound_m[expected], map_.endpoint_bound_m[expected], map_.status[expected]])
    np.testing.assert_array_equal(np.array(bounds), stored)
    # Outside the box: no leaf, and the query is outside the fitted range.
    L_hi = coefficients.fitted_range_m["L"][1]
    outside = core(coefficients, math.nextafter(L_hi, 1.0), 0.1, *(0.0, 0.56)[: k - 2], tables=tables)
    assert outside[3] is False and outside[4] == -1 and outside[7] == -1 and math.isnan(outside[5])


@settings(max_examples=200, deadline=None)
@given(st.floats(0.05, 0.6), st.floats(0.05, 0.5), st.floats(-0.3, 0.3))
def test_the_first_unreachable_point_is_the_path_modules(paper_x, L, W, x) -> None:
    scene = replace(paper_x.scene, centre_x_m=x)
    if W >= scene.top_y_m:
        return  # refused before the core (the obstacle covers the base)
    points = constraint_points(Obstacle.in_scene(L, W, scene), scene)
    lo, hi = reach_annulus_m(paper_x.link_lengths_m)
    radii = np.hypot(points[:, 0], points[:, 1])
    outside = np.flatnonzero((radii < lo) | (radii > hi))
    unreachable, radius = core(paper_x, L, W, x=x)[:2]
    if outside.size == 0:
        assert unreachable == -1 and math.isnan(radius)
    else:
        assert unreachable == outside[0]
        assert radius == pytest.approx(radii[outside[0]], rel=1e-15)


def test_variables_over_d_alone(paper) -> None:
    """The code of d alone (the variables' order is L, W, then d): the core's inside test and
    regression read d."""
    lwd = Variables(("L", "W", "d"))
    parameters = {}
    for name, b in paper.parameters.items():
        row = np.zeros(lwd.basis_size)
        row[[0, 1, 2, 4, 5, 7]] = b
        row[3] = 1.0  # + d
        parameters[name] = tuple(row.tolist())
    over_d = replace(paper, parameters=parameters, fitted_range_m={**paper.fitted_range_m, "d": D_RANGE}, variables=lwd)
    for d in (0.55, 0.56, 0.57):
        base = core(paper, 0.25, 0.1)
        moved = core(over_d, 0.25, 0.1, d=d)
        assert moved[3] is True
        np.testing.assert_allclose(np.subtract(moved[8], base[8]), d, rtol=0, atol=1e-15)
    assert core(over_d, 0.25, 0.1, d=0.571)[3] is False


def test_coefficients_whose_terms_do_not_fit_their_variables_are_refused(paper, paper_x) -> None:
    """The core reads the basis' terms by the variables' count: another count is refused in one
    line before it runs."""
    for coefficients, given_values in ((paper, {}), (paper_x, {"x": 0.0})):
        short = replace(coefficients, parameters={name: v[:-1] for name, v in coefficients.parameters.items()})
        with pytest.raises(InvalidParameterError, match=r"^coefficients' parameters = '8 parameters of \d+ terms'"):
            generate(short, 0.25, 0.1, **given_values)
