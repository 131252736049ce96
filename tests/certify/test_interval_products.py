"""pipeline.certify.interval_products: the compiled bounds of the interval product are the NumPy
form's doubles bit for bit (signed zeros, infinities and 0 x inf included), broadcast like it,
and enclose every product of points of the two intervals."""

from __future__ import annotations

import warnings

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.certify.interval import Interval
from pipeline.certify.interval_products import product_hi, product_lo


def numpy_bounds(a_lo, a_hi, b_lo, b_hi) -> tuple[np.ndarray, np.ndarray]:
    """The NumPy form: four products, 0 x inf taken as 0, their min and max."""

    def times(a, b):
        with np.errstate(invalid="ignore"):
            p = np.multiply(a, b)
        return np.where(np.isnan(p), 0.0, p)

    products = [times(a_lo, b_lo), times(a_lo, b_hi), times(a_hi, b_lo), times(a_hi, b_hi)]
    return np.minimum.reduce(products), np.maximum.reduce(products)


def bits(x: np.ndarray) -> np.ndarray:
    return np.asarray(x, dtype=float).view(np.int64)


def test_same_doubles_as_the_numpy_form_with_zeros_and_infinities() -> None:
    rng = np.random.default_rng(0)
    pool = np.concatenate([rng.normal(size=1000), rng.normal(size=100) * 1e300, [0.0, -0.0, np.inf, -np.inf]])
    n = 100_000
    a_lo, a_hi, b_lo, b_hi = (rng.choice(pool, n) for _ in range(4))
    with np.errstate(over="ignore", invalid="ignore"):
        lo, hi = numpy_bounds(a_lo, a_hi, b_lo, b_hi)
        compiled = product_lo(a_lo, a_hi, b_lo, b_hi), product_hi(a_lo, a_hi, b_lo, b_hi)
    assert np.array_equal(bits(compiled[0]), bits(lo))
    assert np.array_equal(bits(compiled[1]), bits(hi))
    assert np.any(np.signbit(lo) & (lo == 0.0)) and np.any(np.isinf(hi))  # the edge cases occur


def test_no_warning_for_zero_times_infinity() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        product = Interval(np.array([0.0, -1.0]), np.array([0.0, 2.0])) * Interval(np.array([-np.inf, 1.0]), np.inf)
    assert np.array_equal(product.lo, [0.0, -np.inf]) and np.array_equal(product.hi, [0.0, np.inf])


def test_broadcasting_and_the_scalar_operand() -> None:
    rng = np.random.default_rng(1)
    a_lo = rng.normal(size=(3, 1, 4))
    a_hi = a_lo + rng.uniform(size=(3, 1, 4))
    o = rng.normal(size=(5, 1))
    product = Interval(a_lo, a_hi) * o
    lo, hi = numpy_bounds(a_lo, a_hi, o, o)
    assert product.shape == (3, 5, 4)
    assert np.array_equal(bits(product.lo), bits(lo)) and np.array_equal(bits(product.hi), bits(hi))


finite = st.floats(-1e3, 1e3, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(finite, finite, finite, finite, st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_encloses_every_product_of_points(a1: float, a2: float, b1: float, b2: float, s: float, t: float) -> None:
    a_lo, a_hi, b_lo, b_hi = min(a1, a2), max(a1, a2), min(b1, b2), max(b1, b2)
    x, y = a_lo + s * (a_hi - a_lo), b_lo + t * (b_hi - b_lo)
    x, y = min(max(x, a_lo), a_hi), min(max(y, b_lo), b_hi)
    assert product_lo(a_lo, a_hi, b_lo, b_hi) <= x * y <= product_hi(a_lo, a_hi, b_lo, b_hi)
