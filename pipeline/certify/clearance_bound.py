"""Rigorous lower bounds on the clearance of both links over boxes of (v, s), v the coefficients'
axes ((L, W), with the obstacle's centre x and / or its far edge y d if they vary them) and
s = t / T(L, W).

Geometry (``pipeline.obstacle``, ``pipeline.robot``): link k is a capsule, the segment
S_k = [a_k, b_k] (link 1: base -> elbow, link 2: elbow -> tip) inflated by its radius r_k; the
obstacle is the core rectangle R(L, W, x, d) = [x - (L/2 - r), x + L/2 - r] x [d - W + r, d - r]
inflated by the corner radius r, i.e. footprint [x - L/2, x + L/2] x [d - W, d] (x = 0 without an
x axis, d the scene's ``top_y_m`` without a d axis: the paper's scene). Because the arm and the
box are straight prisms over the same plane (the box is taller than the capsules), the 3-D
distance Coal computes is the planar one, and for positive clearance

    c_k = dist(S_k, R) - r_k - r        (the analytic route of ``pipeline.clearance``).

Where the capsule and the box meet, dist(S_k, R) - r_k - r <= 0 and Coal's value (a penetration
depth) is <= 0 too: every bound below is a lower bound on c_k, so a positive bound certifies
both the analytic and the Coal clearance (up to Coal's error, :data:`COAL_DISTANCE_ERROR_M`).

Every point p = (v, s) of a box X with centre c and half widths r (``radius``) has
joint angles theta(x) from :class:`pipeline.certify.range_model.RangeModel` (the regression's
parameters, T(L, W), the family's expansion); interval jets give enclosures of theta and of
d theta / d(L, W, s) over X. Three lower bounds are computed per link and box, and the largest
is kept (each is valid everywhere, so their maximum is):

(a) **Separating direction (dual form).** For any unit vector n,
    dist(S, R) >= min_{p in S} n.p - max_{q in R} n.q = min_{e in {a, b}, j} n.(e - v_j)
    (v_j the four vertices of R; linear functionals take their extremes at vertices). n is
    fixed per box as the direction of the closest pair at the centre c. Each of the eight
    n.(e(x) - v_j(x)) is a smooth function of x, bounded over X by the mean-value form
    f(p) >= f(c) - sum_i max_X |df/dp_i| r_i (arm and obstacle in one function, so that their
    common dependence on the axes is not counted twice). At the centre the bound equals the
    distance when the witness is a vertex of S (an endpoint) and by the envelope theorem its
    first-order change equals the distance's, so the gap shrinks quadratically with the box.
(b) **Supporting line of the link.** With m(p) = (-sin phi, cos phi) the unit normal of link k
    (phi = theta1, resp. theta1 + theta2) and sigma = +-1, if sigma m.(v_j - a) > 0 for all j,
    R lies on one side of the line through S and dist(S, R) >= dist(line, R) =
    min_j sigma m.(v_j - a); otherwise this is <= 0 <= dist. The bound is exact when the
    witness on S is interior (a corner of R against the side of the link), the case where (a)
    loses first order; again each m.(v_j - a) is bounded by its mean-value form.
(c) **Lipschitz form with the distance at the centre.** Distance is 1-Lipschitz in the Hausdorff
    motion of either body. Over X, the segment of link 1 moves by at most l1 |d theta1|
    (|e(x) - e(c)| = 2 l1 |sin(d theta1 / 2)|), link 2 by at most l1 |d theta1| + l2 |d(theta1 +
    theta2)| (the Hausdorff distance of two segments is at most the larger endpoint
    displacement), with |d theta| <= sum_i max_X |d theta / dp_i| r_i. The obstacle's core
    rectangle moves by at most sqrt((r_L / 2 + r_x)^2 + (r_W + r_d)^2) in Hausdorff distance
    (r_x = 0 without an x axis, r_d = 0 without a d axis), and the inflation by r does not
    increase that. Derivation: from the centre's (L, W, x, d) to (L + dL, W + dW, x + dx, d + dd)
    the core's corners move by (dx +- dL / 2, dd) (top corners, y = d - r) and (dx +- dL / 2,
    dd - dW) (bottom corners, y = d - W + r). Write each point of the first core bilinearly in
    its corners, (1 - a)(1 - b) v_00 + a (1 - b) v_10 + (1 - a) b v_01 + a b v_11 with a, b in
    [0, 1], and map it to the same combination of the moved corners: a bijection of the two
    cores that moves every point by at most the largest corner displacement (the weights are
    convex and the norm is convex), so the Hausdorff distance is at most that. With |dL| <= r_L, |dW| <= r_W,
    |dx| <= r_x, |dd| <= r_d, the x component is at most r_x + r_L / 2 and the y component at
    most max(|dd|, |dd - dW|) <= r_d + r_W, both reached at one corner (dx = r_x, dL = r_L,
    dd = -r_d, dW = r_W at the bottom right), hence the Euclidean of the two, not their max.
    So c_k(p) >= c_k(c) - motion - obstacle motion
    - distance error, with c_k(c) from the analytic route (``distance_error_m`` its bound) or
    from Coal (:data:`COAL_DISTANCE_ERROR_M`). This bound is first order; it guards the
    degenerate centres where (a) and (b) have no good direction.

**The second-order form** (``second_order=True``). The functions of (a) and (b) are smooth in
p: sines and cosines of the joint angles, themselves sines of polynomials in p and of s T(L, W)
with T smooth (``pipeline.certify.duration``), and the obstacle's vertices affine in p. So each
f also satisfies f(p) >= f(c) - sum_i |df/dp_i(c)| r_i - 1/2 sum_ij max_X |d2f/dp_i dp_j| r_i r_j
(Taylor's theorem with the Lagrange remainder; the Hessian enclosed over X by jets of order 2,
the gradient at c by the jets at the centre), and the larger of this and the mean-value form is
kept (``pipeline.certify.interval.lower_bound``). The mean-value form loses the gradient's
spread over X times r; the second-order form keeps the gradient at c and loses only the
curvature term, which on small boxes is much smaller (``python scripts/clearance_gap.py``).

Rounding: every bound is lowered by :data:`FLOAT_SLACK_M` (see ``pipeline.certify.interval``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.certify.interval import FLOAT_SLACK_M, Jet, lower_bound, upper_bound
from pipeline.certify.range_model import RangeModel
from pipeline.geometry.clearance import ANALYTIC_DISTANCE_ERROR_M, COAL_DISTANCE_ERROR_M
from pipeline.geometry.segment_distance import segment_rectangle_distance

__all__ = [
    "COAL_DISTANCE_ERROR_M",
    "FLOAT_SLACK_M",
    "BoxBounds",
    "box_clearance_bounds",
    "obstacle_motion_m",
    "point_clearance_m",
    "tightened_lower_m",
]


@dataclass(frozen=True, eq=False)
class BoxBounds:
    """Clearance bounds over N boxes of (L, W, s).

    Attributes:
        lower_m: Rigorous lower bound on the clearance of both links over each box [m], (N,).
        link_lower_m: The same per link [m], (N, 2).
        center_m: Analytic clearance (both links) at each box centre [m], (N,): a value the
            clearance takes, so no bound over the box can exceed it.
        split_s: True where the box's gap is dominated by its extent in s (bisect s first).
        axis_gap_m: Each axis's first-order share of the gap [m], (N, k): how far the tip moves
            and the obstacle's core moves over the box's extent along that axis alone; the axis
            to cut where the axes dominate (:mod:`pipeline.certify.search`).
    """

    lower_m: np.ndarray
    link_lower_m: np.ndarray
    center_m: np.ndarray
    split_s: np.ndarray
    axis_gap_m: np.ndarray


def obstacle_motion_m(
    radius_l_m: np.ndarray,
    radius_w_m: np.ndarray,
    radius_x_m: np.ndarray | None = None,
    radius_d_m: np.ndarray | None = None,
) -> np.ndarray:
    """Bound [m] on the Hausdorff distance by which the obstacle's core can move within
    L +- radius_l, W +- radius_w [m] (and its centre within x +- radius_x, its far edge within
    d +- radius_d [m]; None: fixed): sqrt((r_L / 2 + r_x)^2 + (r_W + r_d)^2) (module docstring, (c))."""
    half_l = 0.5 * np.asarray(radius_l_m)
    along_x = half_l if radius_x_m is None else half_l + np.asarray(radius_x_m)
    along_y = np.asarray(radius_w_m) if radius_d_m is None else np.asarray(radius_w_m) + np.asarray(radius_d_m)
    return np.hypot(along_x, along_y)


def _geometry(model: RangeModel, center: np.ndarray, radius: np.ndarray, order: int = 1) -> dict:
    """Jets of the joint angles, link endpoints and obstacle vertices over the boxes (of ``order``
    1, or 2 with Hessians)."""
    l1, l2 = model.link_lengths_m
    theta1, theta2 = model.joint_jets(center, radius, order)
    phi2 = theta1 + theta2
    c1, s1, c2, s2 = theta1.cos(), theta1.sin(), phi2.cos(), phi2.sin()
    elbow = (c1 * l1, s1 * l1)
    tip = (elbow[0] + c2 * l2, elbow[1] + s2 * l2)
    jets = model.variables(center, radius, order)
    L, W, n = jets[0], jets[1], len(jets)
    r, d = model.scene.corner_radius_m, model.scene.top_y_m
    half_x = L * 0.5 - r
    if model.d_column is not None:  # the moved far edge: y in [d - W + r, d - r]
        top_edge = jets[model.d_column]
        bottom, top = top_edge + W * (-1.0) + r, top_edge - r
    else:  # the scene's far edge
        bottom = W * (-1.0) + (d + r)
        top = Jet.constant(np.full(center.shape[0], d - r), n, order)
    if model.x_column is not None:  # the moved obstacle: [x - half_x, x + half_x]
        x = jets[model.x_column]
        right, left = x + half_x, x - half_x
    else:  # the paper's scene, centred on x = 0
        right, left = half_x, -half_x
    vertices = [(right, bottom), (right, top), (left, top), (left, bottom)]
    zero = Jet.constant(np.zeros(center.shape[0]), n, order)
    return {
        "theta": (theta1, phi2),
        "normals": ((-s1, c1), (-s2, c2)),
        "links": (((zero, zero), elbow), (elbow, tip)),
        "vertices": vertices,
    }


def _dot(n: np.ndarray, p: tuple[Jet, Jet]) -> Jet:
    return p[0] * n[:, 0] + p[1] * n[:, 1]


def _witness_directions(a: np.ndarray, b: np.ndarray, center: np.ndarray, half: np.ndarray) -> tuple:
    """Unit direction (N, 2) from the rectangle to the segment along their closest pair, and a validity mask."""
    lo, hi = center - half, center + half
    candidates = [p - np.clip(p, lo, hi) for p in (a, b)]
    ab = b - a
    length2 = np.maximum(np.sum(ab * ab, axis=1), 1e-300)
    for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        v = center + half * np.array([sx, sy])
        t = np.clip(np.sum((v - a) * ab, axis=1) / length2, 0.0, 1.0)
        candidates.append(a + t[:, None] * ab - v)
    stack = np.stack(candidates, axis=1)
    lengths = np.linalg.norm(stack, axis=2)
    best = np.argmin(lengths, axis=1)
    rows = np.arange(a.shape[0])
    vector, length = stack[rows, best], lengths[rows, best]
    touching = segment_rectangle_distance(a, b, center, half) <= 0.0
    valid = (length > 1e-12) & ~touching
    n = vector / np.where(valid, length, 1.0)[:, None]
    return n, valid


def box_clearance_bounds(
    model: RangeModel,
    center: np.ndarray,
    radius: np.ndarray,
    *,
    center_clearance_m: np.ndarray | None = None,
    distance_error_m: float = ANALYTIC_DISTANCE_ERROR_M,
    second_order: bool = False,
) -> BoxBounds:
    """Lower bounds on the clearance over boxes of (L, W, s) (module docstring).

    Args:
        model: The coefficients' range model.
        center: Box centres (N, k + 1): the axes [m] (L, W[, x][, d]), then s [-].
        radius: Half widths (N, k + 1), same units; boxes must lie in the fitted range and s in [0, 1].
        center_clearance_m: Per-link clearance (N, 2) [m] at each box centre's configuration
            and obstacle from another route (e.g. Coal through Pinocchio); default the analytic route.
        distance_error_m: Error bound of ``center_clearance_m`` [m] (Coal: COAL_DISTANCE_ERROR_M).
        second_order: Bound each function of (a) and (b) by the tighter of its mean-value and
            second-order Taylor forms (module docstring, "The second-order form"): tighter on
            small boxes, at one to two times the time (``python scripts/clearance_gap.py``).

    Returns:
        The :class:`BoxBounds`.
    """
    center = np.asarray(center, dtype=float)
    radius = np.asarray(radius, dtype=float)
    point = _geometry(model, center, np.zeros_like(radius))
    box = _geometry(model, center, radius, 2 if second_order else 1)
    r_corner = model.scene.corner_radius_m
    rect = _core_rectangle(model, center)
    x_col, d_col = model.x_column, model.d_column
    hausdorff = obstacle_motion_m(
        radius[:, 0],
        radius[:, 1],
        None if x_col is None else radius[:, x_col],
        None if d_col is None else radius[:, d_col],
    )
    link_lower = np.empty((center.shape[0], 2))
    segments, centre_values = _centre_clearances(model, point, rect)
    for k in (0, 1):
        a_c, b_c = segments[k]
        clearance_c = centre_values[:, k]
        inflate = model.link_radii_m[k] + r_corner
        bound_a = _separating_direction_bound(point, box, k, (a_c, b_c), rect, radius) - inflate
        bound_b = _supporting_line_bound(point, box, k, radius) - inflate
        given = clearance_c if center_clearance_m is None else np.asarray(center_clearance_m)[:, k]
        error = distance_error_m if center_clearance_m is not None else ANALYTIC_DISTANCE_ERROR_M
        bound_c = given - _link_motion_m(model, point, box, k, radius) - hausdorff - error
        link_lower[:, k] = np.maximum(np.maximum(bound_a, bound_b), bound_c) - FLOAT_SLACK_M
    lower = np.where(np.isnan(link_lower), -np.inf, link_lower)
    return BoxBounds(
        lower_m=np.min(lower, axis=1),
        link_lower_m=lower,
        center_m=np.min(centre_values, axis=1),
        split_s=_split_s(model, box, radius, hausdorff),
        axis_gap_m=_axis_gaps(model, box, radius),
    )


def point_clearance_m(model: RangeModel, points: np.ndarray) -> np.ndarray:
    """The analytic clearance of both links (the smaller) at points (N, k + 1) of (v, s) (the axes
    [m], then s [-]) [m], (N,): the value :func:`box_clearance_bounds` reports at a box centre."""
    points = np.asarray(points, dtype=float)
    point = _geometry(model, points, np.zeros_like(points))
    return np.min(_centre_clearances(model, point, _core_rectangle(model, points))[1], axis=1)


def _centre_clearances(model: RangeModel, point: dict, rect: tuple) -> tuple[list, np.ndarray]:
    """Per link, its segment (a, b) at the points of ``point`` (the geometry of zero-width boxes)
    and its analytic clearance there [m], (N, 2), against the core rectangle ``rect``."""
    segments, values = [], np.empty((rect[0].shape[0], 2))
    for k in (0, 1):
        pa, pb = point["links"][k]
        a = np.stack([pa[0].value.mid, pa[1].value.mid], -1)
        b = np.stack([pb[0].value.mid, pb[1].value.mid], -1)
        segments.append((a, b))
        values[:, k] = segment_rectangle_distance(a, b, *rect) - model.link_radii_m[k] - model.scene.corner_radius_m
    return segments, values


def tightened_lower_m(
    model: RangeModel, center: np.ndarray, radius: np.ndarray, lower_m: np.ndarray, rows: np.ndarray
) -> np.ndarray:
    """``lower_m`` (the mean-value form's bounds of the boxes ``center``, ``radius``, as
    :func:`box_clearance_bounds` gives them) with the boxes ``rows`` bounded by the second-order
    form too and the larger bound kept (both hold), in place; returned."""
    if len(rows):
        tighter = box_clearance_bounds(model, center[rows], radius[rows], second_order=True).lower_m
        lower_m[rows] = np.maximum(lower_m[rows], tighter)
    return lower_m


def _core_rectangle(model: RangeModel, center: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The obstacle's core rectangle at each box centre: its centre and half sizes, (N, 2) each [m]."""
    r_corner = model.scene.corner_radius_m
    x_col, d_col = model.x_column, model.d_column
    rect_x = np.zeros(center.shape[0]) if x_col is None else center[:, x_col]
    d = model.scene.top_y_m if d_col is None else center[:, d_col]
    rect_center = np.stack([rect_x, d - center[:, 1] / 2], -1)
    rect_half = np.stack([center[:, 0] / 2 - r_corner, center[:, 1] / 2 - r_corner], -1)
    return rect_center, rect_half


