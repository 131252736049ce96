"""Cuts of the leaves that miss the margin where the clearance keeps it: each halved along its
coarsest axis and its halves bounded on their own, a few rounds, where the bound's gap, not the
clearance, keeps the leaf below the margin.

A leaf certified collision-free below the margin and not proven infeasible whose search found
the clearance at the centres of its boxes at or above the margin
(``SearchLeaves.center_clearance_m``) most likely keeps the margin all over: what it misses is
the bound's gap. Over four axes the search stops at cubes of 1/32, where the second-order form's
gap below the clearance is a few millimetres, and the cubes it leaves below the margin this way
are about half of the volume below the margin (``python scripts/margin_band.py``). A cut of every
axis is 2^k halves; a cut of one axis at a time, kept only where a half is still open, is the
interval subpaving's way (SIVIA): each round halves every open leaf along its coarsest axis (its
lowest level, the first such axis: k rounds halve every axis once) and bounds each half over all
of s by the strips' branch and bound over s
(:func:`pipeline.certify.strip_split.cell_clearance_bounds`, in the settings' bound form). A half
is closed once its bound reaches the margin, or once the clearance at the centre of one of its
boxes is below the margin (a value the clearance takes in it: no cut proves the margin all over
it); the others are cut again in the next round.

**Soundness.** A half keeps its leaf's endpoint-error bound and infeasibility bound (each holds
over the whole leaf, so over a part of it) and gets the larger of its leaf's clearance bound and
its own: both are lower bounds on the clearance over the half times all of s (the leaf's holds
over the whole leaf; the half's, by ``clearance_bound``'s derivation, over the boxes that cover
the half times [0, 1]). Which leaves are cut, along which axis and for how many rounds is a choice
of work: any choice keeps every bound valid.
"""

from __future__ import annotations

import numpy as np

from pipeline.certify.range_model import RangeModel
from pipeline.certify.strip_split import cell_clearance_bounds

__all__ = ["coarsest_axes", "half_clearance_bounds"]


def coarsest_axes(levels: np.ndarray) -> np.ndarray:
    """Per leaf (levels (n, k)), the axis to halve it along: its coarsest (lowest level), the
    first such axis on a tie (module docstring)."""
    return np.argmin(np.asarray(levels), axis=1)


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
