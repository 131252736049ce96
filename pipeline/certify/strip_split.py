"""Strips along W: the smallest cells that straddle a contour, cut along W alone and proven strip
by strip (leaves of the subpaving whose W level is deeper than their other axes').

Where the map misses the margin without proving infeasibility, its leaves sit at the smallest
cell astride one of two contours: where the coefficients' clearance crosses the margin, or where
the end poses' room does (the infeasibility contour). On the default build both run along L
near W = 0.12 m (as W grows the obstacle's corner nears the arm's pose at P5; the room falls by
about 0.67 mm per mm of W there and changes little along L), so a cut along W separates them
where a cut along L would not, and 2^E strips cost 2^E, not 4^E, times the leaves.

Over more axes (x, d) the same holds with the other axes held: a strip keeps its leaf's interval
on every axis but W, and a column is the strips that share those intervals (over (L, W, x) the
band lies near W = 0.12 m too, python scripts/margin_band.py).

Each strip (the leaf's interval on every axis but W, W in one 2^-E of it) gets:

* a clearance lower bound, by branch and bound over s alone on the boxes strip x [s interval]
  (``clearance_bound.box_clearance_bounds``, whose docstring derives the bound): an interval
  is halved while its bound is below the margin, until the clearance at an interval's centre
  is below the margin (a value the clearance takes: the strip cannot be certified at the
  margin; its open intervals are closed with their bounds as they are), the deepest s interval,
  or an interval whose bound's gap is dominated by the strip's extent in (L, W) rather than in
  s (``BoxBounds.split_s``: cutting s would not close it; the clearance search's rule at its
  deepest cells). The strip's bound is the minimum over the closed intervals, which cover s in
  [0, 1], or the parent leaf's bound where that is larger: both are valid lower bounds over
  the strip, which lies in the leaf.
* its endpoint-error bound (``endpoints.endpoint_error_bounds`` over the strip);
* an infeasibility bound, from the monotonicity of the infeasibility in W: P1 and P5 depend on
  L and, where they are axes, on the centre x and the far edge d, never on W; and with L, x and
  d held the obstacle O grows with W (its core rectangle is [x - (L/2 - r), x + L/2 - r] x
  [d - W + r, d - r]), so a pose clears O(L, W', x, d) by at most what it clears O(L, W, x, d)
  for W' > W. Hence the room U = max{c(q, O) : tip(q) within the tolerance of P1 (or P5)} is
  non-increasing in W with the other axes held, and an upper bound on U over one strip bounds U
  over every strip above it in its column (each of their points lies above a point of the
  proven strip with the same L, x and d). The strips of all cut cells of one column (one
  interval per axis but W, at the deepest level) are taken together, W ascending: the
  certificate finds, by bisection, the lowest strip whose sampled room at its lower edge
  (``pipeline.certify.end_pose_room``, the largest of its values at the corners of that face:
  (L0, W0) and (L1, W0) over (L, W); monotone in W for the same reason) is :data:`ROOM_SLACK_M`
  below the margin, bounds it and the strip above it by ``endpoints.infeasibility_upper_bounds``
  (:data:`SUB_CELL_LEVELS` halvings of the length, the polar branch and bound
  :data:`POLAR_DEPTH` levels deep), and gives the lower proven one's bound to it and to every
  strip above it in the column. The sampling only chooses which strips to try: a wrong choice
  costs proofs, never soundness. At the default 9 polar levels the bound is loose by about the
  width of a strip in clearance (at three obstacles of the default build's strip, point cells,
  it proved the sampled room + 20 um at 9 levels, + 5 um at 11 and + 2 um at 13, where the
  room changes by 3 um across a strip of 1/8192 of the range).
"""

from __future__ import annotations

import itertools

import numpy as np

from pipeline.certify.bisection import lowest_true
from pipeline.certify.clearance_bound import box_clearance_bounds, tightened_lower_m
from pipeline.certify.end_pose_room import end_pose_room_m
from pipeline.certify.endpoints import endpoint_error_bounds, infeasibility_upper_bounds
from pipeline.certify.range_model import RangeModel

#: Depth of the polar branch and bound of the strips' infeasibility bounds, halvings of their
#: length (``endpoints.infeasibility_upper_bounds``' ``polar_depth`` and ``levels``), and how far
#: below the margin the sampled room of the first strip tried must be [m]. Measured on the 363
#: strips of the default build's map: with 4 levels and depth 11, 19.5 ms per strip, all strips
#: proven whose sampled room is more than 12 um below the margin, 93 % of those 8-12 um below,
#: none of those less than 8 um below; with 5 levels 26.6 ms, 57 % of those 5-8 um below.
POLAR_DEPTH = 11
SUB_CELL_LEVELS = 4
ROOM_SLACK_M = 8e-6
#: Depth of the starting grid in s of each strip (as the clearance search's).
_INITIAL_DEPTH_S = 4

