"""Interval arithmetic on single intervals, compiled with Numba, for the compiled routes.

The same operations as :mod:`pipeline.motion.interval_arithmetic` (which works on NumPy arrays of
intervals), on one interval ``(lo, hi)`` of floats at a time, for use inside Numba-compiled loops
(:mod:`pipeline.motion.certificate_kernel`, :func:`pipeline.motion.path_constraints.compiled_piece_constraints`).
The arithmetic is the same operation for operation, so their results equal the array routes'
(Numba's sin may differ from NumPy's in the last unit, which the widening covers).
"""

from __future__ import annotations

import math

import numba

from pipeline.motion.interval_arithmetic import FLOAT_SLACK_ABSOLUTE, FLOAT_SLACK_RELATIVE

__all__ = ["HALF_PI", "affine_trig", "mul", "scale", "sin_range", "square", "widen"]

HALF_PI = 0.5 * math.pi
_TWO_PI = 2.0 * math.pi


@numba.njit(cache=True, nogil=True)
def sin_range(lo, hi):
    """Exact (min, max) of sin over [lo, hi]."""
    top = math.ceil((lo - HALF_PI) / _TWO_PI) * _TWO_PI + HALF_PI <= hi
    bottom = math.ceil((lo + HALF_PI) / _TWO_PI) * _TWO_PI - HALF_PI <= hi
    a, b = math.sin(lo), math.sin(hi)
    return (-1.0 if bottom else min(a, b)), (1.0 if top else max(a, b))


@numba.njit(cache=True, nogil=True)
def scale(k, lo, hi):
    """k [lo, hi]."""
    a, b = k * lo, k * hi
    return min(a, b), max(a, b)


@numba.njit(cache=True, nogil=True)
def mul(a_lo, a_hi, b_lo, b_hi):
    """[a] [b]: the extremes of the four corner products."""
    p, q, r, s = a_lo * b_lo, a_lo * b_hi, a_hi * b_lo, a_hi * b_hi
    return min(min(p, q), min(r, s)), max(max(p, q), max(r, s))


@numba.njit(cache=True, nogil=True)
def square(lo, hi):
    """[a]^2 (0 at the bottom when the interval holds 0)."""
    low = 0.0 if (lo <= 0.0 and hi >= 0.0) else min(lo * lo, hi * hi)
    return low, max(lo * lo, hi * hi)


@numba.njit(cache=True, nogil=True)
def widen(lo, hi):
    """[lo, hi] widened for rounding, as :func:`pipeline.motion.interval_arithmetic.widen`."""
    slack = FLOAT_SLACK_RELATIVE * max(abs(lo), abs(hi)) + FLOAT_SLACK_ABSOLUTE
    return lo - slack, hi + slack


@numba.njit(cache=True, nogil=True)
def affine_trig(k0, kc, ks, c_lo, c_hi, s_lo, s_hi):
    """k0 + kc [cos] + ks [sin]."""
    a_lo, a_hi = scale(kc, c_lo, c_hi)
    b_lo, b_hi = scale(ks, s_lo, s_hi)
    return k0 + a_lo + b_lo, k0 + a_hi + b_hi
