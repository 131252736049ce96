"""The adaptive clearance certificate's refinement rounds, compiled: the bookkeeping of
:meth:`pipeline.geometry.sinusoid_certificate._AdaptiveCertificate.run` (interval bounds, which
intervals to split and into how many parts, the settled minima, the new points and the new
intervals) on arrays of a few dozen intervals, where NumPy spends its time in call overhead.

Each function performs the same floating-point operations, in the same order, as the readable
NumPy route it replaces (sin and cos may differ from NumPy's by an ulp); the clearance itself
(Coal) is evaluated between the two calls of a round, outside. Tests prove both routes give the
same certificates (``tests/geometry/test_adaptive_kernel.py``).

The motion's constants are passed as one array, :data:`MOTION_FIELDS` in order.
"""

from __future__ import annotations

import math

import numba
import numpy as np

#: The order of the constants in the ``motion`` array (per joint 1, 2 where paired).
MOTION_FIELDS = (
    "half_w1", "half_w2", "phi1", "phi2", "half_abs_w1", "half_abs_w2", "rate_peak1", "rate_peak2",
    "acceleration_peak1", "acceleration_peak2", "rate_amplitude1", "rate_amplitude2", "link1_factor",
    "link2_factor_reach", "link2_factor_radius", "link2_factor_elbow", "w1", "w2", "amplitude1", "amplitude2",
    "gamma1", "gamma2",
)  # fmt: skip


@numba.njit(cache=True, nogil=True)
def _own_speed(motion: np.ndarray, ta: float, tb: float, on_link2: bool) -> float:
    """:meth:`_AdaptiveCertificate.speeds` of one interval, for its link."""
    h = tb - ta
    rate = np.empty(2)
    acceleration = np.empty(2)
    mid = np.empty(2)
    for j in range(2):
        um = (ta + tb) * motion[j] + motion[2 + j]
        spread = math.sin(min(h * motion[4 + j], np.pi / 2))
        sine, cosine = math.sin(um), math.cos(um)
        abs_sine, abs_cosine = abs(sine), abs(cosine)
        rate[j] = min(abs_sine * spread + abs_cosine, 1.0) * motion[6 + j]
        acceleration[j] = min(abs_cosine * spread + abs_sine, 1.0) * motion[8 + j]
        mid[j] = cosine * motion[10 + j]
    w1, w2 = rate[0], rate[1]
    if not on_link2:
        return w1 * motion[12]
    sum_rate = abs(mid[0] + mid[1]) + h * (acceleration[0] + acceleration[1]) / 2.0
    sum_rate = min(sum_rate, w1 + w2)
    return min(w1 * motion[13] + w2 * motion[14], w1 * motion[15] + sum_rate * motion[14])


@numba.njit(cache=True, nogil=True)
def _refines(lower: float, floor: float, tolerance: float, decide: float, has_decide: bool) -> bool:
    """:meth:`_AdaptiveCertificate._refine` of one interval."""
    refine = lower < floor - tolerance
    if has_decide:
        if floor <= decide:
            return False
        refine = refine and lower <= decide
    return refine


