"""Range certificates at the ends of the motion: an upper bound on the endpoint errors over
cells of the coefficients' axes ((L, W), with the obstacle's centre x and / or its far edge y d
if they vary them), and an infeasibility certificate for the margin at the endpoints. The
sections below derive both over (L, W); the last two extend them to x and to d.

Endpoint errors
===============

e_start(L, W) = tip(theta(L, W, s = 0)) - P1(L, W) and e_end = tip(theta(L, W, s = 1)) - P5(L, W),
tip by Eq. 2 (l1 (cos th1, sin th1) + l2 (cos(th1 + th2), sin(th1 + th2))),
P1 = (L/2 + dx1, y1), P5 = (-(L/2 + dx1), y1). Each component is a smooth function of (L, W),
enclosed over a cell by the mean-value form around the cell centre (interval jets of
``pipeline.certify.range_model``, T(L, W) included through s = 1); |e| <= the norm of the
largest corner of the enclosing box. The form is exact to first order, so the bound exceeds
the cell's true maximum by O(h^2). For a family that pins the endpoints (exact-endpoints), the
errors vanish algebraically wherever its A1 is not clamped over the cell
(:meth:`pipeline.certify.range_model.RangeModel.endpoints_pinned`); the bound there is the
rounding slack.

The second-order form (``second_order=True``). The mean-value form reads |de/dv_a| over the whole
cell, and the interval of the gradient over a cell is as wide as the Hessian times the cell, so
its gap is the gradient at the centre times h plus a term in h^2 whose interval overestimation
dominates on the cells the certificate reaches (a gap that falls by 4.4 per halving:
``python scripts/endpoint_gap.py``). Each component e is C^2 over the cell (the jets enclose its
Hessian there: second-order jets of the axes, of T through
:meth:`pipeline.certify.duration.DurationModel.hessian_magnitude`, and of every operation), so by
Taylor's theorem with the Lagrange remainder, for v = c + u in the cell (|u_a| <= r_a)

    e(v) = e(c) + grad e(c) . u + u^T H(xi) u / 2,   xi on the segment [c, v] (in the cell),

hence |e(v) - e(c)| <= sum_a |grad e(c)|_a r_a + sum_ab |H|_ab r_a r_b / 2 with |grad e(c)| the
magnitude of the gradient's enclosure at the centre (a point jet) and |H| that of the Hessian's
enclosure over the cell. Both forms enclose e over the cell, so their intersection does; the
bound takes, per component, the larger magnitude of the intersected interval. Its gap is the
centre's gradient times h plus half the Hessian's enclosure times h^2, without the gradient's
interval: on the default (L, W, x) build's coefficients, 0.13 mm on cubes of 1/32 against the
mean-value form's 1.86 mm. The rounding of the jets is covered as for the mean-value form, by
the slack on the final bound.

Infeasibility at the margin
===========================

Let tol be the endpoint tolerance. Every trajectory of the family whose end pose q(T) puts the
tip within tol of P5 (and on the family's elbow branch, sign(theta2) = elbow) has clearance
at t = T at most

    U = max { c(q, O(L, W)) : |tip(q) - P5(L, W)| <= tol, sign(th2) = elbow, (L, W) in the cell },

and the same at P1. Where U < margin, no member of the family keeps both the endpoint
tolerance and the margin anywhere in the cell: the cell is *infeasible*. An upper bound on U:

* P5(L, W) lies within h_L / 2 of P5(centre), so the tips form a subset of the disc of radius
  rho = tol + h_L / 2 about P5(centre), itself inside the polar box r in [|P| - rho, |P| + rho],
  psi in [psi_P - asin(rho / |P|), psi_P + asin(rho / |P|)].
* On a polar sub-box the inverse kinematics is monotone: th2 = elbow acos((r^2 - l1^2 - l2^2) /
  (2 l1 l2)) is monotone in r; th1 = psi - beta(th2), beta = atan2(l2 sin th2, l1 + l2 cos th2),
  d beta / d th2 = l2 (l2 + l1 cos th2) / r^2, so beta is monotone between the zeros of
  l2 + l1 cos th2 (checked). So each sub-box maps into a box of (th1, th2).
* The obstacles of a cell are nested: the core rectangle R(L, W) = [-(L/2 - r), L/2 - r] x
  [d - W + r, d - r] grows with both L and W, so every obstacle of the cell [L0, L1] x [W0, W1]
  contains O0 = O(L0, W0), the obstacle of its smallest corner, and a pose's clearance against
  any obstacle of the cell is at most its clearance against O0 (distance to a superset is no
  larger). So the bound is taken against O0 alone and the obstacle's change across the cell
  costs nothing (the alternative, the centre's obstacle plus its Hausdorff motion
  sqrt((h_L / 2)^2 + h_W^2), costs about 0.06 mm on a 1/512 cell of the default range). O0 is formed
  from the cell's centre minus its half widths in floating point, a few ulps (1e-17 m) from the
  true corner; distance is 1-Lipschitz in that, and the float slack covers it.
* Over a (th1, th2) box with half widths (D1, D2) around q_m, links move by at most
  l1 D1 (link 1) and by the larger of the elbow's motion (l1 D1) and the tip's in Hausdorff
  distance (link 2); the tip stays in the polar sub-box, whose points are within
  (r_hi - r_lo) / 2 + r_hi (psi_hi - psi_lo) / 2 of its centre point (radial step then arc), so
  the tip moves by at most that plus |tip(q_m) - centre point| (and never more than
  l1 D1 + l2 (D1 + D2)). Distance being 1-Lipschitz,
  c(q, O) <= c(q, O0) <= min_k (c_k(q_m, O0) + move_k) + distance error.
* Sub-boxes whose sector misses the disc are dropped. The others are bisected (branch and
  bound for a maximum) until every bound is below the margin, or a sub-box centre, whose pose
  has its tip within tol of P(L0) and clears the margin against O0 (a feasible end pose at
  the cell's corner (L0, W0), which belongs to the closed cell: U >= margin, not infeasible;
  the pose with its tip exactly at P(L0) is tried first), or a depth limit; U is the largest
  bound left. A witness only stops the proof early, so it can cost tightness, never soundness.

The cell's length still enters the bound to first order: the disc grows by h_L / 2 (P moves
along x as L does), and O0 is the obstacle of the shortest L, while a pose near P(L1) is
compared with it. So for leaves close to the margin, :func:`infeasibility_upper_bounds` splits
the cell's length into sub-intervals (halving them where still unproven, several levels deep)
and bounds each; splitting W would not help (every sub-cell's bound is taken at its smallest
W, and the sub-cells at the cell's W0 have the cell's). The leaf is infeasible when every
sub-cell has one end (P1 or P5) with U < margin, and its bound is then the largest over the
sub-cells of the smaller of the two ends, a valid upper bound because the sub-cells cover the cell.

With the obstacle's centre x
============================

With an x axis the obstacle's footprint is [x - L/2, x + L/2] x [d - W, d] and P1..P5 keep their
offsets from it: P1 = (x + L/2 + dx1, y1), P5 = (x - (L/2 + dx1), y1). A cell is
[L0, L1] x [W0, W1] x [x0, x1] with centre (L_c, W_c, x_c) and half widths (h_L, h_W, h_x).

* Endpoint errors: P1 and P5 gain the term x in their x coordinate (a jet of the cell), and the
  mean-value form runs over the three axes; the joint angles' jets carry x through the
  regression's parameters (T does not depend on x).
* The disc: P(L, x) - P(L_c, x_c) = (+-(L - L_c) / 2 + (x - x_c), 0), of length at most
  h_L / 2 + h_x, so the tips form a subset of the disc of radius rho = tol + h_L / 2 + h_x about
  P(L_c, x_c); the polar boxes follow as above.
* The obstacle: the obstacles of a cell are no longer nested (x moves them sideways), but they
  share a common part. The core rectangle of O(L, W, x) is
  [x - L/2 + r, x + L/2 - r] x [d - W + r, d - r]; for L >= L0, W >= W0 and x0 <= x <= x1,
  x - L/2 + r <= x1 - L0/2 + r and x + L/2 - r >= x0 + L0/2 - r, so every core of the cell contains
  R* = [x1 - L0/2 + r, x0 + L0/2 - r] x [d - W0 + r, d - r], which is the core of the obstacle O* of
  length L* = L0 - 2 h_x, width W0 and centre x_c (x0 + x1 = 2 x_c, x1 - x0 = 2 h_x). Each obstacle
  is its core inflated by the same r, and inflating by a common radius keeps inclusion, so every
  obstacle of the cell contains O*; in terms of the clearance, c = dist(S, R) - r_k - r only
  decreases as R grows, so c(q, O(L, W, x)) <= c(q, O*) for every obstacle of the cell, and the
  bound is taken against O* alone. R* is empty once L* < 2 r; for L* <= 2 r the cell gets no
  bound (+inf: not infeasible). O* is formed from the cell's centre and half widths in floating
  point, a few ulps from the exact rectangle; the float slack covers it, as for O0.
* The witness must be a pose feasible for an actual obstacle of the cell, not for O* (which
  every obstacle contains, so a pose clearing it may hit all of them): it is taken at the corner
  (L0, W0, x0), a pose with its tip within tol of P(L0, x0) that clears the margin against
  O(L0, W0, x0). As before it only stops the proof early.
* A pose found with its tip in the disc that clears the margin against O* also ends the branch
  and bound of that end: every cover of the disc by sub-boxes has one holding that pose, whose
  bound is at least its clearance, so the end cannot be proven; the end's value is then the
  largest such clearance or bound found (>= margin: "not infeasible"). Cells whose bound cannot
  reach below the margin because of x then cost a few sub-boxes instead of the full depth.
* Sub-cells: the bound exceeds U by about h_L through the length (a tip near P5(L1) against the
  side of O0 at L0; the same at P1) and by about 2 h_x through x (the disc grows by h_x and the
  side of O* lies h_x inside the nearest obstacle's). Splitting W would not help, as above.
  :func:`infeasibility_upper_bounds` therefore halves, in each sub-cell, the length where
  h_L >= 2 h_x and x otherwise, and counts a sub-cell as beyond help above
  margin + 4 (h_L + 2 h_x) (without x: margin + 4 h_L); a sub-cell without a bound (L* <= 2 r)
  is split further.

With the obstacle's far edge d
==============================

With a d axis (only where y1 = d: ``RangeModel`` refuses d with a fixed ``start_y_m``) the
footprint is [x - L/2, x + L/2] x [d - W, d] and P1..P5 keep their offsets from it vertically too:
P1 = (x + L/2 + dx1, d), P5 = (x - (L/2 + dx1), d). A cell has half width h_d along d around d_c
and spans [d0, d1] (d0 + d1 = 2 d_c, d1 - d0 = 2 h_d); without an x axis read x = 0, h_x = 0 below.

* Endpoint errors: P1 and P5 take the jet d as their y coordinate (in place of the scene's y1),
  and the mean-value form runs over the axes; the joint angles' jets carry d through the
  regression's parameters (T does not depend on d).
* The disc: P(L, x, d) - P(L_c, x_c, d_c) = (+-(L - L_c) / 2 + (x - x_c), d - d_c), of length at
  most sqrt((h_L / 2 + h_x)^2 + h_d^2), so the tips form a subset of the disc of radius
  rho = tol + sqrt((h_L / 2 + h_x)^2 + h_d^2) <= tol + h_L / 2 + h_x + h_d about P(centre).
* The obstacle: for W >= W0 and d0 <= d <= d1 the core's y extent [d - W + r, d - r] contains
  [d1 - W0 + r, d0 - r] (d - W + r <= d1 - W0 + r and d - r >= d0 - r); together with the x
  extent above, every core of the cell contains
  R* = [x1 - L0/2 + r, x0 + L0/2 - r] x [d1 - W0 + r, d0 - r], the core of the obstacle O* of
  length L* = L0 - 2 h_x, width W* = W0 - 2 h_d and far edge d* = d0 = d_c - h_d (its y extent
  [d* - W* + r, d* - r] = [d1 - W0 + r, d0 - r]; its footprint's centre d_c - W0 / 2 is that of
  the obstacle of width W0 at the cell's d_c). As for x, inflation by the common r keeps the
  inclusion, so c(q, O(L, W, x, d)) <= c(q, O*) for every obstacle of the cell and the bound is
  taken against O* alone; R* is empty once L* < 2 r or W* < 2 r, and a cell with L* <= 2 r or
  W* <= 2 r gets no bound (+inf: not infeasible). O* is formed from the cell's centre and half
  widths in floating point, a few ulps (1e-17 m) from the exact rectangle; the float slack
  covers it.
* The witness is taken at the corner (L0, W0, x0, d0): a pose with its tip within tol of
  P(L0, x0, d0) that clears the margin against O(L0, W0, x0, d0), an actual obstacle of the cell.
  A pose with its tip in the disc clearing the margin against O* ends the end's branch and bound
  as for x (the obstacles of the cell are not nested once d varies, whether x does or not).
* Sub-cells: the bound exceeds U by about 2 h_d through d (the disc grows by up to h_d, and the
  top and bottom sides of O* lie h_d inside those of the obstacle at d_c). Each sub-cell halves
  the axis with the largest of h_L, 2 h_x and 2 h_d (the first on ties: L, then x, then d), and
  a sub-cell counts as beyond help above margin + 4 (h_L + 2 h_x + 2 h_d).

In the end's frame
==================

With an x axis, the bound above loses the cell's whole extent along u = x - L / 2 (at P5;
x + L / 2 at P1) twice over: the disc grows by h_L / 2 + h_x, and the near side of O* lies at the
largest u of the cell while a tip may sit at the end point of the smallest. Yet the end point and
the obstacle's near side move together: P5 = (u - dx1, y1) and the near side of O(L, W, x) is at
u, so what changes across the cell is only where the arm's base sits relative to them. So each end
is bounded over the cell in its own frame, on a cell that keeps one coordinate per end instead of
two (``end_frame_cells``):

* P5 of a point of the cell is (u - dx1, y1) with u in [u0, u1] = [x0 - L1 / 2, x1 - L0 / 2], of
  centre u_c = x_c - L_c / 2 and half width h_u = h_x + h_L / 2. The frame cell is the cell of
  length L0 (no extent), width W0 (no extent), centre x'_c = u_c + L0 / 2 and half width h_u, and
  the cell's d interval: its P5, x' - (L0 / 2 + dx1) for x' in [x'_c - h_u, x'_c + h_u], is
  exactly the cell's set of P5 (and its d the same), so its disc holds every tip the cell's poses
  at P5 may have.
* Its obstacle O* (the bound above, on the frame cell) has the x extent
  [x'_c - L0 / 2 + h_u, x'_c + L0 / 2 - h_u] = [u1, u0 + L0]. Every obstacle of the cell has the
  x extent [u, u + L] with u <= u1 and u + L >= u0 + L0 (u >= u0, L >= L0), so it contains that
  extent; its y extent contains O*'s as in the section on d, and W >= W0. So every obstacle of the
  cell contains O*, and the bound on the frame cell bounds U(P5) over the cell. Only the obstacle's
  far side (at u0 + L0, not at the cell's x0 + L0 / 2) is given up, which the pose at P5 does not
  approach.
* At P1 the same with v = x + L / 2 in [x0 + L0 / 2, x1 + L1 / 2]: the frame cell has centre
  x'_c = v_c - L0 / 2 and half width h_u, its O* the x extent [v1 - L0, v0] (within every
  [v - L, v] of the cell).
* The sub-cells then halve x' (or d) alone: each halving halves the extent along u that costs the
  bound, where cutting the cell along L and x halved one of its two terms.
* The frame cell is formed from the cell's centre and half widths in floating point, a few ulps
  (1e-17 m) from the exact interval; the float slack covers it, as for O*.
* A witness on the frame cell sits at the frame's corner (length L0, centre x'_0), which need not
  be a point of the cell: there it only stops the search (the end is then not proven), and the
  cell is never called feasible because of it.
* The cell is proven infeasible where one end's frame bound is below the margin. Unlike the
  sub-cells above, which take the smaller of the two ends per sub-cell, the frame does not
  combine P1 on part of the cell with P5 on the rest: over the (L, W, x) range the room at P1 is
  some 80 mm, so only P5 proves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.certify.clearance_bound import FLOAT_SLACK_M
from pipeline.certify.interval import Jet, lower_bound, upper_bound
from pipeline.certify.range_model import RangeModel
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import ANALYTIC_DISTANCE_ERROR_M, link_segments
from pipeline.geometry.segment_distance import segment_rectangle_distance

#: Cap on the polar sub-boxes alive at once in :func:`endpoint_clearance_upper_bounds`.
_MAX_SUB_BOXES = 400_000
#: Polar sub-boxes whose radial and arc extents are both below this [m] are not bisected
#: further (their bounds are valid as they are). It binds only where the tolerance is tiny
#: (exact-endpoints, tolerance 0: the disc is the cell's h_L / 2, some 1e-5 m, and its sub-boxes
#: went nine halvings deep, to 1e-10 m); with the 2 mm tolerance a ninth-level sub-box spans 8 um.
_POLAR_RESOLUTION_M = 1e-6

__all__ = [
    "end_frame_cells",
    "endpoint_bounds_and_shares",
    "endpoint_clearance_upper_bounds",
    "endpoint_error_bounds",
    "infeasibility_upper_bounds",
]


def _cells(model: RangeModel, center_m: np.ndarray, radius_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cell centres and half widths as float arrays (N, k), k = the model's axes."""
    center = np.asarray(center_m, dtype=float)
    radius = np.asarray(radius_m, dtype=float)
    if center.ndim != 2 or center.shape[1] != model.k or radius.shape != center.shape:
        raise InvalidParameterError(
            "center_m, radius_m", (center.shape, radius.shape), f"two arrays (N, {model.k}): {model.axes.names}"
        )
    return center, radius