def _separating_direction_bound(
    point: dict,
    box: dict,
    k: int,
    segment: tuple[np.ndarray, np.ndarray],
    rect: tuple[np.ndarray, np.ndarray],
    radius: np.ndarray,
) -> np.ndarray:
    """Bound (a) of the module docstring on dist(S_k, R) [m] over each box, the separating direction
    fixed at the centre's closest pair (-inf where there is none): not yet less the inflation.

    Args:
        point, box: :func:`_geometry` at the centres and over the boxes.
        k: The link (0 or 1).
        segment: The link's ends at the centres, (N, 2) each [m].
        rect: The core rectangle's centres and half sizes, (N, 2) each [m].
        radius: The boxes' half widths.
    """
    (pa, pb), (ba, bb) = point["links"][k], box["links"][k]
    n, valid = _witness_directions(segment[0], segment[1], rect[0], rect[1])
    pairs = []
    for p_end, b_end in ((pa, ba), (pb, bb)):
        for pv, bv in zip(point["vertices"], box["vertices"], strict=True):
            p_jet = _dot(n, (p_end[0] - pv[0], p_end[1] - pv[1]))
            b_jet = _dot(n, (b_end[0] - bv[0], b_end[1] - bv[1]))
            pairs.append(lower_bound(p_jet, b_jet, radius))
    return np.where(valid, np.min(pairs, axis=0), -np.inf)


