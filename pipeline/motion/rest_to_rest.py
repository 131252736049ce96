"""The shortest rest-to-rest timing of a joint path within the arm's limits, from closed-form bounds.

With the paper timing's maxima ``V_i = max |theta_i'|`` and ``Acc_i = max |theta_i''|`` over
the path, exact in closed form for a sinusoid over [0, T]
(:meth:`pipeline.motion.trajectory.JointTrajectory.peak_velocity_rad_s`, widened for rounding as
the execution certificate's bounds), a :class:`pipeline.motion.timing.RestToRestTiming` with
speed scale c and ramp r has, at every instant (sigma' <= c, |sigma''| <= 1.5 c / r):

* ``|dq_i| <= c V_i``;
* ``|ddq_i| <= c^2 Acc_i + 1.5 c V_i / r``;
* ``|tau_i| <= sum_j Mmax_ij (c^2 Acc_j + 1.5 c V_j / r) + Hmax c^2 Q_i`` with Mmax, Hmax the
  suprema over q2 of |M_ij| and |h| (:class:`pipeline.model.dynamics.PlanarDynamics`, exact),
  Q_1 = 2 V_1 V_2 + V_2^2 and Q_2 = V_1^2.

Each bound is below its limit (shrunk by :data:`LIMIT_SHARE`, so that the certificate's own,
tighter bound within its tolerance stays below the limit) for every c up to the speed cap
``min(1, v_i / V_i)`` and every r above ``r_min(c)``, the largest of
``1.5 c K / (limit - c^2 G)`` over the acceleration and torque constraints (K, G their
coefficients above); a c where some ``limit <= c^2 G`` is infeasible. ``T'(c) = T / c + r_min(c)``
is then evaluated on :data:`SPEED_SCALES` values of c, geometrically spaced below the cap (one
NumPy expression), and the smallest T' taken: the shortest duration these bounds allow, to the
grid's 2 % in c. The result is certified afterwards like any timing.

:func:`rest_to_rest_scales` is the canonical route (NumPy, many paths at once);
:func:`shortest_rest_to_rest`, for one path, runs the same grid search compiled
(:func:`_shortest_on_grid`, the same operations in the same order on the same grid, tested equal to
the canonical route), its inputs from the path's peaks computed once per trajectory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.execution_certificate import FLOAT_SLACK_ABSOLUTE, FLOAT_SLACK_RELATIVE
from pipeline.motion.timing import RestToRestTiming
from pipeline.motion.trajectory import JointTrajectory

__all__ = ["REST_TO_REST", "ShortestRestToRest", "rest_to_rest_bounds", "rest_to_rest_scales", "shortest_rest_to_rest"]

#: Share of each limit the closed-form bounds may use.
LIMIT_SHARE = 0.999
#: Speed scales tried, from the cap down to 1/1000 of it.
SPEED_SCALES = 360
#: Shortest ramp [s] (when no acceleration or torque limit binds).
MIN_RAMP_S = 1e-3
#: The speed scales tried, relative to the cap: from 1 down to 1/1000, geometrically spaced.
_SCALE_GRID = np.geomspace(1.0, 1e-3, SPEED_SCALES)
_SCALE_GRID.flags.writeable = False


@dataclass(frozen=True)
class ShortestRestToRest:
    """Ask for the shortest :class:`pipeline.motion.timing.RestToRestTiming` within the arm's limits."""

    name: str = "rest-to-rest"


#: The shortest rest-to-rest timing within the limits (``generate_certified(..., timing=REST_TO_REST)``).
REST_TO_REST = ShortestRestToRest()


def _widened(values: np.ndarray) -> np.ndarray:
    return values + FLOAT_SLACK_RELATIVE * np.abs(values) + FLOAT_SLACK_ABSOLUTE