def _end_error_jets(model: RangeModel, center2: np.ndarray, radius2: np.ndarray, second_order: bool = False):
    """Per end (s = 0 with P1, s = 1 with P5): the jets of the tip's error components at the
    centres and over the cells (with Hessians if ``second_order``), and the cells' half widths
    with s's (0) appended."""
    n = center2.shape[0]
    l1, l2 = model.link_lengths_m
    xi, di = model.x_column, model.d_column
    for s, side in ((0.0, 1.0), (1.0, -1.0)):
        center = np.column_stack([center2, np.full(n, s)])
        radius = np.column_stack([radius2, np.zeros(n)])
        comps = []
        for r, order in ((np.zeros_like(radius), 1), (radius, 2 if second_order else 1)):
            theta1, theta2 = model.joint_jets(center, r, order)
            phi2 = theta1 + theta2
            jets = model.variables(center, r, order)
            px = (jets[0] * 0.5 + model.scene.start_dx_m) * side
            if xi is not None:  # P1 and P5 move with the obstacle's centre x (module docstring)
                px = px + jets[xi]
            py = model.scene.y1_m if di is None else jets[di]  # y1 = d with a d axis
            ex = theta1.cos() * l1 + phi2.cos() * l2 - px
            ey = theta1.sin() * l1 + phi2.sin() * l2 - py
            comps.append((ex, ey))
        yield comps, radius