def _supporting_line_bound(point: dict, box: dict, k: int, radius: np.ndarray) -> np.ndarray:
    """Bound (b) of the module docstring on dist(S_k, R) [m] over each box, from the supporting line
    of link ``k`` (0 or 1): not yet less the inflation. ``point``, ``box``, ``radius`` as in
    :func:`_separating_direction_bound`."""
    (pa, _), (ba, _) = point["links"][k], box["links"][k]
    pm, bm = point["normals"][k], box["normals"][k]
    lows, highs = [], []
    for pv, bv in zip(point["vertices"], box["vertices"], strict=True):
        p_jet = pm[0] * (pv[0] - pa[0]) + pm[1] * (pv[1] - pa[1])
        b_jet = bm[0] * (bv[0] - ba[0]) + bm[1] * (bv[1] - ba[1])
        lows.append(lower_bound(p_jet, b_jet, radius))
        highs.append(upper_bound(p_jet, b_jet, radius))
    return np.maximum(np.min(lows, axis=0), -np.max(highs, axis=0))


def _link_motion_m(model: RangeModel, point: dict, box: dict, k: int, radius: np.ndarray) -> np.ndarray:
    """How far [m] link ``k``'s segment (0 or 1) moves over each box (bound (c) of the module docstring):
    l1 |d theta1|, and l1 |d theta1| + l2 |d(theta1 + theta2)| for link 2."""
    l1, l2 = model.link_lengths_m
    d_theta1 = np.sum(box["theta"][0].grad.mag() * radius, axis=1) + point["theta"][0].value.rad
    if k == 0:
        return l1 * d_theta1
    d_phi2 = np.sum(box["theta"][1].grad.mag() * radius, axis=1) + point["theta"][1].value.rad
    return l1 * d_theta1 + l2 * d_phi2


