"""The fastest path-speed profile: at rest at both ends, x >= 0, x_k+1 = x_k + 2 ds u_k, every row
kept at both ends of each piece, x within the speed caps; and optimal against independent
solutions: the analytic trapezoid under a constant acceleration bound and speed cap, and a linear
program (scipy's HiGHS) on random problems, which the greedy profile must dominate pointwise.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

from pipeline import generate, load_coefficients, load_planar_arm
from pipeline.model.limits import ArmLimits
from pipeline.motion.path_constraints import enclose_path, piece_constraints
from pipeline.motion.speed_profile import fastest_profile
from pipeline.online.execution import dynamics_of

_RTOL = 1e-9


def _check_invariants(cu, cx, rhs, cap, ds, x, u) -> None:
    n = cap.size
    assert x.shape == (n + 1,) and u.shape == (n,)
    assert x[0] == 0.0 and x[-1] == 0.0
    assert np.all(x >= 0.0)
    scale_x = max(1.0, float(x.max()))
    assert np.allclose(x[1:], x[:-1] + 2.0 * ds * u, rtol=_RTOL, atol=_RTOL * scale_x)
    for end in (x[:-1], x[1:]):  # every row at both ends of its piece
        lhs = cu * u[:, None] + cx * end[:, None]
        size = np.abs(cu * u[:, None]) + np.abs(cx * end[:, None]) + np.abs(rhs)
        assert np.all(lhs <= rhs + _RTOL * size)
        assert np.all(end <= cap * (1 + _RTOL))


@functools.cache
def _real_rows(pieces: int, share: float):
    trajectory = generate(load_coefficients("paper"), 0.27, 0.09, out_of_range="ignore").trajectory
    arm = load_planar_arm()
    edges = np.linspace(0.0, trajectory.duration_s, pieces + 1)
    rows = piece_constraints(enclose_path(trajectory.parameters, edges, dynamics_of(arm)), _limits(arm), share)
    return rows, edges[1] - edges[0]


def _limits(arm) -> ArmLimits:
    return ArmLimits.from_arm(arm, acceleration_rad_s2=(10.0, 7.0))


@pytest.mark.parametrize(("pieces", "share"), [(50, 1.0), (200, 0.99), (1000, 0.5)])
def test_profile_of_a_real_path_keeps_every_row(pieces, share) -> None:
    rows, ds = _real_rows(pieces, share)
    x, u = fastest_profile(rows.cu, rows.cx, rows.rhs, rows.speed_cap, ds)
    _check_invariants(rows.cu, rows.cx, rows.rhs, rows.speed_cap, ds, x, u)
    assert np.all(x[1:-1] > 0.0)  # it moves
    if pieces <= 200:  # optimal: it dominates the linear program's profile on the same rows
        reference = _lp_profile(rows.cu, rows.cx, rows.rhs, rows.speed_cap, ds)
        assert np.all(x >= reference - 1e-7 * max(1.0, float(reference.max())))


@settings(max_examples=40, deadline=None)
@given(
    st.floats(0.1, 50.0),
    st.one_of(st.just(1e3), st.floats(0.01, 100.0)),  # 1e3: a cap that does not bind
    st.integers(1, 300),
    st.floats(1e-3, 0.1),
)
def test_constant_acceleration_bound_gives_the_analytic_trapezoid(a, cap, pieces, ds) -> None:
    cu = np.tile([1.0, -1.0], (pieces, 1))
    cx = np.zeros((pieces, 2))
    rhs = np.tile([a, a], (pieces, 1))
    caps = np.full(pieces, cap)
    x, u = fastest_profile(cu, cx, rhs, caps, ds)
    _check_invariants(cu, cx, rhs, caps, ds, x, u)
    s = np.arange(pieces + 1) * ds
    total = pieces * ds
    want = np.minimum(np.minimum(2.0 * a * s, cap), 2.0 * a * (total - s))
    want[-1] = 0.0
    # The backward pass takes X_k (1 - 1e-9) where Newton stalls at the root (module docstring): up to
    # 1e-9 lost per piece, compounding over the pieces after k.
    rtol = 1e-9 * (pieces + 1)
    assert np.all(x <= want * (1 + 1e-12) + 1e-15)
    assert np.allclose(x, want, rtol=rtol, atol=rtol * max(1.0, float(want.max())))


def _lp_profile(cu, cx, rhs, cap, ds) -> np.ndarray:
    """max sum x_k subject to every row at both ends of each piece, 0 <= x <= cap, rest at the ends."""
    n, m = cu.shape
    rows, bounds = [], []
    for k in range(n):
        for j in range(m):
            # u_k = (x_k+1 - x_k) / (2 ds); the row at x_k, then at x_k+1.
            for at in (k, k + 1):
                row = np.zeros(n + 1)
                row[k] -= cu[k, j] / (2.0 * ds)
                row[k + 1] += cu[k, j] / (2.0 * ds)
                row[at] += cx[k, j]
                rows.append(row)
                bounds.append(rhs[k, j])
    upper = np.full(n + 1, np.inf)
    upper[:-1] = np.minimum(upper[:-1], cap)
    upper[1:] = np.minimum(upper[1:], cap)
    upper[0] = upper[-1] = 0.0
    result = linprog(
        -np.ones(n + 1),
        A_ub=np.array(rows),
        b_ub=np.array(bounds),
        bounds=list(zip(np.zeros(n + 1), upper, strict=True)),
        method="highs",
    )
    assert result.status == 0, result.message
    return result.x


@st.composite
def random_problems(draw):
    n = draw(st.integers(2, 25))
    m = draw(st.integers(1, 6))
    seed = draw(st.integers(0, 2**32 - 1))
    ds = draw(st.floats(0.005, 0.05))
    rng = np.random.default_rng(seed)
    # Rows that bound u from both sides (an acceleration bound), then random rows; cx small
    # enough against cu that the greedy profile dominates (2 ds |cx| / |cu| < 1).
    a = rng.uniform(0.5, 5.0, (n, 1))
    cu = np.hstack([np.ones((n, 1)), -np.ones((n, 1)), rng.choice([-1.0, 1.0], (n, m)) * rng.uniform(0.3, 3.0, (n, m))])
    cx = np.hstack([np.zeros((n, 2)), rng.uniform(-3.0, 3.0, (n, m))])
    rhs = np.hstack([a, a, rng.uniform(0.2, 5.0, (n, m))])
    # Large finite caps where none binds (infinite ones: see the xfail test below).
    cap = np.where(rng.uniform(size=n) < 0.3, 1e3, rng.uniform(0.05, 5.0, n))
    return cu, cx, rhs, cap, ds


@settings(max_examples=40, deadline=None)
@given(random_problems())
def test_greedy_profile_dominates_the_linear_program(problem) -> None:
    cu, cx, rhs, cap, ds = problem
    x, u = fastest_profile(cu, cx, rhs, cap, ds)
    _check_invariants(cu, cx, rhs, cap, ds, x, u)
    reference = _lp_profile(cu, cx, rhs, cap, ds)
    assert np.all(x >= reference - 1e-7 * max(1.0, float(reference.max()))), np.max(reference - x)
    # Feasible for the LP, so it cannot beat the LP's optimum: the sums agree.
    assert np.sum(x) <= np.sum(reference) + 1e-6 * max(1.0, float(np.sum(reference)))


def test_profile_with_no_rows_is_the_speed_cap() -> None:
    cap = np.array([1.0, 4.0, 2.0, 3.0])
    x, u = fastest_profile(np.zeros((4, 0)), np.zeros((4, 0)), np.zeros((4, 0)), cap, 0.1)
    _check_invariants(np.zeros((4, 0)), np.zeros((4, 0)), np.zeros((4, 0)), cap, 0.1, x, u)
    assert np.allclose(x, [0.0, 1.0, 2.0, 2.0, 0.0], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("a", "ds", "pieces"), [(1e-3, 1e-2, 2), (1.5285422968826818, 0.0625, 2), (1e-2, 1e-2, 10)])
def test_trapezoid_without_a_speed_cap(a, ds, pieces) -> None:
    cu = np.tile([1.0, -1.0], (pieces, 1))
    cx = np.zeros((pieces, 2))
    rhs = np.tile([a, a], (pieces, 1))
    x, _ = fastest_profile(cu, cx, rhs, np.full(pieces, np.inf), ds)
    s = np.arange(pieces + 1) * ds
    want = np.minimum(2.0 * a * s, 2.0 * a * (pieces * ds - s))
    assert np.allclose(x, want, rtol=1e-9, atol=1e-9 * max(1.0, float(want.max())))