__all__ = [
    "POLAR_DEPTH",
    "ROOM_SLACK_M",
    "SUB_CELL_LEVELS",
    "cell_clearance_bounds",
    "strip_bounds",
    "strip_clearance_bounds",
    "strip_infeasibility_bounds",
]


def strip_clearance_bounds(
    model: RangeModel,
    center_m: np.ndarray,
    radius_m: np.ndarray,
    floor_m: np.ndarray,
    margin_m: float,
    max_depth_s: int,
    *,
    second_order: bool = False,
) -> np.ndarray:
    """Lower bounds [m] on the clearance of both links over cells (centres, half widths (n, k))
    times all of s in [0, 1] (module docstring), each at least ``floor_m`` (a valid bound known
    beforehand), shape (n,). With ``second_order`` a box the mean-value form leaves below the
    margin while its centre keeps it is bounded by the second-order form too, the larger bound
    kept (both hold: ``clearance_bound``)."""
    return cell_clearance_bounds(model, center_m, radius_m, floor_m, margin_m, max_depth_s, second_order=second_order)[
        0
    ]


def cell_clearance_bounds(
    model: RangeModel,
    center_m: np.ndarray,
    radius_m: np.ndarray,
    floor_m: np.ndarray,
    margin_m: float,
    max_depth_s: int,
    *,
    second_order: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`strip_clearance_bounds`, and per cell whether the clearance at the centre of every
    box bounded kept the margin (False: the cell holds a point below the margin, no cut of it
    can be proven at the margin everywhere)."""
    center2 = np.asarray(center_m, dtype=float).reshape(-1, model.k)
    radius2 = np.asarray(radius_m, dtype=float).reshape(-1, model.k)
    n = center2.shape[0]
    m = 2**_INITIAL_DEPTH_S
    owner = np.repeat(np.arange(n), m)
    depth_s = np.full(owner.size, _INITIAL_DEPTH_S, dtype=np.int64)
    index_s = np.tile(np.arange(m, dtype=np.int64), n)
    worst = np.full(n, np.inf)
    hopeful = np.ones(n, dtype=bool)
    while owner.size:
        half_s = 0.5 / 2.0 ** depth_s.astype(float)
        center = np.column_stack([center2[owner], (2 * index_s + 1) * half_s])
        radius = np.column_stack([radius2[owner], half_s])
        bounds = box_clearance_bounds(model, center, radius)
        rows = np.flatnonzero((bounds.lower_m < margin_m) & (bounds.center_m >= margin_m)) if second_order else []
        tightened_lower_m(model, center, radius, bounds.lower_m, rows)
        hopeful[owner[bounds.center_m < margin_m]] = False
        # Closed too: boxes whose gap is dominated by the strip's extent in (L, W), which cutting s cannot help.
        done = (bounds.lower_m >= margin_m) | (depth_s >= max_depth_s) | ~hopeful[owner] | ~bounds.split_s
        np.minimum.at(worst, owner[done], bounds.lower_m[done])
        keep = np.flatnonzero(~done)
        owner = np.repeat(owner[keep], 2)
        depth_s = np.repeat(depth_s[keep] + 1, 2)
        index_s = (2 * index_s[keep][:, None] + np.array([0, 1])).ravel()
    return np.maximum(worst, np.asarray(floor_m, dtype=float)), hopeful


def _lower_edge_room_m(model: RangeModel, corner_m: np.ndarray, side_m: np.ndarray, tolerance_m: float) -> np.ndarray:
    """Sampled room [m] at the lower W edge of strips (lowest corners and side lengths (n, k)): the
    largest of ``end_pose_room_m`` at the corners of that face, every axis but W at either end
    (over (L, W): (L0, W0) and (L1, W0)), with the obstacle moved by x and d where they are axes."""
    others = [axis for axis in range(model.k) if axis != 1]
    room = np.full(corner_m.shape[0], -np.inf)
    for ends in itertools.product((0.0, 1.0), repeat=len(others)):
        point = corner_m.copy()
        for axis, end in zip(others, ends, strict=True):
            point[:, axis] += end * side_m[:, axis]
        moves = model.obstacle_moves(point)
        room = np.maximum(room, end_pose_room_m(model, point[:, 0], point[:, 1], tolerance_m, **moves))
    return room


def _lowest_short_strips(
    model: RangeModel,
    corner_m: np.ndarray,
    side_m: np.ndarray,
    starts: np.ndarray,
    margin_m: float,
    tolerance_m: float,
) -> np.ndarray:
    """Per column (strips ``starts[c]`` to ``starts[c + 1]`` - 1, W ascending), the index of the
    lowest strip whose sampled room at its lower edge (:func:`_lower_edge_room_m`) is below
    margin - :data:`ROOM_SLACK_M`; the column's end if none. By bisection: that room is
    non-increasing in W (module docstring)."""
    floor_m = margin_m - ROOM_SLACK_M
    return lowest_true(
        starts[:-1], starts[1:], lambda _, j: _lower_edge_room_m(model, corner_m[j], side_m[j], tolerance_m) < floor_m
    )


def strip_infeasibility_bounds(
    model: RangeModel,
    center_m: np.ndarray,
    radius_m: np.ndarray,
    column: np.ndarray,
    margin_m: float,
    tolerance_m: float,
) -> np.ndarray:
    """Upper bounds [m] on the end poses' room over strips sorted by ``column`` (strips of one
    column share their interval on every axis but W), W ascending within a column (module
    docstring): below the margin on the strips proven infeasible, +inf on the others, shape (n,)."""
    center2 = np.asarray(center_m, dtype=float).reshape(-1, model.k)
    radius2 = np.asarray(radius_m, dtype=float).reshape(-1, model.k)
    column = np.asarray(column)
    n = center2.shape[0]
    out = np.full(n, np.inf)
    if n == 0:
        return out
    starts = np.concatenate([[0], np.flatnonzero(np.diff(column)) + 1, [n]])
    ends = starts[1:]
    first = _lowest_short_strips(model, center2 - radius2, 2 * radius2, starts, margin_m, tolerance_m)
    candidates = np.concatenate([first[first < ends], (first + 1)[first + 1 < ends]])
    if candidates.size == 0:
        return out
    upper = infeasibility_upper_bounds(
        model,
        center2[candidates],
        radius2[candidates],
        tolerance_m,
        margin_m,
        levels=SUB_CELL_LEVELS,
        polar_depth=POLAR_DEPTH,
    )
    # The lowest proven candidate of each column bounds it and every strip above it in the column.
    owner = np.searchsorted(starts, candidates, side="right") - 1
    lowest = ends.copy()
    bound = np.full(ends.size, np.inf)
    for row in np.flatnonzero(upper < margin_m):
        c = owner[row]
        if candidates[row] < lowest[c]:
            lowest[c], bound[c] = candidates[row], upper[row]
    strip_column = np.searchsorted(starts, np.arange(n), side="right") - 1
    above = np.arange(n) >= lowest[strip_column]
    out[above] = bound[strip_column[above]]
    return out


def strip_bounds(
    model: RangeModel,
    center_m: np.ndarray,
    radius_m: np.ndarray,
    floor_m: np.ndarray,
    column: np.ndarray,
    margin_m: float,
    tolerance_m: float,
    max_depth_s: int,
    second_order: bool = False,
) -> np.ndarray:
    """Per strip (centres, half widths (n, k) [m], sorted by ``column``, W ascending within a
    column; ``floor_m`` its cell's clearance bound): the clearance bound (with ``second_order``
    the tighter of both forms, :func:`strip_clearance_bounds`), the endpoint-error bound and the
    infeasibility bound (+inf where not proven), as columns of an (n, 3) array [m]. Strips proven
    infeasible keep their cell's clearance bound (their status is settled unless that bound
    reaches the margin)."""
    center2 = np.asarray(center_m, dtype=float).reshape(-1, model.k)
    radius2 = np.asarray(radius_m, dtype=float).reshape(-1, model.k)
    floor = np.asarray(floor_m, dtype=float)
    out = np.empty((center2.shape[0], 3))
    out[:, 2] = strip_infeasibility_bounds(model, center2, radius2, column, margin_m, tolerance_m)
    out[:, 1] = np.max(endpoint_error_bounds(model, center2, radius2), axis=1)
    out[:, 0] = floor
    open_ = out[:, 2] >= margin_m
    if np.any(open_):
        out[open_, 0] = strip_clearance_bounds(
            model, center2[open_], radius2[open_], floor[open_], margin_m, max_depth_s, second_order=second_order
        )
    return out
