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
are about 1e-14 rad and 1e-13 s. The leaf is the map's own scalar lookup's,
:func:`pipeline.certify.lookup.leaf_of` (the same leaf as :meth:`RegionMap.leaf_indices`), and its
bounds and status are read from a copy of the map's own columns.

**Why the certificate covers either route.** The range certificate bounds the clearance and the
endpoint error of the exact regression polynomial and the exact T at every point of a leaf, and
lowers every bound by ``pipeline.certify.interval.FLOAT_SLACK_M`` (1e-9 m). An answer's
parameters and T carry rounding errors of the sizes above (both routes). A joint angle
A sin(w t + phi) + gamma moves by at most |dA| + |A| (|dw| t + w |dt| + |dphi|) + |dgamma|, and
the links' points by at most (l1 + l2) times the angles' change: with every d below 1e-12 and
|A|, w, T of order 1 to 10, that is below 1e-10 m, under the slack.

**Its arguments.** Five numbers of the obstacle's pose, the values of the regression's variables
past its first two (the obstacle's size), their count, and three flat arrays: the plan of the
coefficients (:func:`plan_numbers`) and the map's two lookup arrays
(:class:`pipeline.certify.lookup.LookupTables`; :data:`NO_TABLES` without a map). The cost of a
Numba call grows with the number of arrays it is given, so they are few and packed; the core
allocates nothing, so its time is its arithmetic. Its machine code is loaded when this module is
imported (:data:`query_core_entry`), so no query compiles: the extension module compiled from
this source when the package was built (under a millisecond), else Numba's JIT compilation for
its one signature, cached on disk (``cache=True``; loading it starts Numba's compiler target,
about half a second, and the first compilation takes a few seconds; :mod:`pipeline.native`). The
first query with a coefficients object and its map builds their arrays once. Every array is
C-contiguous and writable (Numba's dispatch of a read-only array costs twice as much)."""

from __future__ import annotations

import math

import numba
import numpy as np

from pipeline.certify import lookup
from pipeline.certify.lookup import NO_TABLES, bounds_of, leaf_of
from pipeline.native import Export, NativeModule

__all__ = ["COMPILED", "NATIVE", "NO_TABLES", "plan_numbers", "query_core", "query_core_entry"]

#: Where the plan's numbers start (:func:`plan_numbers`): the scene's and the reach's seven, then
#: the fitted range's (lo, hi) of each of the k variables, then the regression, then the rule.
_RANGES = 7


def plan_numbers(
    scene_numbers: tuple[float, ...], ranges: np.ndarray, matrix: np.ndarray, rule: np.ndarray
) -> np.ndarray:
    """The plan of one coefficients object, as the core reads it: one flat float64 array.

    Args:
        scene_numbers: start_dx, approach_dx, approach_dy, apex_dy [m], speed [m/s], and the reach
            annulus' inner and outer radii [m].
        ranges: (k, 2): the fitted range of every variable of the regression, in its order [m].
        matrix: (1 + k + k(k+1)/2, 8): the regression, basis -> parameters, columns past the
            family's free parameters zero.
        rule: (5, m): the arc-length rule: rows 1, u^2, u^4, u^6 at its nodes, then its weights.
    """
    parts = (np.asarray(scene_numbers, float), ranges, matrix, rule)
    return np.concatenate([np.asarray(part, float).reshape(-1) for part in parts])


@numba.njit(cache=True, nogil=True)
def _value(a: int, length_m: float, width_m: float, v2: float, v3: float) -> float:
    """The regression's a-th variable's value: the obstacle's size first, then v2, v3."""
    if a == 0:
        return length_m
    if a == 1:
        return width_m
    if a == 2:
        return v2
    return v3


@numba.njit(cache=True, nogil=True)
def _add_row(p, b: float, plan: np.ndarray, row: int):
    """The eight sums ``p`` plus b times the regression's row starting at ``plan[row]``."""
    return (
        p[0] + b * plan[row], p[1] + b * plan[row + 1], p[2] + b * plan[row + 2], p[3] + b * plan[row + 3],
        p[4] + b * plan[row + 4], p[5] + b * plan[row + 5], p[6] + b * plan[row + 6], p[7] + b * plan[row + 7],
    )  # fmt: skip


@numba.njit(cache=True, nogil=True)
def _duration(plan: np.ndarray, k: int, x1: float, x2: float, y2: float, y3: float, y1: float, speed: float) -> float:
    """T [s] of the even quartic through (x1, y1), (x2, y2), (0, y3) (pipeline.motion.path.symmetric_quartic,
    then its length by the plan's arc-length rule); NaN unless x1 > x2 > 0."""
    if not x1 > x2 > 0.0:
        return math.nan
    terms = 1 + k + k * (k + 1) // 2
    rule = _RANGES + 2 * k + 8 * terms
    nodes = (plan.shape[0] - rule) // 5
    ua = x1 * x1
    ub = x2 * x2
    ra = (y1 - y3) / ua
    rb = (y2 - y3) / ub
    c4 = (ra - rb) / (ua - ub)
    c2 = ra - c4 * ua
    k1 = 2.0 * c2 * x1
    k3 = 4.0 * c4 * x1 * x1 * x1
    f1, f2, f3 = k1 * k1, 2.0 * k1 * k3, k3 * k3
    # The rule's rows as views, indexed from 0: the compiler then drops the negative-index checks.
    ones, u2, u4, u6 = (
        plan[rule : rule + nodes],
        plan[rule + nodes : rule + 2 * nodes],
        plan[rule + 2 * nodes : rule + 3 * nodes],
        plan[rule + 3 * nodes : rule + 4 * nodes],
    )
    weights = plan[rule + 4 * nodes : rule + 5 * nodes]
    total = 0.0
    for j in range(nodes):
        q = ones[j] + f1 * u2[j]
        q = q + f2 * u4[j]
        q = q + f3 * u6[j]
        total += math.sqrt(q) * weights[j]
    return 2.0 * x1 * total / speed


@numba.njit(cache=True, nogil=True)
def query_core(
    length_m: float, width_m: float, centre_x_m: float, top_y_m: float, start_y_m: float, v2: float, v3: float,
    k: int, plan: np.ndarray, index: np.ndarray, bounds: np.ndarray,
):  # fmt: skip
    """One query's numbers (module docstring).

    Args:
        length_m, width_m: L, W [m], finite and positive, checked by the caller.
        centre_x_m, top_y_m, start_y_m: The obstacle's centre x, far edge d and the height of P1
            and P5 [m] of this query.
        v2, v3: The values of the regression's third and fourth variables (not read past ``k``).
        k: The number of the regression's variables (2 to 4), the obstacle's size first.
        plan: The coefficients' plan (:func:`plan_numbers`).
        index, bounds: The region map's lookup arrays
            (:class:`pipeline.certify.lookup.LookupTables`; :data:`NO_TABLES` for none).

    Returns:
        (unreachable, radius_m, duration_s, inside, leaf, clearance_bound_m, endpoint_bound_m,
        status, (p0, ..., p7), finite): the number (0-4) of the first of P1..P5 outside the reach
        annulus or -1, and its distance from the base [m] (NaN if none); T [s] (NaN where the
        path's closed form does not apply: P2 not between the centre and P1); True inside the
        fitted range; the map's leaf (-1 outside it or without a map) with its two bounds [m]
        and its status (index into ``STATUSES``; NaN, NaN, -1 without a leaf); the regression's
        eight columns, as one tuple; True if all eight are finite.
    """
    start_dx, approach_dx, approach_dy, apex_dy, speed, reach_lo, reach_hi = (
        plan[0], plan[1], plan[2], plan[3], plan[4], plan[5], plan[6],
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
    for point in range(5):
        if not (reach_lo <= radii[point] <= reach_hi):
            unreachable, radius = point, radii[point]
            break
    duration = _duration(plan, k, x1, x2, y2, y3, start_y_m, speed)
    inside = True
    for a in range(k):
        value = _value(a, length_m, width_m, v2, v3)
        if not (plan[_RANGES + 2 * a] <= value <= plan[_RANGES + 2 * a + 1]):
            inside = False
    row = _RANGES + 2 * k
    p = _add_row((0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), 1.0, plan, row)
    for a in range(k):
        row += 8
        p = _add_row(p, _value(a, length_m, width_m, v2, v3), plan, row)
    for a in range(k):
        va = _value(a, length_m, width_m, v2, v3)
        for b in range(a, k):
            row += 8
            p = _add_row(p, va * _value(b, length_m, width_m, v2, v3), plan, row)
    finite = True
    for col in range(8):
        if not math.isfinite(p[col]):
            finite = False
    leaf, clearance, endpoint, status = -1, math.nan, math.nan, -1
    if inside:
        leaf = leaf_of(index, bounds, k, length_m, width_m, v2, v3)
        if leaf >= 0:
            clearance, endpoint, status = bounds_of(bounds, k, leaf)
    return unreachable, radius, duration, inside, leaf, clearance, endpoint, status, p, finite


#: The core's machine code (:mod:`pipeline.native`): compiled ahead of time into
#: ``pipeline.online.kernel_native`` when the package is built, else by the JIT. Its code is this
#: module's and the lookup's.
NATIVE = NativeModule(
    "pipeline.online.kernel_native",
    (
        Export(
            "query_core",
            query_core,
            "Tuple((int64, float64, float64, boolean, int64, float64, float64, int64, UniTuple(float64, 8), boolean))"
            "(float64, float64, float64, float64, float64, float64, float64, int64, float64[::1], int32[::1],"
            " float64[::1])",
        ),
    ),
    (__file__, lookup.__file__),
)
#: The core's callables, loaded when this module is imported (:meth:`NativeModule.load`).
COMPILED = NATIVE.load()
#: :func:`query_core`'s callable: for callers that have checked the types of its arguments and give
#: C-contiguous arrays, as :func:`pipeline.online.generator.generate` does.
query_core_entry = COMPILED["query_core"]