def _axis_gaps(model: RangeModel, box: dict, radius: np.ndarray) -> np.ndarray:
    """Per box and axis, the tip's motion over the box's extent along that axis plus the
    obstacle's core's (module docstring, bound (c): r_L / 2, r_W, r_x, r_d) [m], (N, k)."""
    l1, l2 = model.link_lengths_m
    k = model.k
    g1, g2 = box["theta"][0].grad.mag()[:, :k], box["theta"][1].grad.mag()[:, :k]
    gaps = (l1 * g1 + l2 * g2) * radius[:, :k]
    gaps[:, 0] += radius[:, 0] / 2
    gaps[:, 1:] += radius[:, 1:k]  # W, and x and d where they are axes: the core moves by their whole extent
    return gaps


def _split_s(model: RangeModel, box: dict, radius: np.ndarray, hausdorff: np.ndarray) -> np.ndarray:
    """Where the tip's motion along s [m] exceeds its motion along all the axes and the obstacle's
    (``hausdorff`` [m]) over the box: the boxes better split along s (:attr:`BoxBounds.split_s`)."""
    l1, l2 = model.link_lengths_m
    g1, g2 = box["theta"][0].grad.mag(), box["theta"][1].grad.mag()
    motion = l1 * g1 * radius + l2 * g2 * radius
    k = model.k
    axes_term = motion[:, 0]
    for i in range(1, k):
        axes_term = axes_term + motion[:, i]
    return motion[:, k] > axes_term + hausdorff
