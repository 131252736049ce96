"""The compiled core of one online query: P1..P5 against the reach, T, the regression and the
region map's leaf, in one call of a Numba-compiled function.

:func:`pipeline.online.generator.generate` checks its arguments in Python, calls
:func:`query_core` once, and builds the answer from what it returns. The NumPy routes are the
canonical ones: :func:`pipeline.motion.path.symmetric_quartic_length_m` for T,
:meth:`pipeline.offline.coefficients.Coefficients.predict_free` for the regression and
:meth:`pipeline.certify.region_map.RegionMap.leaf_indices` for the leaf. This core evaluates the
same formulas in the same floating-point operations, except for the order of two sums:

* **T.** T = 2 a sum_j w_j sqrt(q_j) / v with q_j = P_0j + k1^2 P_1j + 2 k1 k3 P_2j + k3^2 P_3j
  (the path module's rule: 160 nodes, rows P of 1, u^2, u^4, u^6). NumPy forms q_j and the sum
  over j with BLAS, whose order of additions depends on the machine; here they are added from
  left to right.
* **The regression.** p_k = sum_i b_i M_ik over the basis b = (1, v, v_i v_j for i <= j), also
  added from left to right here, by BLAS there. The basis itself is the same floats in both.

**How far the two routes can differ.** With u = 2^-53 and gamma_n = n u / (1 - n u), a sum of
n products computed in any order differs from the exact one by at most gamma_n sum |terms|
(Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Sec. 3.1). Two orders
differ from each other by at most twice that. For the regression with m basis terms:

    |p_k(core) - p_k(NumPy)| <= 2 gamma_(m+1) sum_i |b_i M_ik|,

and for T, with Q_j = P_0j + k1^2 P_1j + 2 |k1 k3| P_2j + k3^2 P_3j and q_j >= 1 (q_j = 1 +
u^2 (k1 + k3 u^2)^2 exactly), each route's sqrt(q_j) is within (gamma_5 Q_j / q_j) sqrt(q_j) of
the exact one (the square root halves the relative error and adds one rounding), its weighted
sum of positive terms and the last product and quotient add gamma_162 of the value, and the two
routes differ by at most twice that:

    |T(core) - T(NumPy)| <= 2 (gamma_5 max_j Q_j / q_j + gamma_162) T (1 + gamma_8).

``tests/online/test_kernel.py`` checks both bounds on random queries; on the fitted ranges they
are about 1e-14 rad and 1e-13 s. The leaf is an integer found by the same floating-point
operations as :meth:`RegionMap.leaf_indices` (a division, a product by a power of two, a
truncation), so it is the same leaf, and its bounds and status are read from the map's own
columns (:attr:`pipeline.certify.region_map.LookupTables.leaves`).

**Why the certificate covers either route.** The range certificate bounds the clearance and the
endpoint error of the exact regression polynomial and the exact T at every point of a leaf, and
lowers every bound by ``pipeline.certify.interval.FLOAT_SLACK_M`` (1e-9 m). An answer's
parameters and T carry rounding errors of the sizes above (both routes). A joint angle
A sin(w t + phi) + gamma moves by at most |dA| + |A| (|dw| t + w |dt| + |dphi|) + |dgamma|, and
the links' points by at most (l1 + l2) times the angles' change: with every d below 1e-12 and
|A|, w, T of order 1 to 10, that is below 1e-10 m, under the slack.

The core is compiled for its one signature when this module is imported, and Numba caches the
machine code on disk (``cache=True``): importing it loads the cache (or, the first time, compiles,
a few seconds), so no query compiles. The first query with a coefficients object
and its map builds their tables once (0.1 s for the default (L, W) map). Every array argument is
C-contiguous, as the generator and :class:`LookupTables` make them.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from pipeline.certify.region_map import LOOKUP_SIZE, LookupTables

__all__ = ["NO_MAP", "NO_TABLES", "query_core"]

#: The map mode of a query without a region map (the lookup arrays are then not read).
NO_MAP = 0


def _no_tables() -> LookupTables:
    layout = np.array([NO_MAP, 1, 0, 0, 1, 0], dtype=np.int64)
    return LookupTables(layout, np.zeros((0, 2)), np.zeros(0, np.int32), np.zeros((0, 3)))


#: The lookup tables of a query without a region map: the arrays' types are a map's, so that
#: one compiled core serves both.
NO_TABLES = _no_tables()


@numba.njit("int64(float64[::1], int64[::1], float64[:, ::1], int32[::1])", cache=True, nogil=True)
def _leaf(values: np.ndarray, layout: np.ndarray, ranges: np.ndarray, table: np.ndarray) -> int:
    """The leaf holding ``values``, as RegionMap.leaf_indices finds it; -1 outside the map's box."""
    for a in range(values.shape[0]):
        if not (ranges[a, 0] <= values[a] <= ranges[a, 1]):
            return -1
    mode, n, shift, coarse, width, rows = layout[0], layout[1], layout[2], layout[3], layout[4], layout[5]
    if mode == LOOKUP_SIZE:
        i = int((values[0] - ranges[0, 0]) / (ranges[0, 1] - ranges[0, 0]) * n)
        v = (values[1] - ranges[1, 0]) / (ranges[1, 1] - ranges[1, 0]) * n
        j = int(v)
        i = min(i, n - 1)
        j = min(j, n - 1)
        leaf = table[i * n + j]
        if leaf >= 0:
            return leaf
        slot = min(max(int(v * width) - j * width, 0), width - 1)
        return table[rows + (-leaf - 1) * width + slot]
    k = values.shape[0]
    cells = np.empty(k, dtype=np.int64)
    key = 0
    for a in range(k):
        t = int((values[a] - ranges[a, 0]) / (ranges[a, 1] - ranges[a, 0]) * n)
        t = min(t, n - 1)
        cells[a] = t
        key = (key << coarse) | (t >> shift)
    leaf = table[key]
    while leaf < 0:
        shift -= 1
        slot = 0
        for a in range(k):
            slot = (slot << 1) | ((cells[a] >> shift) & 1)
        leaf = table[rows + (-leaf - 1) * width + slot]
    return leaf