def endpoint_error_bounds(
    model: RangeModel, center_m: np.ndarray, radius_m: np.ndarray, second_order: bool = False
) -> np.ndarray:
    """Upper bounds [m] on |tip(0) - P1| and |tip(T) - P5| over cells of the model's axes, shape (N, 2).

    Args:
        model: The coefficients' range model.
        center_m: Cell centres (N, k): the axes (L, W[, x][, d]) [m].
        radius_m: Half widths (N, k) [m].
        second_order: Also take the second-order Taylor form and keep the tighter of the two
            per component (module docstring, "The second-order form").
    """
    return endpoint_bounds_and_shares(model, center_m, radius_m, second_order)[0]


def _component_magnitude(point: Jet, box: Jet, radius: np.ndarray) -> np.ndarray:
    """max |e| [m] over each cell of one error component: the mean-value form's interval, cut
    by the second-order Taylor form's where ``box`` carries a Hessian (``interval.lower_bound``)."""
    lo, hi = lower_bound(point, box, radius), upper_bound(point, box, radius)
    return np.maximum(np.abs(lo), np.abs(hi))


def endpoint_bounds_and_shares(
    model: RangeModel, center_m: np.ndarray, radius_m: np.ndarray, second_order: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`endpoint_error_bounds` (N, 2), and each axis's share [m] of the bound's gap over each
    cell (N, k): the larger over the two ends of the sum over the error's components of
    max |d e / d v_a| r_a, the mean-value form's term along axis a (which axis to cut to tighten
    the bound; not a bound itself)."""
    center2, radius2 = _cells(model, center_m, radius_m)
    out = np.empty((center2.shape[0], 2))
    shares = np.zeros(center2.shape)
    ends = _end_error_jets(model, center2, radius2, second_order)
    for column, (((px_, py_), (bx_, by_)), radius) in enumerate(ends):
        mag_x, mag_y = _component_magnitude(px_, bx_, radius), _component_magnitude(py_, by_, radius)
        out[:, column] = np.hypot(mag_x, mag_y) + FLOAT_SLACK_M
        shares = np.maximum(shares, ((bx_.grad.mag() + by_.grad.mag()) * radius)[:, : model.k])
    pinned = model.endpoints_pinned(center2, radius2)
    out[pinned] = FLOAT_SLACK_M  # exact by construction (RangeModel.endpoints_pinned), up to rounding
    return out, shares


def _beta(theta2: np.ndarray, l1: float, l2: float) -> np.ndarray:
    return np.arctan2(l2 * np.sin(theta2), l1 + l2 * np.cos(theta2))


def _beta_range(lo: np.ndarray, hi: np.ndarray, l1: float, l2: float) -> tuple[np.ndarray, np.ndarray]:
    """Range of beta(th2) over [lo, hi] (module docstring): ends, plus the turning points inside."""
    values = [_beta(lo, l1, l2), _beta(hi, l1, l2)]
    if l2 <= l1:  # turning points where l2 + l1 cos th2 = 0
        turn = math.acos(-l2 / l1)
        for t in (turn, -turn):
            inside = (lo <= t) & (t <= hi)
            values.append(np.where(inside, _beta(np.full_like(lo, t), l1, l2), values[0]))
    return np.minimum.reduce(values), np.maximum.reduce(values)


def _pose_box_upper_bounds(
    model: RangeModel,
    r_lo: np.ndarray,
    r_hi: np.ndarray,
    psi_lo: np.ndarray,
    psi_hi: np.ndarray,
    obstacle_lw: np.ndarray,
    witness_lw: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Upper bound on the clearance against the obstacles ``obstacle_lw`` over polar tip boxes,
    the clearance and tip of each box's centre pose, and that pose's clearance against
    ``obstacle_lw``.

    The obstacles are rows (n, 4) of L, W, centre x and far edge y d [m] (:func:`_cell_obstacles`).
    The centre pose's clearance (second value) is taken against ``witness_lw`` (same layout)
    if given, else against ``obstacle_lw`` (the fourth value then is the same array).
    """
    l1, l2 = model.link_lengths_m
    cos2 = lambda r: np.clip((r * r - l1 * l1 - l2 * l2) / (2 * l1 * l2), -1.0, 1.0)  # noqa: E731
    t2a, t2b = model.elbow * np.arccos(cos2(r_lo)), model.elbow * np.arccos(cos2(r_hi))
    t2_lo, t2_hi = np.minimum(t2a, t2b), np.maximum(t2a, t2b)
    b_lo, b_hi = _beta_range(t2_lo, t2_hi, l1, l2)
    t1_lo, t1_hi = psi_lo - b_hi, psi_hi - b_lo
    q_mid = np.stack([(t1_lo + t1_hi) / 2, (t2_lo + t2_hi) / 2], -1)
    d1, d2 = (t1_hi - t1_lo) / 2, (t2_hi - t2_lo) / 2
    elbow, tip = link_segments(q_mid, model.link_lengths_m)
    r_corner = model.scene.corner_radius_m

    def link_distances(obstacle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rect_center = np.stack([obstacle[:, 2], obstacle[:, 3] - obstacle[:, 1] / 2], -1)
        rect_half = np.stack([obstacle[:, 0] / 2 - r_corner, obstacle[:, 1] / 2 - r_corner], -1)
        c1 = segment_rectangle_distance(np.zeros_like(elbow), elbow, rect_center, rect_half) - model.link_radii_m[0]
        c2 = segment_rectangle_distance(elbow, tip, rect_center, rect_half) - model.link_radii_m[1]
        return c1, c2

    c1, c2 = link_distances(obstacle_lw)
    bound_centre = np.minimum(c1, c2) - r_corner
    centre_clearance = bound_centre if witness_lw is None else np.minimum(*link_distances(witness_lw)) - r_corner
    move1 = l1 * d1
    r_mid, p_mid = (r_lo + r_hi) / 2, (psi_lo + psi_hi) / 2
    sector_center = np.stack([r_mid * np.cos(p_mid), r_mid * np.sin(p_mid)], -1)
    tip_move = np.linalg.norm(tip - sector_center, axis=1) + (r_hi - r_lo) / 2 + r_hi * (psi_hi - psi_lo) / 2
    move2 = np.minimum(np.maximum(move1, tip_move), l1 * d1 + l2 * (d1 + d2))
    upper = np.minimum(c1 + move1, c2 + move2) - r_corner
    upper = upper + ANALYTIC_DISTANCE_ERROR_M + FLOAT_SLACK_M
    return upper, centre_clearance, tip, bound_centre


def _cell_obstacles(
    model: RangeModel, center: np.ndarray, radius: np.ndarray
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Per cell (centres, half widths (n, k) [m]): the obstacle every obstacle of the cell
    contains, as rows (n, 4) of L, W, centre x and far edge y d [m]; the obstacle a witness must
    clear (the cell's smallest corner's, same layout; None where it is the first one); and where
    the first is empty (no bound). Without x and d the obstacles are nested and both are the
    smallest corner's (L0, W0); with x or d, the first is O* of length L0 - 2 h_x, width
    W0 - 2 h_d, centre x_c and far edge d_c - h_d (module docstring)."""
    n = center.shape[0]
    xi, di = model.x_column, model.d_column
    corner = center - radius
    zeros, top = np.zeros(n), np.full(n, model.scene.top_y_m)
    if xi is None and di is None:
        return np.column_stack([corner[:, 0], corner[:, 1], zeros, top]), None, np.zeros(n, dtype=bool)
    length = corner[:, 0] if xi is None else corner[:, 0] - 2.0 * radius[:, xi]
    width = corner[:, 1] if di is None else corner[:, 1] - 2.0 * radius[:, di]
    common = np.column_stack(
        [length, width, zeros if xi is None else center[:, xi], top if di is None else center[:, di] - radius[:, di]]
    )
    witness = np.column_stack(
        [corner[:, 0], corner[:, 1], zeros if xi is None else corner[:, xi], top if di is None else corner[:, di]]
    )
    smallest = 2.0 * model.scene.corner_radius_m
    return common, witness, ~((length > smallest) & (width > smallest))


def _disc_radius(model: RangeModel, radius: np.ndarray, tolerance_m: float) -> np.ndarray:
    """rho [m] per cell (half widths (n, k) [m]): ``tolerance_m`` plus a bound on how far P1 (or
    P5) of a point of the cell lies from that of its centre, |(+-dL / 2 + dx, dd)| (module
    docstring): h_L / 2 (+ h_x) without d, the Euclidean sqrt((h_L / 2 + h_x)^2 + h_d^2) with it."""
    xi, di = model.x_column, model.d_column
    if di is None:
        rho = tolerance_m + radius[:, 0] / 2
        return rho if xi is None else rho + radius[:, xi]
    along_x = radius[:, 0] / 2 if xi is None else radius[:, 0] / 2 + radius[:, xi]
    return tolerance_m + np.hypot(along_x, radius[:, di])


def _sector_distance(
    radius: np.ndarray, angle: np.ndarray, r_lo: np.ndarray, r_hi: np.ndarray, p_lo: np.ndarray, p_hi: np.ndarray
) -> np.ndarray:
    """Distance from the point (radius, angle) (polar) to the annular sectors [r_lo, r_hi] x [p_lo, p_hi]
    (angles within pi/2 of each other)."""
    inside = (p_lo <= angle) & (angle <= p_hi)
    radial = np.maximum.reduce([r_lo - radius, radius - r_hi, np.zeros_like(radius)])
    edge = np.where(angle < p_lo, p_lo, p_hi)
    along = np.clip(radius * np.cos(angle - edge), r_lo, r_hi)
    to_edge = np.sqrt(np.maximum(radius**2 + along**2 - 2 * radius * along * np.cos(angle - edge), 0.0))
    return np.where(inside, radial, to_edge)


def endpoint_clearance_upper_bounds(
    model: RangeModel,
    center_m: np.ndarray,
    radius_m: np.ndarray,
    tolerance_m: float,
    margin_m: float,
    *,
    max_depth: int = 9,
) -> np.ndarray:
    """Upper bounds [m] on the clearance of every pose with its tip within ``tolerance_m`` of P1
    (column 0) or P5 (column 1), on the family's elbow branch, over cells of the model's axes
    (centres and half widths (N, k): L, W[, x][, d] [m]): shape (N, 2).

    The branch and bound stops proving once a bound is below ``margin_m`` or a pose is found
    that clears it, so values at or above the margin only mean "not infeasible" (module docstring).
    """
    return _upper_bounds_and_witnesses(model, center_m, radius_m, tolerance_m, margin_m, max_depth)[0]


def _upper_bounds_and_witnesses(
    model: RangeModel, center_m: np.ndarray, radius_m: np.ndarray, tolerance_m: float, margin_m: float, max_depth: int
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`endpoint_clearance_upper_bounds` (n, 2), and per cell and end whether a pose was
    found at the cell's smallest corner (L0, W0[, x0][, d0]) with its tip within the tolerance of
    that end and clearing the margin against that corner's obstacle (a witness: the end does not
    make the corner infeasible), (n, 2)."""
    center2, radius2 = _cells(model, center_m, radius_m)
    n = center2.shape[0]
    out = np.empty((n, 2))
    found = np.zeros((n, 2), dtype=bool)
    moved = model.x_column is not None or model.d_column is not None  # the obstacles of a cell are not nested
    corner = center2 - radius2
    obstacles = _cell_obstacles(model, center2, radius2)
    degenerate = obstacles[2]
    rho = _disc_radius(model, radius2, tolerance_m)
    for column, side in enumerate((1.0, -1.0)):
        disc = _EndDisc.at(model, center2, corner, rho, side)
        witnessed = _corner_witnesses(model, disc, obstacles, margin_m)
        best, floor = _polar_search(model, disc, obstacles, witnessed, (tolerance_m, margin_m), max_depth, moved)
        out[:, column] = np.where(witnessed, np.maximum(best, margin_m), best)
        if moved:
            out[:, column] = np.maximum(out[:, column], floor)
            out[degenerate, column] = np.inf
        found[:, column] = witnessed
    return out, found


@dataclass(frozen=True)
class _EndDisc:
    """Per cell, one end (P1 or P5) of the path: where it lies for the cell's centre and for its
    smallest corner, and the disc of the tips the end's poses may have (module docstring).

    Attributes:
        px, py: The end at the cell's centre [m].
        px0, py0: The end at the cell's smallest corner (L0[, x0][, d0]), where a witness must end [m].
        dist, psi: The end at the centre in polar form [m], [rad].
        rho: The disc's radius [m] (:func:`_disc_radius`).
        spread: The half angle [rad] under which the disc is seen from the base.
    """

    px: np.ndarray
    py: np.ndarray
    px0: np.ndarray
    py0: np.ndarray
    dist: np.ndarray
    psi: np.ndarray
    rho: np.ndarray
    spread: np.ndarray

    @classmethod
    def at(cls, model: RangeModel, center: np.ndarray, corner: np.ndarray, rho: np.ndarray, side: float) -> _EndDisc:
        """The end on ``side`` (+1: P1, -1: P5) of cells with centres ``center`` and smallest corners
        ``corner`` ((n, k) [m]) and disc radii ``rho`` [m]."""
        xi, di = model.x_column, model.d_column
        px = side * (center[:, 0] / 2 + model.scene.start_dx_m)
        px0 = side * (corner[:, 0] / 2 + model.scene.start_dx_m)
        if xi is not None:  # P1, P5 move with the obstacle's centre x
            px, px0 = px + center[:, xi], px0 + corner[:, xi]
        py = np.full(center.shape[0], model.scene.y1_m) if di is None else center[:, di]  # y1 = d with a d axis
        py0 = py if di is None else corner[:, di]
        dist = np.hypot(px, py)
        spread = np.arcsin(np.minimum(rho / dist, 1.0))
        return cls(px, py, px0, py0, dist, np.arctan2(py, px), rho, spread)


def _corner_witnesses(
    model: RangeModel, disc: _EndDisc, obstacles: tuple[np.ndarray, np.ndarray | None, np.ndarray], margin_m: float
) -> np.ndarray:
    """Per cell, whether the pose with its tip exactly at the end of the smallest corner
    P(L0[, x0][, d0]) clears ``margin_m`` [m] against that corner's obstacle O(L0, W0[, x0][, d0]):
    a witness. ``obstacles`` as :func:`_cell_obstacles` returns them."""
    bound_lw, witness_lw, _ = obstacles
    dist0, psi0 = np.hypot(disc.px0, disc.py0), np.arctan2(disc.py0, disc.px0)
    _, exact_c, _, _ = _pose_box_upper_bounds(model, dist0, dist0, psi0, psi0, bound_lw, witness_lw)
    return exact_c >= margin_m


def _polar_search(
    model: RangeModel,
    disc: _EndDisc,
    obstacles: tuple[np.ndarray, np.ndarray | None, np.ndarray],
    witnessed: np.ndarray,
    limits: tuple[float, float],
    max_depth: int,
    moved: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """The branch and bound over polar boxes (r, psi) of the tips of one end's poses, per cell: the
    upper bound [m] on their clearance, the boxes cut in quarters while it is at or above the margin
    and no witness is found (``witnessed`` updated in place), down to :data:`_POLAR_RESOLUTION_M`,
    ``max_depth`` or :data:`_MAX_SUB_BOXES`.

    Args:
        limits: (endpoint tolerance, clearance margin) [m].
        moved: Whether the cells move the obstacle (x or d axes): then :func:`_floored` applies.

    Returns:
        (the bound per cell [m], the floor per cell [m]: with x or d, the clearance against O* of a
        pose of the disc, -inf where none was found).
    """
    tolerance_m, margin_m = limits
    bound_lw, witness_lw, degenerate = obstacles
    n = disc.dist.size
    boxes = _initial_polar_boxes(disc, degenerate)
    best = np.full(n, -np.inf)
    floor = np.full(n, -np.inf)  # with x or d: the clearance against O* of a pose of the disc
    for depth in range(max_depth + 1):
        owner, r_lo, r_hi, p_lo, p_hi = boxes
        upper, centre_c, tip, bound_c = _pose_box_upper_bounds(
            model, r_lo, r_hi, p_lo, p_hi, bound_lw[owner], None if witness_lw is None else witness_lw[owner]
        )
        # A witness needs its tip within the tolerance of P(L0), the corner's own end point.
        in_set = np.hypot(tip[:, 0] - disc.px0[owner], tip[:, 1] - disc.py0[owner]) <= tolerance_m
        hit = in_set & (centre_c >= margin_m)
        np.logical_or.at(witnessed, owner[hit], True)
        # Sub-boxes of the polar box that miss the disc hold no pose of the set.
        gap = _sector_distance(disc.dist[owner], disc.psi[owner], r_lo, r_hi, p_lo, p_hi)
        upper = np.where(gap <= disc.rho[owner] * (1 + 1e-12), upper, -np.inf)
        open_ = (upper >= margin_m) & ~witnessed[owner]
        if moved:
            upper, open_ = _floored(disc, owner, (tip, bound_c), (upper, open_), floor, margin_m)
        closed = ~open_ | (depth == max_depth)
        np.maximum.at(best, owner[closed], upper[closed])
        fine = (r_hi - r_lo < _POLAR_RESOLUTION_M) & (r_hi * (p_hi - p_lo) < _POLAR_RESOLUTION_M)
        np.maximum.at(best, owner[open_ & fine], upper[open_ & fine])
        keep = open_ & ~fine & (depth < max_depth)
        if np.count_nonzero(keep) > _MAX_SUB_BOXES:  # memory cap: close the rest with their (valid) bounds
            np.maximum.at(best, owner[keep], upper[keep])
            keep[:] = False
        if not np.any(keep):
            break
        boxes = _quartered(tuple(a[keep] for a in boxes))
    return best, floor


def _initial_polar_boxes(disc: _EndDisc, degenerate: np.ndarray) -> tuple[np.ndarray, ...]:
    """One polar box per cell around its disc: (owner cell, r_lo, r_hi [m], psi_lo, psi_hi [rad]);
    none for the cells without O* (no bound: +inf)."""
    boxes = (
        np.arange(disc.dist.size),
        disc.dist - disc.rho,
        disc.dist + disc.rho,
        disc.psi - disc.spread,
        disc.psi + disc.spread,
    )
    if np.any(degenerate):
        boxes = tuple(a[~degenerate] for a in boxes)
    return boxes


def _floored(
    disc: _EndDisc,
    owner: np.ndarray,
    poses: tuple[np.ndarray, np.ndarray],
    boxes: tuple[np.ndarray, np.ndarray],
    floor: np.ndarray,
    margin_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """With x or d: a pose with its tip in the disc that clears the margin against O* keeps the bound
    at or above the margin however far the sub-boxes are cut (module docstring): the end is not
    proven, its value is its ``floor`` (raised in place) and its sub-boxes are closed.

    Args:
        disc: The end's disc per cell; ``owner`` the cell of each sub-box.
        poses: Each sub-box's centre pose's tip (m, 2) [m] and its clearance against O* [m].
        boxes: The sub-boxes' bounds [m] and which are open.
        margin_m: The clearance margin [m].

    Returns:
        The sub-boxes' bounds [m] and which stay open.
    """
    tip, bound_c = poses
    upper, open_ = boxes
    in_disc = np.hypot(tip[:, 0] - disc.px[owner], tip[:, 1] - disc.py[owner]) <= disc.rho[owner]
    stuck = in_disc & (bound_c >= margin_m)
    np.maximum.at(floor, owner[stuck], bound_c[stuck])
    blocked = floor[owner] >= margin_m
    return np.where(blocked, -np.inf, upper), open_ & ~blocked


def _quartered(boxes: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """Each polar box (owner, r_lo, r_hi [m], psi_lo, psi_hi [rad]) cut in four at its midpoints."""
    owner, r_lo, r_hi, p_lo, p_hi = boxes
    r_mid, p_mid = (r_lo + r_hi) / 2, (p_lo + p_hi) / 2
    return (
        np.repeat(owner, 4),
        np.stack([r_lo, r_lo, r_mid, r_mid], 1).ravel(),
        np.stack([r_mid, r_mid, r_hi, r_hi], 1).ravel(),
        np.stack([p_lo, p_mid, p_lo, p_mid], 1).ravel(),
        np.stack([p_mid, p_hi, p_mid, p_hi], 1).ravel(),
    )


def infeasibility_upper_bounds(
    model: RangeModel,
    center_m: np.ndarray,
    radius_m: np.ndarray,
    tolerance_m: float,
    margin_m: float,
    *,
    levels: int = 5,
    polar_depth: int = 9,
) -> np.ndarray:
    """Upper bounds [m] on min(U(P1), U(P5)) over cells by sub-cells (module docstring), shape
    (N,); +inf where the cell is not proven infeasible (a sub-cell at or above the margin after
    ``levels`` halvings, or one that clears the margin by more than its extents could explain:
    splitting it further would not help). Without an x axis the sub-cells halve the cell's length
    (and its d extent); with one, each end is bounded over the cell in its own frame (module
    docstring, "In the end's frame") and the cell is proven where one end is.

    Args:
        model: The coefficients' range model.
        center_m, radius_m: Cell centres and half widths (N, k): L, W[, x][, d] [m] (one cell
            may be given as a vector of k).
        tolerance_m: Endpoint tolerance [m].
        margin_m: Clearance margin [m].
        levels: Halvings of the sub-cells (1: two sub-cells per cell) [count].
        polar_depth: Depth of the polar branch and bound of each sub-cell
            (:func:`endpoint_clearance_upper_bounds`' ``max_depth``) [count].
    """
    center2, radius2 = _cells(model, np.atleast_2d(center_m), np.atleast_2d(radius_m))
    search = _SubCellSearch(model, (tolerance_m, margin_m), levels, polar_depth)
    if model.x_column is None:
        return search.run(center2, radius2, (0, 1))
    bounds = [search.run(*end_frame_cells(model, center2, radius2, side), (column,)) for column, side in _ENDS]
    return np.minimum(*bounds)


#: The ends as (column of the bounds, side): P1 at +(L / 2 + dx1), P5 at -(L / 2 + dx1).
_ENDS = ((0, 1.0), (1, -1.0))


def end_frame_cells(
    model: RangeModel, center: np.ndarray, radius: np.ndarray, side: float
) -> tuple[np.ndarray, np.ndarray]:
    """The cells (centres, half widths (n, k) [m]) of the end on ``side`` (+1: P1, -1: P5) in its
    own frame (module docstring, "In the end's frame"): length L0 and width W0 with no extent, x
    centred so that x +- L0 / 2 is the cell's centre of u = x +- L / 2, with half width h_x + h_L / 2;
    d as it is. Needs an x axis."""
    xi = model.x_column
    length = center[:, 0] - radius[:, 0]
    frame_c, frame_r = center.copy(), radius.copy()
    frame_c[:, 0], frame_r[:, 0] = length, 0.0
    frame_c[:, 1], frame_r[:, 1] = center[:, 1] - radius[:, 1], 0.0
    frame_c[:, xi] = center[:, xi] + side * (center[:, 0] - length) / 2
    frame_r[:, xi] = radius[:, xi] + radius[:, 0] / 2
    return frame_c, frame_r


@dataclass(frozen=True)
class _SubCellSearch:
    """The sub-cells of :func:`infeasibility_upper_bounds`: ``limits`` (endpoint tolerance,
    margin) [m], ``levels`` halvings, each sub-cell bounded by the polar branch and bound
    ``polar_depth`` deep."""

    model: RangeModel
    limits: tuple[float, float]
    levels: int
    polar_depth: int

    def run(self, center: np.ndarray, radius: np.ndarray, columns: tuple[int, ...]) -> np.ndarray:
        """Upper bounds [m] over the cells (centres, half widths (n, k)) of the smaller of the ends
        ``columns`` (0: P1, 1: P5) per sub-cell; +inf where not proven."""
        tolerance_m, margin_m = self.limits
        model = self.model
        # The axes beyond L that move the obstacle (x, d), each weighing 2 h against h_L (module docstring).
        moving = [column for column in (model.x_column, model.d_column) if column is not None]
        n = center.shape[0]
        worst = np.full(n, -np.inf)
        alive = np.ones(n, dtype=bool)
        owner = np.arange(n)
        for _ in range(self.levels):
            owner = np.repeat(owner, 2)
            center, radius = _halved(center, radius, moving)
            bounds, witnessed = _upper_bounds_and_witnesses(
                model, center, radius, tolerance_m, margin_m, self.polar_depth
            )
            upper = np.min(bounds[:, columns], axis=1)
            proven = upper < margin_m
            np.maximum.at(worst, owner[proven], upper[proven])
            # A sub-cell above the margin by more than its length terms (the disc's growth h_L / 2 and
            # the end point's motion h_L, module docstring, with room to spare) has feasible poses
            # within reach, and one with a witness at every end bounded has a point (its corner) where
            # those end poses clear the margin: the cell is not infeasible, and no cut can prove it so.
            terms = radius[:, 0] + sum(2.0 * radius[:, column] for column in moving)
            beyond = np.isfinite(upper) & (upper >= margin_m + 4.0 * terms)  # no bound (no O*): split further
            hopeless = ~proven & (beyond | np.all(witnessed[:, columns], axis=1))
            alive[owner[hopeless]] = False
            keep = ~proven & alive[owner]
            owner, center, radius = owner[keep], center[keep], radius[keep]
            if owner.size == 0:
                break
        alive[owner] = False  # sub-cells still unproven after the last level
        return np.where(alive, worst, np.inf)


def _halved(center: np.ndarray, radius: np.ndarray, moving: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Each cell (centres, half widths (n, k) [m]) cut in two along its length, or, with the axes
    ``moving`` (x, d), along the one with the largest of h_L, 2 h_x, 2 h_d, the first on ties
    (module docstring): the halves' centres and half widths (2n, k), each cell's two in a row."""
    k = center.shape[1]
    rows = np.arange(center.shape[0])
    weighed = np.column_stack([radius[:, 0], *(2.0 * radius[:, column] for column in moving)])
    axis = np.array([0, *moving])[np.argmax(weighed, axis=1)]
    step = np.zeros_like(radius)
    step[rows, axis] = radius[rows, axis] / 2
    return np.stack([center - step, center + step], 1).reshape(-1, k), np.repeat(radius - step, 2, axis=0)
