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
from dataclasses import dataclass

import numpy as np

__all__ = [
    "FLOAT_SLACK_ABSOLUTE",
    "FLOAT_SLACK_RELATIVE",
    "MeanValueForm",
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
    p1, p2, p3, p4 = a_lo * b_lo, a_lo * b_hi, a_hi * b_lo, a_hi * b_hi
    return np.minimum(np.minimum(p1, p2), np.minimum(p3, p4)), np.maximum(np.maximum(p1, p2), np.maximum(p3, p4))


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


def sinusoid_ranges(lower, upper, s_lo, s_hi, mean_value: MeanValueForm | None = None):
    """Per joint i, the intervals of theta_i = A sin(w s + phi) + gamma and of its first three
    derivatives in s, over s in [s_lo, s_hi] (arrays, s_lo <= s_hi) and every parameter vector
    between ``lower`` and ``upper`` (the eight (A, w, phi, gamma) of the two joints; equal for one path).

    The phase interval is [w] [s] + [phi]; the ranges of sin and cos over it are exact, and the
    coefficients A w, A w^2, A w^3 are interval products (w^3 is monotone). For one path (lower =
    upper) every operation gives the same floats as the scalar expressions (corner products of
    degenerate intervals are the products themselves).

    With ``mean_value`` (a box of obstacles whose parameters are functions of its variables),
    each enclosure is also taken in the mean-value form (:class:`MeanValueForm`) and the two are
    intersected: the naive one loses the correlation between A, w and phi across the box, the
    mean-value form keeps it to first order.

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
        naive = ((theta[0] + gamma_lo, theta[1] + gamma_hi), mul(*aw, *cos), (-d2[1], -d2[0]), (-d3[1], -d3[0]))
        if mean_value is not None:
            form = _mean_value_joint(i, lower, upper, mean_value, s_lo, s_hi, sin, cos)
            naive = tuple((np.maximum(n[0], f[0]), np.minimum(n[1], f[1])) for n, f in zip(naive, form, strict=True))
        out.append(naive)
    return out


@dataclass(frozen=True, eq=False)
class MeanValueForm:
    """What the mean-value form of the sinusoids over a box of obstacles needs (:func:`sinusoid_ranges`).

    The eight parameters p(v) are functions of the box's variables v in c +- r. For every v of the
    box, ``f(s, p(v)) = f(s, p(c)) + sum_j df/dv_j (s, p(xi)) (v_j - c_j)`` for some xi of the box
    (the mean value theorem on the segment from c to v), so f lies in
    ``f(s, [p(c)]) + sum_j [df/dv_j] [-r_j, r_j]`` with ``df/dv_j`` enclosed over the box.

    Attributes:
        point_lower, point_upper: (8,) an enclosure of p(c), the parameters at the box's centre.
        gradient_lower, gradient_upper: (8, k) enclosures of dp/dv_j over the box.
        radius: (k,) the box's half widths r_j.
    """

    point_lower: np.ndarray
    point_upper: np.ndarray
    gradient_lower: np.ndarray
    gradient_upper: np.ndarray
    radius: np.ndarray


def _mean_value_joint(i, box_lower, box_upper, form: MeanValueForm, s_lo, s_hi, sin, cos):
    """Per derivative order 0..3 of joint i, the mean-value enclosure (:class:`MeanValueForm`): the
    centre's range plus the gradients' spread (its rounding, a few ulps of terms of the result's
    size, is covered by the slack the callers widen every enclosure by)."""
    a, w = (box_lower[4 * i], box_upper[4 * i]), (box_lower[4 * i + 1], box_upper[4 * i + 1])
    centre = sinusoid_ranges(form.point_lower, form.point_upper, s_lo, s_hi)[i]
    spread = [0.0, 0.0, 0.0, 0.0]
    w2 = square(*w)
    aw, aw2 = mul(*a, *w), mul(*mul(*a, *w), *w)
    minus_sin = (-sin[1], -sin[0])
    for j, r in enumerate(form.radius):
        da, dw, dphi, dgamma = (
            (form.gradient_lower[4 * i + q, j], form.gradient_upper[4 * i + q, j]) for q in range(4)
        )
        phase = mul(*dw, s_lo, s_hi)
        phase = (phase[0] + dphi[0], phase[1] + dphi[1])
        dk = (
            da,
            _add2(mul(*da, *w), mul(*a, *dw)),
            _add2(mul(*da, *w2), scale(2.0, *mul(*aw, *dw))),
            _add2(mul(*da, *mul(*w2, *w)), scale(3.0, *mul(*aw2, *dw))),
        )
        k = ((a[0], a[1]), aw, aw2, mul(*aw2, *w))
        trig = (sin, cos, sin, cos)
        dtrig = (cos, minus_sin, cos, minus_sin)
        for m in range(4):
            d = _add2(mul(*dk[m], *trig[m]), mul(*mul(*k[m], *dtrig[m]), *phase))
            if m == 0:
                d = _add2(d, dgamma)
            spread[m] = spread[m] + magnitude(d) * r
    return [(centre[m][0] - spread[m], centre[m][1] + spread[m]) for m in range(4)]


def _add2(x, y):
    return x[0] + y[0], x[1] + y[1]
