"""The execution certificate of a smooth timing, compiled: the same bounds in a fraction of the time.

:func:`pipeline.motion.execution_certificate.certify_execution` is the readable route: NumPy
arrays of intervals, one expression per enclosure. For a
:class:`pipeline.motion.smooth_timing.SmoothTiming` (hundreds of pieces) most of its time goes to
NumPy's per-call overhead, so this module runs the same algorithm as scalar loops compiled with
Numba: the same initial partition (the timing's pieces), the same enclosures in the same interval
arithmetic (:mod:`pipeline.motion.interval_arithmetic`, widened by the same slack), the same
samples, the same rule for which intervals to bisect, round after round. Only the order of the
floating-point operations differs (and Numba's sin and cos may differ from NumPy's in the last
unit), so its bounds equal the readable route's to rounding; ``tests/motion/test_certificate_kernel.py``
checks that on random paths and timings, and :func:`certify_smooth_execution` is what
:func:`pipeline.motion.execution_certificate.certify_execution` calls for a smooth timing.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from pipeline.motion.compiled_intervals import affine_trig as _affine_trig
from pipeline.motion.compiled_intervals import mul as _mul
from pipeline.motion.compiled_intervals import scale as _scale
from pipeline.motion.compiled_intervals import sin_range as _sin_range
from pipeline.motion.compiled_intervals import square as _square
from pipeline.motion.compiled_intervals import widen as _widen

__all__ = ["certify_smooth_execution"]

_HALF_PI = 0.5 * math.pi
_QUANTITIES = 12


@numba.njit(cache=True, nogil=True)
def _timing_ranges(start, jerk, j, a, b):
    """Ranges of sigma, sigma', sigma'', sigma''' over local [a, b] of segment j (as SmoothTiming)."""
    c0, c1, c2, k = start[j, 0], start[j, 1], start[j, 2], jerk[j]
    d2a, d2b = c2 + a * k, c2 + b * k
    vertex = -c2 / k if k != 0.0 else a
    v = min(max(vertex, a), b)
    s1a, s1b, s1v = c1 + a * (c2 + a * k / 2.0), c1 + b * (c2 + b * k / 2.0), c1 + v * (c2 + v * k / 2.0)
    s_lo = min(c0 + a * (c1 + a * (c2 / 2.0 + a * k / 6.0)), c0 + b * (c1 + b * (c2 / 2.0 + b * k / 6.0)))
    s_hi = max(c0 + a * (c1 + a * (c2 / 2.0 + a * k / 6.0)), c0 + b * (c1 + b * (c2 / 2.0 + b * k / 6.0)))
    disc = c2 * c2 - 2.0 * k * c1
    root = math.sqrt(max(disc, 0.0))
    for sign in (-1.0, 1.0):
        if k != 0.0:
            r = (-c2 + sign * root) / k
        elif c2 != 0.0:
            r = -c1 / c2
        else:
            r = a
        r = min(max(r, a), b)
        value = c0 + r * (c1 + r * (c2 / 2.0 + r * k / 6.0))
        s_lo, s_hi = min(s_lo, value), max(s_hi, value)
    d1_lo, d1_hi = min(min(s1a, s1b), s1v), max(max(s1a, s1b), s1v)
    return s_lo, s_hi, d1_lo, d1_hi, min(d2a, d2b), max(d2a, d2b), k, k


@numba.njit(cache=True, nogil=True)
def _upper(p, start, jerk, knots, path_duration, mass, lo, hi, j, out, scratch):
    """Upper bounds of the 12 quantities over [lo, hi] in segment j, into ``out`` (``scratch``:
    (3, 2, 2) work space for the joints' angle, speed and acceleration intervals)."""
    s_lo, s_hi, d1_lo, d1_hi, d2_lo, d2_hi, d3_lo, d3_hi = _timing_ranges(start, jerk, j, lo - knots[j], hi - knots[j])
    if hi >= knots[-1]:  # at T' itself: exactly at rest at T (as SmoothTiming.ranges_with_jerk)
        s_lo, s_hi = min(s_lo, path_duration), max(s_hi, path_duration)
        d1_lo, d1_hi, d2_lo, d2_hi = min(d1_lo, 0.0), max(d1_hi, 0.0), min(d2_lo, 0.0), max(d2_hi, 0.0)
        d3_lo, d3_hi = min(d3_lo, 0.0), max(d3_hi, 0.0)
    sq_lo, sq_hi = _square(d1_lo, d1_hi)
    cube_lo, cube_hi = _mul(sq_lo, sq_hi, d1_lo, d1_hi)
    dd_lo, dd_hi = _mul(d1_lo, d1_hi, d2_lo, d2_hi)
    th, sp, ac = scratch[0], scratch[1], scratch[2]
    for i in range(2):
        amplitude, w, phi, gamma = p[4 * i], p[4 * i + 1], p[4 * i + 2], p[4 * i + 3]
        ph_a, ph_b = w * s_lo + phi, w * s_hi + phi
        ph_lo, ph_hi = min(ph_a, ph_b), max(ph_a, ph_b)
        sin_lo, sin_hi = _sin_range(ph_lo, ph_hi)
        cos_lo, cos_hi = _sin_range(ph_lo + _HALF_PI, ph_hi + _HALF_PI)
        t_lo, t_hi = _scale(amplitude, sin_lo, sin_hi)
        th[i, 0], th[i, 1] = _widen(t_lo + gamma, t_hi + gamma)
        v_lo, v_hi = _scale(amplitude * w, cos_lo, cos_hi)
        a_lo, a_hi = _scale(-amplitude * w * w, sin_lo, sin_hi)
        j_lo, j_hi = _scale(-amplitude * w**3, cos_lo, cos_hi)
        sp[i, 0], sp[i, 1] = _widen(*_mul(v_lo, v_hi, d1_lo, d1_hi))
        f_lo, f_hi = _mul(a_lo, a_hi, sq_lo, sq_hi)
        g_lo, g_hi = _mul(v_lo, v_hi, d2_lo, d2_hi)
        ac[i, 0], ac[i, 1] = _widen(f_lo + g_lo, f_hi + g_hi)
        x_lo, x_hi = _mul(j_lo, j_hi, cube_lo, cube_hi)
        y_lo, y_hi = _scale(3.0, *_mul(a_lo, a_hi, dd_lo, dd_hi))
        z_lo, z_hi = _mul(v_lo, v_hi, d3_lo, d3_hi)
        jl, jh = _widen(x_lo + y_lo + z_lo, x_hi + y_hi + z_hi)
        out[10 + i] = max(abs(jl), abs(jh))
    sin2 = _sin_range(th[1, 0], th[1, 1])
    cos2 = _sin_range(th[1, 0] + _HALF_PI, th[1, 1] + _HALF_PI)
    m11 = _affine_trig(mass[0, 0, 0], mass[1, 0, 0], mass[2, 0, 0], cos2[0], cos2[1], sin2[0], sin2[1])
    m12 = _affine_trig(mass[0, 0, 1], mass[1, 0, 1], mass[2, 0, 1], cos2[0], cos2[1], sin2[0], sin2[1])
    m22 = _affine_trig(mass[0, 1, 1], mass[1, 1, 1], mass[2, 1, 1], cos2[0], cos2[1], sin2[0], sin2[1])
    h = _affine_trig(0.0, 0.5 * mass[2, 0, 0], -0.5 * mass[1, 0, 0], cos2[0], cos2[1], sin2[0], sin2[1])
    cross = _mul(sp[0, 0], sp[0, 1], sp[1, 0], sp[1, 1])
    dq2_sq, dq1_sq = _square(sp[1, 0], sp[1, 1]), _square(sp[0, 0], sp[0, 1])
    q1_lo, q1_hi = 2.0 * cross[0] + dq2_sq[0], 2.0 * cross[1] + dq2_sq[1]
    p1, p2, p3 = _mul(*m11, ac[0, 0], ac[0, 1]), _mul(*m12, ac[1, 0], ac[1, 1]), _mul(h[0], h[1], q1_lo, q1_hi)
    t1 = _widen(p1[0] + p2[0] + p3[0], p1[1] + p2[1] + p3[1])
    r1, r2, r3 = _mul(*m12, ac[0, 0], ac[0, 1]), _mul(*m22, ac[1, 0], ac[1, 1]), _mul(-h[1], -h[0], *dq1_sq)
    t2 = _widen(r1[0] + r2[0] + r3[0], r1[1] + r2[1] + r3[1])
    out[0], out[1], out[2], out[3] = th[0, 1], th[1, 1], -th[0, 0], -th[1, 0]
    for i in range(2):
        out[4 + i] = max(abs(sp[i, 0]), abs(sp[i, 1]))
        out[6 + i] = max(abs(ac[i, 0]), abs(ac[i, 1]))
    out[8], out[9] = max(abs(t1[0]), abs(t1[1])), max(abs(t2[0]), abs(t2[1]))


@numba.njit(cache=True, nogil=True)
def _values(p, start, jerk, knots, path_duration, mass, t, out, scratch):
    """The 12 quantities at time t (as TimedTrajectory with a SmoothTiming), maxima into ``out``
    (``scratch``: (3, 2) work space for q, dq, ddq)."""
    end = knots[-1]
    t = min(max(t, 0.0), end)
    if t >= end:
        s, d1, d2, d3 = path_duration, 0.0, 0.0, 0.0
    else:
        j = min(max(np.searchsorted(knots, t, side="right") - 1, 0), jerk.size - 1)
        h = t - knots[j]
        c0, c1, c2, k = start[j, 0], start[j, 1], start[j, 2], jerk[j]
        s = c0 + h * (c1 + h * (c2 / 2.0 + h * k / 6.0))
        d1, d2, d3 = c1 + h * (c2 + h * k / 2.0), c2 + h * k, k
    s = min(max(s, 0.0), path_duration)
    q, dq, ddq = scratch[0], scratch[1], scratch[2]
    for i in range(2):
        amplitude, w, phi, gamma = p[4 * i], p[4 * i + 1], p[4 * i + 2], p[4 * i + 3]
        sine, cosine = math.sin(w * s + phi), math.cos(w * s + phi)
        v, a, third = amplitude * w * cosine, -(amplitude * w * w) * sine, -(amplitude * w**3) * cosine
        q[i] = amplitude * sine + gamma
        dq[i] = v * d1
        ddq[i] = a * d1 * d1 + v * d2
        out[10 + i] = max(out[10 + i], abs(third * d1**3 + 3.0 * a * d1 * d2 + v * d3))
    c, sn = math.cos(q[1]), math.sin(q[1])
    m11 = mass[0, 0, 0] + mass[1, 0, 0] * c + mass[2, 0, 0] * sn
    m12 = mass[0, 0, 1] + mass[1, 0, 1] * c + mass[2, 0, 1] * sn
    m22 = mass[0, 1, 1] + mass[1, 1, 1] * c + mass[2, 1, 1] * sn
    hc = 0.5 * (-mass[1, 0, 0] * sn + mass[2, 0, 0] * c)
    tau1 = m11 * ddq[0] + m12 * ddq[1] + hc * (2.0 * dq[0] * dq[1] + dq[1] ** 2)
    tau2 = m12 * ddq[0] + m22 * ddq[1] - hc * dq[0] ** 2
    values = (q[0], q[1], -q[0], -q[1], abs(dq[0]), abs(dq[1]), abs(ddq[0]), abs(ddq[1]), abs(tau1), abs(tau2))
    for m in range(10):
        out[m] = max(out[m], values[m])


@numba.njit(cache=True, nogil=True)
def _certify(p, start, jerk, knots, path_duration, mass, limit, decide, tolerance, max_intervals, max_rounds):
    m = jerk.size
    lo, hi, seg = knots[:-1].copy(), knots[1:].copy(), np.arange(m)
    sampled = np.full(_QUANTITIES, -np.inf)
    point, box = np.empty((3, 2)), np.empty((3, 2, 2))
    for t in knots:
        _values(p, start, jerk, knots, path_duration, mass, t, sampled, point)
    bound = np.full(_QUANTITIES, -np.inf)
    upper = np.empty(_QUANTITIES)
    total = 0
    for _ in range(max_rounds + 1):
        n = lo.size
        is_open = np.zeros(n, dtype=np.bool_)
        uppers = np.empty((n, _QUANTITIES))
        for k in range(n):
            _upper(p, start, jerk, knots, path_duration, mass, lo[k], hi[k], seg[k], upper, box)
            uppers[k] = upper
            for q in range(_QUANTITIES):
                loose = upper[q] > sampled[q] + tolerance * max(abs(sampled[q]), 1e-3)
                if decide:
                    loose = loose and upper[q] > limit[q] and sampled[q] <= limit[q]
                if loose:
                    is_open[k] = True
                    break
        opened = int(is_open.sum())
        for k in range(n):
            if not is_open[k]:
                for q in range(_QUANTITIES):
                    bound[q] = max(bound[q], uppers[k, q])
        total += n - opened
        if opened == 0 or 2 * opened + total > max_intervals or _ == max_rounds:
            for k in range(n):
                if is_open[k]:
                    for q in range(_QUANTITIES):
                        bound[q] = max(bound[q], uppers[k, q])
            total += opened
            break
        new_lo, new_hi, new_seg = np.empty(2 * opened), np.empty(2 * opened), np.empty(2 * opened, dtype=np.int64)
        r = 0
        for k in range(n):
            if is_open[k]:
                mid = 0.5 * (lo[k] + hi[k])
                _values(p, start, jerk, knots, path_duration, mass, mid, sampled, point)
                new_lo[r], new_hi[r], new_seg[r] = lo[k], mid, seg[k]
                new_lo[opened + r], new_hi[opened + r], new_seg[opened + r] = mid, hi[k], seg[k]
                r += 1
        lo, hi, seg = new_lo, new_hi, new_seg
    return bound, sampled, total


def certify_smooth_execution(
    parameters,
    timing,
    mass_terms: np.ndarray,
    limit: np.ndarray | None,
    relative_tolerance: float,
    max_intervals: int,
    max_rounds: int,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Bounds and sampled maxima of the 12 certified quantities of a path with a smooth timing
    (module docstring), in the column order of the readable route, and the final partition's size.

    Args:
        parameters: The eight sinusoid parameters.
        timing: A :class:`pipeline.motion.smooth_timing.SmoothTiming`.
        mass_terms: (3, 2, 2) the dynamics' m0, mc, ms.
        limit: (12,) the limits in the certificate's column order, or None for tight bounds.
        relative_tolerance, max_intervals, max_rounds: As the readable route.
    """
    decide = limit is not None
    return _certify(
        np.asarray(parameters, dtype=float),
        np.ascontiguousarray(timing.start, dtype=float),
        np.ascontiguousarray(timing.jerk, dtype=float),
        np.ascontiguousarray(timing.breakpoints_s, dtype=float),
        float(timing.path_duration_s),
        np.ascontiguousarray(mass_terms, dtype=float),
        np.zeros(_QUANTITIES) if limit is None else np.asarray(limit, dtype=float),
        decide,
        float(relative_tolerance),
        int(max_intervals),
        int(max_rounds),
    )
