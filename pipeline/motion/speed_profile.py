"""The fastest path-speed profile under piecewise linear constraints: reachability passes.

The path is cut into n pieces of length ``ds`` (:mod:`pipeline.motion.path_constraints`); the profile
is ``x_k = sdot^2`` at the pieces' ends and a constant path acceleration ``u_k`` on each piece,
so ``x_k+1 = x_k + 2 ds u_k``. Piece k's rows ``cu u + cx x <= rhs`` must hold at both of its ends,
``(x_k, u_k)`` and ``(x_k+1, u_k)``, and x at both ends within the piece's speed cap; then they hold
over the whole piece (x is linear in s there). This is the problem TOPP-RA solves (Pham & Pham,
"A new approach to time-optimal path parameterization based on reachability analysis", 2018),
with each piece's constraints imposed over the piece rather than at grid points.

* **Backward pass** (controllable sets): ``K_n = {0}`` (rest at the end); ``K_k = [0, X_k]`` where
  X_k is the largest x_k for which some u_k satisfies piece k's rows and puts x_k+1 in K_k+1.
  For a fixed x the feasible u form an interval [ulo(x), uhi(x)] (each row bounds u from one
  side), ``F(x) = uhi(x) - ulo(x)`` is concave and piecewise linear, and F(0) >= 0 (x = u = 0 keeps
  every row, each limit being positive); X_k is its largest root, found by Newton steps from the
  right (the tangent of a concave function lies above it, so every step stays at or right of the
  root and the steps end on it); where rounding stalls them at the root, x (1 - 1e-9) is taken if
  feasible, and bisection is the fallback.
* **Forward pass** (greedy): ``x_0 = 0`` (rest at the start), then on each piece the largest u
  that keeps the rows and x_k+1 within K_k+1.

The result keeps every row up to rounding; it is not a certificate. The timing built from it is
certified afterwards (:mod:`pipeline.motion.near_optimal`).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["fastest_profile"]

_NEWTON_STEPS = 60
_BISECTIONS = 80
#: Newton's first point is found by quadrupling x from the next piece's bound (at least this) until
#: it is infeasible or reaches the speed cap; beyond _LARGEST_X no row bounds x.
_SMALLEST_START_X = 1e-12
_LARGEST_X = 1e300
#: Where Newton's steps stall on rounding, x (1 - this) is tried before bisecting.
_NEAR_ROOT = 1e-9


@numba.njit(cache=True, nogil=True)
def _u_range(cu, cx, rhs, x, ds, top):
    """(ulo, uhi, slope of ulo in x, slope of uhi in x) for one piece at x_k = x, x_k+1 <= top."""
    ulo, uhi, slo, shi = -np.inf, np.inf, 0.0, 0.0
    for j in range(cu.size):
        room = rhs[j] - cx[j] * x
        for a in (cu[j], cu[j] + 2.0 * ds * cx[j]):  # the row at x_k, then at x_k+1 = x + 2 ds u
            if a > 0.0:
                if room / a < uhi:
                    uhi, shi = room / a, -cx[j] / a
            elif a < 0.0:
                if room / a > ulo:
                    ulo, slo = room / a, -cx[j] / a
            elif room < 0.0:
                return np.inf, -np.inf, 0.0, 0.0
    if -x / (2.0 * ds) > ulo:
        ulo, slo = -x / (2.0 * ds), -1.0 / (2.0 * ds)
    if (top - x) / (2.0 * ds) < uhi:
        uhi, shi = (top - x) / (2.0 * ds), -1.0 / (2.0 * ds)
    return ulo, uhi, slo, shi


@numba.njit(cache=True, nogil=True)
def _largest_feasible_x(cu, cx, rhs, cap, ds, top):
    """The largest x in [0, cap] with ulo(x) <= uhi(x) (module docstring)."""
    # Start Newton within a factor 4 of the root (from far above, its first step would cancel).
    x = min(cap, max(top, _SMALLEST_START_X))
    while x < cap:
        ulo, uhi, _, _ = _u_range(cu, cx, rhs, x, ds, top)
        if uhi < ulo:
            break
        if x > _LARGEST_X:  # no row bounds x: the cap, if any, does
            return min(cap, x)
        x = min(4.0 * x, cap)
    for _ in range(_NEWTON_STEPS):
        ulo, uhi, slo, shi = _u_range(cu, cx, rhs, x, ds, top)
        gap = uhi - ulo
        if gap >= 0.0:
            return x
        slope = shi - slo
        if not slope < 0.0:
            break
        step = x - gap / slope
        if not step < x:  # at the root up to rounding: look just below it first
            below = x * (1.0 - _NEAR_ROOT)
            ulo, uhi, _, _ = _u_range(cu, cx, rhs, below, ds, top)
            if uhi >= ulo:
                return below
            break
        x = max(step, 0.0)
    lo, hi = 0.0, x
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        ulo, uhi, _, _ = _u_range(cu, cx, rhs, mid, ds, top)
        if uhi >= ulo:
            lo = mid
        else:
            hi = mid
    return lo


@numba.njit(cache=True, nogil=True)
def _passes(cu, cx, rhs, cap, ds):
    n = cap.size
    reach = np.zeros(n + 1)
    for k in range(n - 1, -1, -1):
        top = min(reach[k + 1], cap[k])
        reach[k] = _largest_feasible_x(cu[k], cx[k], rhs[k], cap[k], ds, top)
    x = np.zeros(n + 1)
    u = np.zeros(n)
    for k in range(n):
        top = min(reach[k + 1], cap[k])
        ulo, uhi, _, _ = _u_range(cu[k], cx[k], rhs[k], x[k], ds, top)
        step = uhi if uhi >= ulo else ulo
        x[k + 1] = min(max(x[k] + 2.0 * ds * step, 0.0), top)
        u[k] = (x[k + 1] - x[k]) / (2.0 * ds)
    return x, u, reach


def fastest_profile(
    cu: np.ndarray, cx: np.ndarray, rhs: np.ndarray, speed_cap: np.ndarray, ds: float
) -> tuple[np.ndarray, np.ndarray]:
    """The greedy fastest profile (module docstring) on n pieces of length ``ds`` [s].

    Args:
        cu, cx, rhs: (n, m) the rows ``cu u + cx x <= rhs`` of each piece.
        speed_cap: (n,) the largest x on each piece (inf: none).
        ds: The pieces' length on the path time [s].

    Returns:
        (x, u): x = sdot^2 at the n + 1 ends (0 at both), u = sddot on each piece, (n,).
    """
    x, u, _ = _passes(
        np.ascontiguousarray(cu, dtype=float),
        np.ascontiguousarray(cx, dtype=float),
        np.ascontiguousarray(rhs, dtype=float),
        np.ascontiguousarray(speed_cap, dtype=float),
        float(ds),
    )
    return x, u