@numba.njit(cache=True, nogil=True)
def plan_round(
    ta, tb, da, db, link, speed, own, floor, tolerance, decide, has_decide, budget, split_safety, max_split,
    best_value, best_time, motion,
):  # fmt: skip
    """One round's decisions: which intervals to refine (their speed bounds made their own first),
    into how many parts, the settled intervals' lowest bound per link (``best_value``,
    ``best_time`` updated in place) and the new points with their configurations.

    Returns:
        (count, over_budget, refine (m,) bool, inner (refined,) int, points (count,), point_link
        (count,) bool, q (count, 2), owner (count,), j (count,), last (refined,)); count 0: stop.
    """
    m = ta.size
    h = tb - ta
    lower = (da + db - speed * h) / 2.0
    refine = np.empty(m, dtype=np.bool_)
    for i in range(m):
        refine[i] = _refines(lower[i], floor, tolerance, decide, has_decide)
        if refine[i] and not own[i]:
            speed[i] = _own_speed(motion, ta[i], tb[i], link[i])
            own[i] = True
            lower[i] = (da[i] + db[i] - speed[i] * h[i]) / 2.0
            refine[i] = _refines(lower[i], floor, tolerance, decide, has_decide)
    refined = 0
    for i in range(m):
        if refine[i]:
            refined += 1
    inner = np.ones(refined, dtype=np.int64)
    count = refined
    if refined and has_decide:
        target = min(floor - tolerance, decide)
        k, count = 0, 0
        for i in range(m):
            if refine[i]:
                gap = min(da[i], db[i]) - target
                parts = math.ceil(split_safety * speed[i] * h[i] / (2.0 * gap))
                parts = min(max(parts, 2.0), max_split)
                inner[k] = int(parts) - 1
                count += inner[k]
                k += 1
    over_budget = count > budget
    if over_budget:
        refine[:] = False
        refined, count = 0, 0
        inner = np.ones(0, dtype=np.int64)
    for side in range(2):
        best, where = math.inf, -1
        for i in range(m):
            if not refine[i] and link[i] == (side == 1) and lower[i] < best:
                best, where = lower[i], i
        if where >= 0 and best < best_value[side]:
            s, hi = speed[where], h[where]
            offset = (da[where] - db[where] + s * hi) / (2.0 * s) if s > 0 else 0.0
            best_value[side] = best
            best_time[side] = ta[where] + min(max(offset, 0.0), hi)
    points = np.empty(count)
    point_link = np.empty(count, dtype=np.bool_)
    q = np.empty((count, 2))
    owner = np.empty(count, dtype=np.int64)
    j = np.empty(count, dtype=np.int64)
    last = np.empty(refined, dtype=np.int64)
    p, k = 0, 0
    for i in range(m):
        if not refine[i]:
            continue
        for jj in range(1, inner[k] + 1):
            t = ta[i] + h[i] * (jj / (inner[k] + 1))
            points[p], point_link[p], owner[p], j[p] = t, link[i], k, jj
            for joint in range(2):
                q[p, joint] = (
                    math.sin(t * motion[16 + joint] + motion[2 + joint]) * motion[18 + joint] + motion[20 + joint]
                )
            p += 1
        last[k] = p - 1
        k += 1
    return count, over_budget, refine, inner, points, point_link, q, owner, j, last


@numba.njit(cache=True, nogil=True)
def merge_round(ta, tb, da, db, link, speed, refine, points, values, point_link, owner, j, last):
    """The intervals after a round: for every refined interval, [previous point, point] for each of
    its new points, then [last point, tb] (``values``: the new points' clearance minus the error)."""
    kept = np.flatnonzero(refine)
    count, refined = points.size, kept.size
    size = count + refined
    new_ta, new_tb = np.empty(size), np.empty(size)
    new_da, new_db = np.empty(size), np.empty(size)
    new_link, new_speed = np.empty(size, dtype=np.bool_), np.empty(size)
    for p in range(count):
        i = kept[owner[p]]
        if j[p] == 1:
            new_ta[p], new_da[p] = ta[i], da[i]
        else:
            new_ta[p], new_da[p] = points[p - 1], values[p - 1]
        new_tb[p], new_db[p] = points[p], values[p]
        new_link[p], new_speed[p] = point_link[p], speed[i]
    for k in range(refined):
        i = kept[k]
        new_ta[count + k], new_da[count + k] = points[last[k]], values[last[k]]
        new_tb[count + k], new_db[count + k] = tb[i], db[i]
        new_link[count + k], new_speed[count + k] = link[i], speed[i]
    return new_ta, new_tb, new_da, new_db, new_link, new_speed, np.zeros(size, dtype=np.bool_)
