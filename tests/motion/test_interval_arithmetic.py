"""Interval arithmetic: every operation encloses dense samples of itself over random intervals,
and the ranges of sin are exact (their ends are attained).

The references are independent of the module: dense samples, and for sin the critical points
pi/2 + k pi enumerated one by one over the interval.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.motion.interval_arithmetic import (
    FLOAT_SLACK_ABSOLUTE,
    FLOAT_SLACK_RELATIVE,
    affine_trig,
    magnitude,
    mul,
    scale,
    sin_range,
    square,
    widen,
)

#: Tolerance of an enclosure against samples computed in floating point.
_ATOL = 1e-12

ends = st.floats(-30.0, 30.0, allow_nan=False)
widths = st.one_of(st.just(0.0), st.floats(0.0, 1e-6), st.floats(0.0, 20.0))
factors = st.floats(-50.0, 50.0, allow_nan=False)


@st.composite
def intervals(draw, widths=widths):
    lo = draw(ends)
    return lo, lo + draw(widths)


def _dense(lo: float, hi: float, n: int = 2001) -> np.ndarray:
    return np.linspace(lo, hi, n)


def _encloses(interval, values, atol: float = _ATOL) -> bool:
    lo, hi = (float(np.asarray(v).reshape(-1)[0]) for v in interval)
    scale_ = max(1.0, float(np.max(np.abs(values))))
    return lo <= hi and lo <= values.min() + atol * scale_ and values.max() <= hi + atol * scale_


def _exact_sin_range(lo: float, hi: float) -> tuple[float, float]:
    """min and max of sin over [lo, hi] from the ends and every critical point pi/2 + k pi inside."""
    candidates = [math.sin(lo), math.sin(hi)]
    for k in range(math.floor(lo / math.pi) - 2, math.ceil(hi / math.pi) + 2):
        point = math.pi / 2 + k * math.pi
        if lo <= point <= hi:
            candidates.append(1.0 if k % 2 == 0 else -1.0)
    return min(candidates), max(candidates)


@settings(max_examples=300, deadline=None)
@given(intervals())
def test_sin_range_encloses_samples_and_is_exact(interval) -> None:
    lo, hi = interval
    got_lo, got_hi = (float(v[0]) for v in sin_range(np.array([lo]), np.array([hi])))
    assert _encloses((got_lo, got_hi), np.sin(_dense(lo, hi, 20001)))
    want_lo, want_hi = _exact_sin_range(lo, hi)
    assert abs(got_lo - want_lo) <= 1e-12 and abs(got_hi - want_hi) <= 1e-12, (lo, hi, got_lo, got_hi)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(ends, widths), min_size=1, max_size=40))
def test_sin_range_is_elementwise(pairs) -> None:
    lo = np.array([p[0] for p in pairs])
    hi = lo + np.array([p[1] for p in pairs])
    got_lo, got_hi = sin_range(lo, hi)
    assert got_lo.shape == lo.shape and got_hi.shape == lo.shape
    for k in range(lo.size):
        want = _exact_sin_range(lo[k], hi[k])
        assert abs(got_lo[k] - want[0]) <= 1e-12 and abs(got_hi[k] - want[1]) <= 1e-12


def test_sin_range_at_and_around_critical_points() -> None:
    for k in range(-6, 7):
        peak = math.pi / 2 + k * math.pi
        top = 1.0 if k % 2 == 0 else -1.0
        # A degenerate interval on the critical point, and ones that end on it or just miss it.
        for lo, hi in ((peak, peak), (peak - 0.3, peak), (peak, peak + 0.3), (peak - 0.5, peak - 1e-3)):
            got = tuple(float(v[0]) for v in sin_range(np.array([lo]), np.array([hi])))
            want = _exact_sin_range(lo, hi)
            assert abs(got[0] - want[0]) <= 1e-12 and abs(got[1] - want[1]) <= 1e-12, (lo, hi, got, want)
        full = sin_range(np.array([peak - 0.1]), np.array([peak + 0.1]))
        assert float((full[1] if top > 0 else full[0])[0]) == top


@settings(max_examples=200, deadline=None)
@given(factors, intervals())
def test_scale_encloses_and_attains(k, interval) -> None:
    lo, hi = interval
    got = scale(k, np.array([lo]), np.array([hi]))
    values = k * _dense(lo, hi)
    assert _encloses(got, values)
    assert abs(float(got[0][0]) - values.min()) <= _ATOL * max(1.0, abs(values).max())
    assert abs(float(got[1][0]) - values.max()) <= _ATOL * max(1.0, abs(values).max())


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(factors, ends, widths), min_size=1, max_size=20))
def test_scale_by_an_array(rows) -> None:
    k = np.array([r[0] for r in rows])
    lo = np.array([r[1] for r in rows])
    hi = lo + np.array([r[2] for r in rows])
    got_lo, got_hi = scale(k, lo, hi)
    for i in range(k.size):
        assert _encloses((got_lo[i], got_hi[i]), k[i] * _dense(lo[i], hi[i], 101))


@settings(max_examples=200, deadline=None)
@given(intervals(), intervals())
def test_mul_encloses_every_product(a, b) -> None:
    got = mul(np.array([a[0]]), np.array([a[1]]), np.array([b[0]]), np.array([b[1]]))
    values = np.outer(_dense(*a, 201), _dense(*b, 201)).ravel()
    assert _encloses(got, values)
    # Tight: a product is bilinear, so its extremes are at the corners, which the grid holds.
    assert abs(float(got[0][0]) - values.min()) <= _ATOL * max(1.0, abs(values).max())
    assert abs(float(got[1][0]) - values.max()) <= _ATOL * max(1.0, abs(values).max())


@settings(max_examples=200, deadline=None)
@given(intervals())
def test_square_encloses_and_starts_at_zero_through_zero(interval) -> None:
    lo, hi = interval
    got = square(np.array([lo]), np.array([hi]))
    samples = _dense(lo, hi, 20001)
    values = samples * samples
    assert _encloses(got, values)
    if lo <= 0.0 <= hi:
        assert float(got[0][0]) == 0.0
    else:
        assert abs(float(got[0][0]) - min(lo * lo, hi * hi)) <= _ATOL * max(1.0, hi * hi, lo * lo)
    assert abs(float(got[1][0]) - max(lo * lo, hi * hi)) <= _ATOL * max(1.0, hi * hi, lo * lo)


@settings(max_examples=150, deadline=None)
@given(factors, factors, factors, intervals())
def test_affine_trig_encloses_over_a_phase_interval(k0, kc, ks, phase) -> None:
    lo, hi = phase
    s = sin_range(np.array([lo]), np.array([hi]))
    c = sin_range(np.array([lo + math.pi / 2]), np.array([hi + math.pi / 2]))
    got = affine_trig(k0, kc, ks, *c, *s)
    t = _dense(lo, hi, 20001)
    assert _encloses(got, k0 + kc * np.cos(t) + ks * np.sin(t), atol=1e-11)


@settings(max_examples=150, deadline=None)
@given(factors, factors, factors, intervals(), intervals())
def test_affine_trig_encloses_over_independent_boxes(k0, kc, ks, c, s) -> None:
    got = affine_trig(k0, kc, ks, np.array([c[0]]), np.array([c[1]]), np.array([s[0]]), np.array([s[1]]))
    values = (k0 + kc * _dense(*c, 101)[:, None] + ks * _dense(*s, 101)[None, :]).ravel()
    assert _encloses(got, values, atol=1e-11)
    # Exact for independent boxes: the extremes are at corners of the box.
    assert abs(float(got[0][0]) - values.min()) <= 1e-11 * max(1.0, abs(values).max())
    assert abs(float(got[1][0]) - values.max()) <= 1e-11 * max(1.0, abs(values).max())


@settings(max_examples=200, deadline=None)
@given(st.floats(-1e6, 1e6), st.floats(0.0, 1e6))
def test_widen_widens_by_the_stated_slack(lo, width) -> None:
    hi = lo + width
    got_lo, got_hi = (float(v[0]) for v in widen(np.array([lo]), np.array([hi])))
    slack = FLOAT_SLACK_RELATIVE * max(abs(lo), abs(hi)) + FLOAT_SLACK_ABSOLUTE
    assert got_lo < lo and got_hi > hi
    assert math.isclose(lo - got_lo, slack, rel_tol=1e-6, abs_tol=1e-15 * max(1.0, abs(lo)))
    assert math.isclose(got_hi - hi, slack, rel_tol=1e-6, abs_tol=1e-15 * max(1.0, abs(hi)))


@settings(max_examples=200, deadline=None)
@given(intervals())
def test_magnitude_is_the_largest_absolute_value(interval) -> None:
    lo, hi = interval
    got = float(np.asarray(magnitude((np.array([lo]), np.array([hi]))))[0])
    values = np.abs(_dense(lo, hi))
    assert values.max() <= got <= values.max() * (1 + 1e-15)
