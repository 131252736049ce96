"""Linear constraints on the path speed, with worst-case coefficients over each piece of the path.

A timing of the joint path ``theta(s)``, s in [0, T] (:mod:`pipeline.motion.timing`), is described
along the path by ``x(s) = sdot^2`` and ``u(s) = sddot`` (derivatives of s in executed time). The
executed motion is ``dq = theta'(s) sdot`` and ``ddq = theta''(s) x + theta'(s) u``, and the closed-form
dynamics (:class:`pipeline.model.dynamics.PlanarDynamics`) give

    tau_i = sum_j M_ij(q2) ddq_j + c_i,   c_1 = h (2 dq_1 dq_2 + dq_2^2),   c_2 = -h dq_1^2,

so ``tau_i = a_i(s) u + b_i(s) x`` with ``a_i = sum_j M_ij theta_j'`` and
``b_i = sum_j M_ij theta_j'' + h Q_i`` (Q_1 = 2 theta_1' theta_2' + theta_2'^2, Q_2 = -theta_1'^2):
every acceleration and torque is linear in (x, u), and every speed is ``|theta_i'| sqrt(x)``.

**Over a piece [s_k, s_k+1]** the coefficients are enclosed (:mod:`pipeline.motion.interval_arithmetic`):
theta', theta'', theta''' exactly over the phase interval of each sinusoid, M and h over the
piece's exact range of q2, the products and sums in interval arithmetic, each result widened for
rounding. A quantity ``a u + b x`` stays within [-L, L] for every a in [a], b in [b] when, with
x >= 0,

    a_hi u + b_hi x <= L,   a_lo u + b_hi x <= L,   -a_lo u - b_lo x <= L,   -a_hi u - b_lo x <= L

(the first two bound ``max(a_lo u, a_hi u) + b_hi x``, the largest value; the last two the smallest).
These four rows per limited quantity are the piece's constraints; the speed limits give
``x <= min_i (v_i / max |theta_i'|)^2``. A profile with constant u on the piece, so that x is
linear in s there, keeps every limit over the whole piece when the rows hold at both of its ends
(each row is linear in x): that is what :mod:`pipeline.motion.speed_profile` imposes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.compiled_intervals import mul as compiled_mul
from pipeline.motion.compiled_intervals import scale as compiled_scale
from pipeline.motion.compiled_intervals import sin_range as compiled_sin_range
from pipeline.motion.compiled_intervals import widen as compiled_widen
from pipeline.motion.interval_arithmetic import (
    MeanValueForm,
    affine_trig,
    magnitude,
    mul,
    scale,
    sin_range,
    sinusoid_ranges,
    square,
    widen,
)

__all__ = ["PathEnclosures", "PieceConstraints", "compiled_piece_constraints", "enclose_path", "piece_constraints"]

_HALF_PI = 0.5 * math.pi


@dataclass(frozen=True, eq=False)
class PathEnclosures:
    """Enclosures of the path's derivatives over each of n pieces (module docstring).

    Attributes:
        edges_s: The pieces' ends s_0 = 0 < ... < s_n = T on the path time [s], (n + 1,).
        d1, d2, d3: theta', theta'', theta''' as (lo, hi) pairs of (n, 2) arrays [rad/s, rad/s^2, rad/s^3].
        accel_u, accel_x: The intervals of a_i = theta_i' and b_i = theta_i'' ((lo, hi), each (n, 2)).
        torque_u, torque_x: The intervals of the torque's a_i and b_i [kg m^2 rad/s, kg m^2 rad/s^2].
    """

    edges_s: np.ndarray
    d1: tuple[np.ndarray, np.ndarray]
    d2: tuple[np.ndarray, np.ndarray]
    d3: tuple[np.ndarray, np.ndarray]
    accel_u: tuple[np.ndarray, np.ndarray]
    accel_x: tuple[np.ndarray, np.ndarray]
    torque_u: tuple[np.ndarray, np.ndarray]
    torque_x: tuple[np.ndarray, np.ndarray]


@dataclass(frozen=True, eq=False)
class PieceConstraints:
    """The rows ``cu u + cx x <= rhs`` of every piece and its speed cap (module docstring).

    Attributes:
        edges_s: (n + 1,) the pieces' ends on the path time [s].
        cu, cx, rhs: (n, m) the rows of each piece (m = 4 per finite acceleration or effort limit).
        speed_cap: (n,) the largest x = sdot^2 the speed limits allow on each piece (inf: none).
    """

    edges_s: np.ndarray
    cu: np.ndarray
    cx: np.ndarray
    rhs: np.ndarray
    speed_cap: np.ndarray


def _column(values: tuple[np.ndarray, np.ndarray], i: int) -> tuple[np.ndarray, np.ndarray]:
    return values[0][:, i], values[1][:, i]


def _add(*intervals):
    return sum(v[0] for v in intervals), sum(v[1] for v in intervals)


def enclose_path(
    parameters, edges_s: np.ndarray, dynamics: PlanarDynamics, mean_value: MeanValueForm | None = None
) -> PathEnclosures:
    """Enclose theta', theta'', theta''' and the torque coefficients over each piece of ``edges_s``.

    Args:
        parameters: The eight sinusoid parameters (A1, w1, phi1, gamma1, A2, w2, phi2, gamma2) of
            one path, or a pair (lower, upper) of them: every path of that box at once.
        edges_s: Increasing path times [s], (n + 1,).
        dynamics: The arm's closed-form dynamics.
        mean_value: For a box, its mean-value form (tighter enclosures:
            :func:`pipeline.motion.interval_arithmetic.sinusoid_ranges`).
    """
    if isinstance(parameters, tuple) and len(parameters) == 2:
        lower, upper = (np.asarray(p, dtype=float) for p in parameters)
    else:
        lower = upper = np.asarray(parameters, dtype=float)
    joints = sinusoid_ranges(lower, upper, edges_s[:-1], edges_s[1:], mean_value)
    pair = lambda k: (np.stack([j[k][0] for j in joints], 1), np.stack([j[k][1] for j in joints], 1))  # noqa: E731
    d1, d2, d3 = (widen(*pair(k)) for k in (1, 2, 3))
    q2 = widen(*joints[1][0])
    sin2, cos2 = sin_range(*q2), sin_range(q2[0] + math.pi / 2, q2[1] + math.pi / 2)
    m0, mc, ms = (np.asarray(m) for m in (dynamics.m0, dynamics.mc, dynamics.ms))
    mass = [[affine_trig(m0[i, j], mc[i, j], ms[i, j], *cos2, *sin2) for j in (0, 1)] for i in (0, 1)]
    h = affine_trig(0.0, 0.5 * ms[0, 0], -0.5 * mc[0, 0], *cos2, *sin2)
    v1, v2 = _column(d1, 0), _column(d1, 1)
    a1, a2 = _column(d2, 0), _column(d2, 1)
    quadratic = (_add(scale(2.0, *mul(*v1, *v2)), square(*v2)), scale(-1.0, *square(*v1)))
    torque_u, torque_x = [], []
    for i in (0, 1):
        torque_u.append(widen(*_add(mul(*mass[i][0], *v1), mul(*mass[i][1], *v2))))
        torque_x.append(widen(*_add(mul(*mass[i][0], *a1), mul(*mass[i][1], *a2), mul(*h, *quadratic[i]))))
    stack = lambda pairs: (np.stack([p[0] for p in pairs], 1), np.stack([p[1] for p in pairs], 1))  # noqa: E731
    return PathEnclosures(edges_s, d1, d2, d3, d1, d2, stack(torque_u), stack(torque_x))


def _rows(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray], limit: float):
    """The four rows (cu, cx, rhs) of |a u + b x| <= limit (module docstring), each (n, 4)."""
    cu = np.stack([a[1], a[0], -a[0], -a[1]], 1)
    cx = np.stack([b[1], b[1], -b[0], -b[0]], 1)
    return cu, cx, np.full_like(cu, limit)


def piece_constraints(
    enclosures: PathEnclosures, limits: ArmLimits, share: float = 1.0, speed_share: float | None = None
) -> PieceConstraints:
    """The rows and speed caps of every piece for ``limits``, the acceleration and effort limits
    scaled by ``share`` and the speed limits by ``speed_share`` (default ``share``), each in (0, 1].

    Raises:
        InvalidParameterError: no limit bounds the path's speed or acceleration (no fastest timing).
    """
    velocity = (share if speed_share is None else speed_share) * np.asarray(limits.velocity_rad_s)
    peak = magnitude(enclosures.d1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(peak > 0.0, velocity / peak, np.inf)
    cap = np.min(ratio, axis=1) ** 2
    parts = []
    for (a, b), bound in (
        ((enclosures.accel_u, enclosures.accel_x), limits.acceleration_rad_s2),
        ((enclosures.torque_u, enclosures.torque_x), limits.effort_n_m),
    ):
        for i in (0, 1):
            if math.isfinite(bound[i]):
                parts.append(_rows(_column(a, i), _column(b, i), share * bound[i]))
    if not parts and not np.all(np.isfinite(cap)):
        raise InvalidParameterError(
            "limits", limits, "a finite speed, acceleration or effort limit (else no timing is fastest)"
        )
    n = cap.size
    cu, cx, rhs = (np.concatenate([p[k] for p in parts], 1) if parts else np.zeros((n, 0)) for k in range(3))
    return PieceConstraints(enclosures.edges_s, cu, cx, rhs, cap)


@numba.njit(cache=True, nogil=True)
def _compiled_rows(p, edges, mass, bounds, share, speed_share, velocity):
    """The compiled twin of :func:`enclose_path` then :func:`piece_constraints` (same arithmetic)."""
    n = edges.size - 1
    finite = np.array([math.isfinite(b) for b in bounds])
    m = 4 * int(finite.sum())
    cu, cx, rhs = np.empty((n, m)), np.empty((n, m)), np.empty((n, m))
    cap = np.empty(n)
    peaks = np.empty((3, n, 2))  # max |theta'|, |theta''|, |theta'''| per piece and joint
    d1 = np.empty((2, 2))
    d2 = np.empty((2, 2))
    for k in range(n):
        sin2_lo, sin2_hi = 0.0, 0.0
        for i in range(2):
            amplitude, w, phi = p[4 * i], p[4 * i + 1], p[4 * i + 2]
            ph_a, ph_b = w * edges[k] + phi, w * edges[k + 1] + phi
            ph_lo, ph_hi = min(ph_a, ph_b), max(ph_a, ph_b)
            s_lo, s_hi = compiled_sin_range(ph_lo, ph_hi)
            c_lo, c_hi = compiled_sin_range(ph_lo + _HALF_PI, ph_hi + _HALF_PI)
            d1[i, 0], d1[i, 1] = compiled_widen(*compiled_scale(amplitude * w, c_lo, c_hi))
            d2[i, 0], d2[i, 1] = compiled_widen(*compiled_scale(-amplitude * w * w, s_lo, s_hi))
            third = compiled_widen(*compiled_scale(-amplitude * w**3, c_lo, c_hi))
            peaks[0, k, i] = max(abs(d1[i, 0]), abs(d1[i, 1]))
            peaks[1, k, i] = max(abs(d2[i, 0]), abs(d2[i, 1]))
            peaks[2, k, i] = max(abs(third[0]), abs(third[1]))
            if i == 1:
                sin2_lo, sin2_hi = s_lo, s_hi
        q_lo, q_hi = compiled_scale(p[4], sin2_lo, sin2_hi)
        q_lo, q_hi = compiled_widen(q_lo + p[7], q_hi + p[7])
        sn = compiled_sin_range(q_lo, q_hi)
        cs = compiled_sin_range(q_lo + _HALF_PI, q_hi + _HALF_PI)
        ratio = np.inf
        for i in range(2):
            if peaks[0, k, i] > 0.0:
                ratio = min(ratio, speed_share * velocity[i] / peaks[0, k, i])
        cap[k] = ratio**2
        cross = compiled_mul(d1[0, 0], d1[0, 1], d1[1, 0], d1[1, 1])
        sq2_lo = 0.0 if (d1[1, 0] <= 0.0 and d1[1, 1] >= 0.0) else min(d1[1, 0] ** 2, d1[1, 1] ** 2)
        sq1_lo = 0.0 if (d1[0, 0] <= 0.0 and d1[0, 1] >= 0.0) else min(d1[0, 0] ** 2, d1[0, 1] ** 2)
        sq2_hi, sq1_hi = max(d1[1, 0] ** 2, d1[1, 1] ** 2), max(d1[0, 0] ** 2, d1[0, 1] ** 2)
        quad = ((2.0 * cross[0] + sq2_lo, 2.0 * cross[1] + sq2_hi), (-sq1_hi, -sq1_lo))
        h_lo = 0.0 + min(0.5 * mass[2, 0, 0] * cs[0], 0.5 * mass[2, 0, 0] * cs[1])
        h_lo += min(-0.5 * mass[1, 0, 0] * sn[0], -0.5 * mass[1, 0, 0] * sn[1])
        h_hi = 0.0 + max(0.5 * mass[2, 0, 0] * cs[0], 0.5 * mass[2, 0, 0] * cs[1])
        h_hi += max(-0.5 * mass[1, 0, 0] * sn[0], -0.5 * mass[1, 0, 0] * sn[1])
        column = 0
        for kind in range(2):  # acceleration, then effort
            for i in range(2):
                if not finite[2 * kind + i]:
                    continue
                if kind == 0:
                    a_lo, a_hi, b_lo, b_hi = d1[i, 0], d1[i, 1], d2[i, 0], d2[i, 1]
                else:
                    a_lo, a_hi, b_lo, b_hi = 0.0, 0.0, 0.0, 0.0
                    for j in range(2):
                        mj = compiled_scale(mass[1, i, j], cs[0], cs[1])
                        ms = compiled_scale(mass[2, i, j], sn[0], sn[1])
                        m_lo, m_hi = mass[0, i, j] + mj[0] + ms[0], mass[0, i, j] + mj[1] + ms[1]
                        u_part = compiled_mul(m_lo, m_hi, d1[j, 0], d1[j, 1])
                        x_part = compiled_mul(m_lo, m_hi, d2[j, 0], d2[j, 1])
                        a_lo, a_hi = a_lo + u_part[0], a_hi + u_part[1]
                        b_lo, b_hi = b_lo + x_part[0], b_hi + x_part[1]
                    c_part = compiled_mul(h_lo, h_hi, quad[i][0], quad[i][1])
                    a_lo, a_hi = compiled_widen(a_lo, a_hi)
                    b_lo, b_hi = compiled_widen(b_lo + c_part[0], b_hi + c_part[1])
                limit = share * bounds[2 * kind + i]
                cu[k, column : column + 4] = (a_hi, a_lo, -a_lo, -a_hi)
                cx[k, column : column + 4] = (b_hi, b_hi, -b_lo, -b_lo)
                rhs[k, column : column + 4] = limit
                column += 4
    return cu, cx, rhs, cap, peaks


def compiled_piece_constraints(
    parameters, edges_s: np.ndarray, dynamics: PlanarDynamics, limits: ArmLimits, share: float, speed_share: float
) -> tuple[PieceConstraints, np.ndarray]:
    """:func:`enclose_path` then :func:`piece_constraints`, compiled (the same arithmetic in scalar
    loops; tests prove the two equal). Also returns the peaks (3, n, 2): the largest |theta'|,
    |theta''|, |theta'''| of each piece and joint."""
    velocity = np.asarray(limits.velocity_rad_s, dtype=float)
    bounds = np.array([*limits.acceleration_rad_s2, *limits.effort_n_m], dtype=float)
    if not np.any(np.isfinite(bounds)) and not np.all(np.isfinite(velocity)):
        raise InvalidParameterError(
            "limits", limits, "a finite speed, acceleration or effort limit (else no timing is fastest)"
        )
    mass = np.array([dynamics.m0, dynamics.mc, dynamics.ms], dtype=float)
    edges = np.ascontiguousarray(edges_s, dtype=float)
    cu, cx, rhs, cap, peaks = _compiled_rows(
        np.asarray(parameters, dtype=float), edges, mass, bounds, float(share), float(speed_share), velocity
    )
    return PieceConstraints(edges, cu, cx, rhs, cap), peaks
