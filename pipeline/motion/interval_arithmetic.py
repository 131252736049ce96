"""Interval arithmetic on NumPy arrays of lower and upper ends, elementwise.

An interval is a pair ``(lo, hi)`` of arrays (or scalars) with lo <= hi. Each operation returns an
interval that encloses every value the operation takes over its arguments' intervals: products
take the extremes of the four corner products, a square of an interval holding 0 starts at 0, and
the ranges of sin and cos over a phase interval are exact (the ends, and -1 / +1 where the interval
holds a critical point). Rounding is not accounted for here: callers widen their results with
:func:`widen` once a chain of operations is done (:mod:`pipeline.motion.execution_certificate`
states the slack and why it covers the chain).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "FLOAT_SLACK_ABSOLUTE",
    "FLOAT_SLACK_RELATIVE",
    "affine_trig",
    "magnitude",
    "mul",
    "scale",
    "sin_extremes",
    "sin_range",
    "sinusoid_ranges",
    "square",
    "widen",
]

#: Widening of every enclosure for floating-point rounding (:mod:`pipeline.motion.execution_certificate`).
FLOAT_SLACK_RELATIVE = 1e-10
FLOAT_SLACK_ABSOLUTE = 1e-12
_TWO_PI = 2.0 * math.pi


def sin_range(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact (min, max) of sin over [lo, hi] (elementwise, lo <= hi)."""
    top = np.ceil((lo - math.pi / 2) / _TWO_PI) * _TWO_PI + math.pi / 2 <= hi
    bottom = np.ceil((lo + math.pi / 2) / _TWO_PI) * _TWO_PI - math.pi / 2 <= hi
    s_lo, s_hi = np.sin(lo), np.sin(hi)
    return np.where(bottom, -1.0, np.minimum(s_lo, s_hi)), np.where(top, 1.0, np.maximum(s_lo, s_hi))


def sin_extremes(lo: float, hi: float) -> tuple[float, float]:
    """:func:`sin_range` of one interval in plain floats: (min, max) of sin over [lo, hi] (lo <= hi)."""
    top = math.ceil((lo - math.pi / 2) / (2 * math.pi)) * 2 * math.pi + math.pi / 2 <= hi
    bottom = math.ceil((lo + math.pi / 2) / (2 * math.pi)) * 2 * math.pi - math.pi / 2 <= hi
    ends = (math.sin(lo), math.sin(hi))
    return (-1.0 if bottom else min(ends), 1.0 if top else max(ends))


def scale(k, lo, hi):
    """k [lo, hi] for a scalar or array k."""
    a, b = k * lo, k * hi
    return np.minimum(a, b), np.maximum(a, b)


def mul(a_lo, a_hi, b_lo, b_hi):
    """[a] [b]: the extremes of the four corner products."""
    corners = np.stack(np.broadcast_arrays(a_lo * b_lo, a_lo * b_hi, a_hi * b_lo, a_hi * b_hi))
    return corners.min(0), corners.max(0)


def square(lo, hi):
    """[a]^2 (0 at the bottom when the interval holds 0)."""
    low = np.where((lo <= 0.0) & (hi >= 0.0), 0.0, np.minimum(lo * lo, hi * hi))
    return low, np.maximum(lo * lo, hi * hi)


def affine_trig(k0, kc, ks, c_lo, c_hi, s_lo, s_hi):
    """k0 + kc [cos] + ks [sin] as an interval."""
    a_lo, a_hi = scale(kc, c_lo, c_hi)
    b_lo, b_hi = scale(ks, s_lo, s_hi)
    return k0 + a_lo + b_lo, k0 + a_hi + b_hi


def widen(lo, hi):
    """[lo, hi] widened by :data:`FLOAT_SLACK_RELATIVE` of its magnitude plus :data:`FLOAT_SLACK_ABSOLUTE`."""
    slack = FLOAT_SLACK_RELATIVE * np.maximum(np.abs(lo), np.abs(hi)) + FLOAT_SLACK_ABSOLUTE
    return lo - slack, hi + slack


def magnitude(interval) -> np.ndarray:
    """The largest |value| of an interval."""
    return np.maximum(np.abs(interval[0]), np.abs(interval[1]))


def sinusoid_ranges(lower, upper, s_lo, s_hi):
    """Per joint i, the intervals of theta_i = A sin(w s + phi) + gamma and of its first three
    derivatives in s, over s in [s_lo, s_hi] (arrays, s_lo <= s_hi) and every parameter vector
    between ``lower`` and ``upper`` (the eight (A, w, phi, gamma) of the two joints; equal for one path).

    The phase interval is [w] [s] + [phi]; the ranges of sin and cos over it are exact, and the
    coefficients A w, A w^2, A w^3 are interval products (w^3 is monotone). For one path (lower =
    upper) every operation gives the same floats as the scalar expressions (corner products of
    degenerate intervals are the products themselves).

    Returns:
        ``[(theta, d1, d2, d3) for each joint]``, each an interval ``(lo, hi)``, not yet widened.
    """
    out = []
    for i in (0, 1):
        a_lo, w_lo, phi_lo, gamma_lo = lower[4 * i : 4 * i + 4]
        a_hi, w_hi, phi_hi, gamma_hi = upper[4 * i : 4 * i + 4]
        ph_lo, ph_hi = mul(w_lo, w_hi, s_lo, s_hi)
        ph_lo, ph_hi = ph_lo + phi_lo, ph_hi + phi_hi
        sin = sin_range(ph_lo, ph_hi)
        cos = sin_range(ph_lo + math.pi / 2, ph_hi + math.pi / 2)
        aw = mul(a_lo, a_hi, w_lo, w_hi)
        aw2 = mul(*aw, w_lo, w_hi)
        aw3 = mul(a_lo, a_hi, w_lo**3, w_hi**3)
        theta = mul(a_lo, a_hi, *sin)
        d2, d3 = mul(*aw2, *sin), mul(*aw3, *cos)
        out.append(((theta[0] + gamma_lo, theta[1] + gamma_hi), mul(*aw, *cos), (-d2[1], -d2[0]), (-d3[1], -d3[0])))
    return out