@numba.njit(
    "Tuple((int64, float64, float64, boolean, int64, float64, float64, int64, float64, float64, float64, float64,"
    " float64, float64, float64, float64))(float64, float64, float64, float64, float64, int64[::1], float64[::1],"
    " float64[:, ::1], float64[:, ::1], int64[::1], float64[:, ::1], int32[::1], float64[:, ::1])",
    cache=True,
    nogil=True,
)
def query_core(
    length_m: float, width_m: float, centre_x_m: float, top_y_m: float, start_y_m: float,
    variables: np.ndarray, numbers: np.ndarray, rule: np.ndarray, matrix: np.ndarray,
    layout: np.ndarray, ranges: np.ndarray, table: np.ndarray, leaves: np.ndarray,
):  # fmt: skip
    """One query's numbers (module docstring).

    Args:
        length_m, width_m: L, W [m], finite and positive, checked by the caller.
        centre_x_m, top_y_m, start_y_m: The obstacle's centre x, far edge d and the height of P1
            and P5 [m] of this query.
        variables: Codes of the regression's variables beyond L and W, in order (0 = x, 1 = d).
        numbers: start_dx, approach_dx, approach_dy, apex_dy [m], speed [m/s], the reach
            annulus' inner and outer radii [m], then the fitted range's lower ends of every
            variable (L, W, then ``variables``), then their upper ends [m].
        rule: The arc-length rule: rows 1, u^2, u^4, u^6 at its nodes, then its weights (5, m).
        matrix: The regression (basis, 8), columns past the family's free parameters zero.
        layout, ranges, table, leaves: The region map's lookup tables
            (:class:`pipeline.certify.region_map.LookupTables`; :data:`NO_TABLES` for none).

    Returns:
        (unreachable, radius_m, duration_s, inside, leaf, clearance_bound_m, endpoint_bound_m,
        status, p0, ..., p7): the number (0-4) of the first of P1..P5 outside the reach annulus
        or -1, and its distance from the base [m] (NaN if none); T [s] (NaN where the path's
        closed form does not apply: P2 not between the centre and P1); True inside the fitted
        range; the map's leaf (-1 outside it or without a map) with its two bounds [m] and its
        status (index into ``STATUSES``; NaN, NaN, -1 without a leaf); the regression's eight
        columns.
    """
    start_dx, approach_dx, approach_dy, apex_dy, speed, reach_lo, reach_hi = (
        numbers[0], numbers[1], numbers[2], numbers[3], numbers[4], numbers[5], numbers[6],
    )  # fmt: skip
    bottom = top_y_m - width_m
    x1 = length_m / 2.0 + start_dx
    x2 = length_m / 2.0 + approach_dx
    y2 = bottom - approach_dy
    y3 = bottom - apex_dy
    c = centre_x_m
    radii = (
        math.hypot(x1 + c, start_y_m), math.hypot(x2 + c, y2), math.hypot(c, y3),
        math.hypot(c - x2, y2), math.hypot(c - x1, start_y_m),
    )  # fmt: skip
    unreachable, radius = -1, math.nan
    for p in range(5):
        if not (reach_lo <= radii[p] <= reach_hi):
            unreachable, radius = p, radii[p]
            break
    duration = math.nan
    if x1 > x2 > 0.0:  # pipeline.motion.path.symmetric_quartic, then its length
        ua = x1 * x1
        ub = x2 * x2
        ra = (start_y_m - y3) / ua
        rb = (y2 - y3) / ub
        c4 = (ra - rb) / (ua - ub)
        c2 = ra - c4 * ua
        k1 = 2.0 * c2 * x1
        k3 = 4.0 * c4 * x1 * x1 * x1
        f1, f2, f3 = k1 * k1, 2.0 * k1 * k3, k3 * k3
        total = 0.0
        for j in range(rule.shape[1]):
            q = rule[0, j] + f1 * rule[1, j]
            q = q + f2 * rule[2, j]
            q = q + f3 * rule[3, j]
            total += math.sqrt(q) * rule[4, j]
        duration = 2.0 * x1 * total / speed
    k = 2 + variables.shape[0]
    values = np.empty(k)
    values[0] = length_m
    values[1] = width_m
    for a in range(variables.shape[0]):
        values[2 + a] = centre_x_m if variables[a] == 0 else top_y_m
    inside = True
    for a in range(k):
        if not (numbers[7 + a] <= values[a] <= numbers[7 + k + a]):
            inside = False
    basis = np.empty(matrix.shape[0])
    basis[0] = 1.0
    m = 1
    for a in range(k):
        basis[m] = values[a]
        m += 1
    for a in range(k):
        for b in range(a, k):
            basis[m] = values[a] * values[b]
            m += 1
    p = np.zeros(8)
    for i in range(matrix.shape[0]):
        for col in range(8):
            p[col] += basis[i] * matrix[i, col]
    leaf, clearance, endpoint, status = -1, math.nan, math.nan, -1
    if layout[0] != NO_MAP and inside:
        leaf = _leaf(values, layout, ranges, table)
        if leaf >= 0:
            clearance, endpoint, status = leaves[leaf, 0], leaves[leaf, 1], int(leaves[leaf, 2])
    return (
        unreachable, radius, duration, inside, leaf, clearance, endpoint, status,
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7],
    )  # fmt: skip
