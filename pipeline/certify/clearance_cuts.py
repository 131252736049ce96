"""Cuts of the leaves that miss the margin where the clearance keeps it: each halved along the
axis across which the clearance changes most and its halves bounded on their own, a few rounds,
where the margin's contour crosses the leaf or the bound's gap keeps it below the margin.

A leaf certified collision-free below the margin and not proven infeasible whose search found
the clearance at the centres of its boxes at or above the margin
(``SearchLeaves.center_clearance_m``) keeps the margin over part of it at least. Over four axes
the search stops at cubes of 1/32, and most such cubes are crossed by the margin's contour: after
the cuts, the clearance sampled on the 3^4 grid of their corners and midpoints still falls below
the margin in three of four, while the bound lies less than a tenth of a millimetre under the
sampled minimum (``python scripts/margin_band.py``, its last line).
What recovers their part above the contour is a cut across it: a cut of every axis is 2^k
halves; a cut of one axis at a time, kept only where a half is still open, is the interval
subpaving's way (SIVIA). Each round halves every open leaf along its **steepest axis**
(:func:`steepest_axes`): the axis along which the regression's clearance, at the time s* of its
lowest sampled value at the leaf's centre, changes most between the leaf's two faces across it
(the contour's normal leans most towards that axis, so that cut leaves the largest part of a half
on one side of it), and bounds each half over all of s by the strips' branch and bound over s
(:func:`pipeline.certify.strip_split.cell_clearance_bounds`, in the settings' bound form). A half
is closed once its bound reaches the margin, or once the clearance at the centre of one of its
boxes is below the margin (a value the clearance takes in it: no cut proves the margin all over
it); the others are cut again in the next round.

**Soundness.** A half keeps its leaf's endpoint-error bound and infeasibility bound (each holds
over the whole leaf, so over a part of it) and gets the larger of its leaf's clearance bound and
its own: both are lower bounds on the clearance over the half times all of s (the leaf's holds
over the whole leaf; the half's, by ``clearance_bound``'s derivation, over the boxes that cover
the half times [0, 1]). Which leaves are cut, along which axis (the sampled clearance that picks
it proves nothing and need not) and for how many rounds is a choice of work: any choice keeps
every bound valid.
"""

from __future__ import annotations

import numpy as np

from pipeline.certify.clearance_bound import point_clearance_m
from pipeline.certify.range_model import RangeModel
from pipeline.certify.strip_split import cell_clearance_bounds

__all__ = ["half_clearance_bounds", "steepest_axes"]

#: Times s sampled at a leaf's centre for the one, s*, at which its clearance is lowest.
STEEPEST_SAMPLES_S = 33


def steepest_axes(model: RangeModel, center_m: np.ndarray, radius_m: np.ndarray) -> np.ndarray:
    """Per leaf (centres, half widths (n, k) [m]), the axis to halve it along: the one along which
    the clearance at s* (the lowest of :data:`STEEPEST_SAMPLES_S` times at the centre) differs most
    between the leaf's two faces across it, the first such axis on a tie (module docstring)."""
    center = np.asarray(center_m, dtype=float).reshape(-1, model.k)
    radius = np.asarray(radius_m, dtype=float).reshape(center.shape)
    n, k = center.shape
    s = np.linspace(0.0, 1.0, STEEPEST_SAMPLES_S)
    at_centre = point_clearance_m(model, np.column_stack([np.repeat(center, s.size, axis=0), np.tile(s, n)]))
    s_star = s[np.argmin(at_centre.reshape(n, s.size), axis=1)]
    change = np.empty((n, k))
    for axis in range(k):
        ends = [center.copy(), center.copy()]
        ends[0][:, axis] -= radius[:, axis]
        ends[1][:, axis] += radius[:, axis]
        low, high = (point_clearance_m(model, np.column_stack([end, s_star])) for end in ends)
        change[:, axis] = np.abs(high - low)
    return np.argmax(np.nan_to_num(change, nan=-1.0), axis=1)


def half_clearance_bounds(
    model: RangeModel,
    center_m: np.ndarray,
    radius_m: np.ndarray,
    floor_m: np.ndarray,
    margin_m: float,
    max_depth_s: int,
    second_order: bool,
) -> np.ndarray:
    """Per half (centres, half widths (n, k) [m]; ``floor_m`` its leaf's clearance bound): its
    clearance lower bound [m] over all of s, at least the floor, and 1.0 where the clearance at
    every box centre kept the margin (0.0: a point below it), as an (n, 2) array."""
    bound, hopeful = cell_clearance_bounds(
        model, center_m, radius_m, floor_m, margin_m, max_depth_s, second_order=second_order
    )
    return np.column_stack([bound, hopeful.astype(float)])