def rest_to_rest_scales(
    path_duration_s: np.ndarray,
    peak_velocity_rad_s: np.ndarray,
    peak_acceleration_rad_s2: np.ndarray,
    dynamics: PlanarDynamics,
    limits: ArmLimits,
    torque_terms: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The speed scale c and ramp r [s] of the shortest rest-to-rest timing that the closed-form
    bounds (module docstring) keep within ``limits``, for n paths at once.

    The bounds hold for every path whose duration is at least ``path_duration_s`` (the ramps fit:
    r <= T / c) and whose peaks are at most the given ones, so a cell of the region map can
    give its own (c, r) to every obstacle it holds.

    Args:
        path_duration_s: T [s] (a lower bound for a set of paths), (n,).
        peak_velocity_rad_s, peak_acceleration_rad_s2: Upper bounds of |theta_i'| and
            |theta_i''| over the path(s), widened for rounding, (n, 2).
        dynamics: The arm's inverse dynamics.
        limits: The limits to keep.
        torque_terms: (G, K), each (n, 2): bounds with |tau_i| <= c^2 G_i + 1.5 c K_i / r
            (:mod:`pipeline.certify.execution_range`); None: from the peaks and the suprema of
            |M| and |h| (module docstring).

    Returns:
        (c, r), each (n,); NaN where no timing keeps the limits (a limit that binds at rest).
    """
    T = np.asarray(path_duration_s, dtype=float).reshape(-1)
    V = np.asarray(peak_velocity_rad_s, dtype=float).reshape(-1, 2)
    acc = np.asarray(peak_acceleration_rad_s2, dtype=float).reshape(-1, 2)
    share = LIMIT_SHARE
    velocity = share * np.asarray(limits.velocity_rad_s)
    with np.errstate(divide="ignore"):
        cap = np.minimum(1.0, np.min(np.where(V > 0.0, velocity / V, np.inf), axis=1))
    c = cap[:, None] * _SCALE_GRID[None, :]  # (n, S)
    mass = dynamics.mass_matrix_sup()
    h = dynamics.coriolis_sup()
    # Constraints limit >= c^2 G + 1.5 c K / r: two for acceleration, two for torque.
    if torque_terms is None:
        quadratic = np.stack([2 * V[:, 0] * V[:, 1] + V[:, 1] ** 2, V[:, 0] ** 2], -1)
        torque_terms = (acc @ mass.T + h * quadratic, V @ mass.T)
    G = np.concatenate([acc, np.asarray(torque_terms[0], dtype=float).reshape(-1, 2)], 1)  # (n, 4)
    K = np.concatenate([V, np.asarray(torque_terms[1], dtype=float).reshape(-1, 2)], 1)
    bound = share * np.concatenate([np.asarray(limits.acceleration_rad_s2), np.asarray(limits.effort_n_m)])
    unlimited = np.isinf(bound)
    room = bound[None, None, :] - (c * c)[:, :, None] * G[:, None, :]  # (n, S, 4)
    with np.errstate(divide="ignore", invalid="ignore"):
        needed = np.where(unlimited, 0.0, 1.5 * c[:, :, None] * K[:, None, :] / room)
    feasible = np.all((room > 0.0) | unlimited, axis=2)
    ramp = np.maximum(np.where(feasible, needed.max(2), np.inf), MIN_RAMP_S)
    fits = ramp <= T[:, None] / c
    total = np.where(feasible & fits, T[:, None] / c + ramp, np.inf)
    best = np.argmin(total, axis=1)
    rows = np.arange(T.size)
    found = np.isfinite(total[rows, best])
    return np.where(found, c[rows, best], np.nan), np.where(found, ramp[rows, best], np.nan)


def rest_to_rest_bounds(
    speed_scale: np.ndarray,
    ramp_s: np.ndarray,
    peak_velocity_rad_s: np.ndarray,
    peak_acceleration_rad_s2: np.ndarray,
    dynamics: PlanarDynamics,
    torque_terms: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closed-form bounds (module docstring) of |dq|, |ddq| [rad/s, rad/s^2] and |tau| [N m]
    of a rest-to-rest timing (c, r) of paths with the given peaks; each (n, 2). ``ramp_s`` = inf
    with c = 1 gives the paper timing's bounds. ``torque_terms`` as :func:`rest_to_rest_scales`."""
    c = np.asarray(speed_scale, dtype=float).reshape(-1, 1)
    r = np.asarray(ramp_s, dtype=float).reshape(-1, 1)
    V = np.asarray(peak_velocity_rad_s, dtype=float).reshape(-1, 2)
    acc = np.asarray(peak_acceleration_rad_s2, dtype=float).reshape(-1, 2)
    speed = c * V
    acceleration = c * c * acc + 1.5 * c * V / r
    if torque_terms is None:
        quadratic = np.stack([2 * V[:, 0] * V[:, 1] + V[:, 1] ** 2, V[:, 0] ** 2], -1)
        torque = acceleration @ dynamics.mass_matrix_sup().T + dynamics.coriolis_sup() * c * c * quadratic
    else:
        G, K = (np.asarray(x, dtype=float).reshape(-1, 2) for x in torque_terms)
        with np.errstate(invalid="ignore"):  # 0 * inf (no ramp, paper timing) is 0
            ramp_term = np.where(K == 0.0, 0.0, 1.5 * c * K / r)
        torque = c * c * G + ramp_term
    return _widened(speed), _widened(acceleration), _widened(torque)


@numba.njit(cache=True, nogil=True)
def _shortest_on_grid(
    duration: float, cap: float, grid: np.ndarray, G: np.ndarray, K: np.ndarray, bound: np.ndarray, min_ramp: float
) -> tuple[float, float]:
    """The grid search of :func:`rest_to_rest_scales` for one path, compiled: for each
    c = cap * grid[s], the shortest ramp of the constraints ``bound_k >= c^2 G_k + 1.5 c K_k / r``
    (an infinite bound: none), and the first c of least T' = T / c + r; (nan, nan) if none is
    feasible. The same operations, in the same order, as the NumPy route."""
    best_total, best_c, best_r = math.inf, math.nan, math.nan
    for s in range(grid.size):
        c = cap * grid[s]
        feasible, needed = True, -math.inf
        for k in range(bound.size):
            if math.isinf(bound[k]):
                need = 0.0
            else:
                room = bound[k] - (c * c) * G[k]
                if not room > 0.0:
                    feasible = False
                    break
                need = 1.5 * c * K[k] / room
            if need > needed:
                needed = need
        if not feasible:
            continue
        ramp = max(needed, min_ramp)
        if not ramp <= duration / c:
            continue
        total = duration / c + ramp
        if total < best_total:
            best_total, best_c, best_r = total, c, ramp
    return best_c, best_r


def _widened_float(value: float) -> float:
    """:func:`_widened` of one float (the same operations)."""
    return value + FLOAT_SLACK_RELATIVE * abs(value) + FLOAT_SLACK_ABSOLUTE


def shortest_rest_to_rest(trajectory: JointTrajectory, dynamics: PlanarDynamics, limits: ArmLimits) -> RestToRestTiming:
    """The shortest rest-to-rest timing of ``trajectory``'s path that the closed-form bounds
    (module docstring) keep within ``limits``: :func:`rest_to_rest_scales` of one path, its
    constraint terms in plain floats from the path's peaks
    (:attr:`pipeline.motion.trajectory.JointTrajectory.peaks`) and its grid search compiled
    (:func:`_shortest_on_grid`); a few microseconds.

    Args:
        trajectory: The path (the paper's sinusoids over [0, T]).
        dynamics: The arm's inverse dynamics.
        limits: The limits to keep.

    Raises:
        InvalidParameterError: no timing keeps the limits (a limit that binds at rest).
    """
    peaks = trajectory.peaks
    V1, V2 = (_widened_float(v) for v in peaks.velocity_rad_s)
    acc1, acc2 = (_widened_float(a) for a in peaks.acceleration_rad_s2)
    share = LIMIT_SHARE
    cap = 1.0
    for peak, limit in ((V1, limits.velocity_rad_s[0]), (V2, limits.velocity_rad_s[1])):
        if peak > 0.0:
            cap = min(cap, share * limit / peak)
    ((m11, m12), (m21, m22)), h = dynamics.suprema
    quadratic1, quadratic2 = 2 * V1 * V2 + V2 * V2, V1 * V1  # as NumPy's V**2: one product
    G = np.array([acc1, acc2, acc1 * m11 + acc2 * m12 + h * quadratic1, acc1 * m21 + acc2 * m22 + h * quadratic2])
    K = np.array([V1, V2, V1 * m11 + V2 * m12, V1 * m21 + V2 * m22])
    bound = np.array([share * v for v in (*limits.acceleration_rad_s2, *limits.effort_n_m)])
    c, r = _shortest_on_grid(float(trajectory.duration_s), cap, _SCALE_GRID, G, K, bound, MIN_RAMP_S)
    if not math.isfinite(c):
        raise InvalidParameterError(
            "limits", limits, "limits a rest-to-rest timing can keep (an acceleration or effort limit binds at rest)"
        )
    return RestToRestTiming(float(trajectory.duration_s), float(c), float(r))
