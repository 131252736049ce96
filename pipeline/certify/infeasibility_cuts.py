"""Cuts along W at the infeasibility contour: the part of a cell above the contour proven
infeasible on its own, the rest left as it was.

A smallest cell that the infeasibility certificate leaves open often straddles the contour where
the end poses' room U crosses the margin: its upper part is infeasible, its lower part is not,
and the bound over the whole cell (taken at the obstacle of its smallest W) cannot prove the
upper part. Over (L, W, x) and (L, W, x, d) that contour runs across W (near W = 0.12 m the room
at P5 falls by about 0.67 mm per mm of W and changes little along the other axes), so the cell
is cut along W alone, at the lowest of its 2^E dyadic levels j / 2^E where the part above it is
proven:

* The part W in [W0 + j (W1 - W0) / 2^E, W1], every other axis as the cell's, is a box; the
  infeasibility certificate (``pipeline.certify.endpoints.infeasibility_upper_bounds``, each end in
  its frame where there is an x axis) bounds U over it like over any cell. A part proven below the
  margin is infeasible, whatever the search that chose it.
* The search, a choice of work: with every other axis held, U is non-increasing in W
  (``pipeline.certify.strip_split``: P1 and P5 do not depend on W and the obstacle grows with W), so
  the parts that can be proven are those above some level. Sampled poses at each end
  (``end_pose_room_m``) at the corners of a part's lower face are poses of points of that part:
  where one keeps the margin the part is not infeasible, nor is any part below it (each contains
  it), and the sampled room is non-increasing in W too, so a bisection finds the lowest level j_s
  without such a pose. The bound tries the part above j_s (j_s = 0: the whole cell); where that
  fails, the lowest part whose sampled room is :data:`_BOUND_GAP_M` below the margin (about what
  the bound exceeds the room by), then, once, halfway towards j_s if that was proven or towards
  the top if not. No step needs the bound to be monotone: the level kept is the lowest that was
  proven, and a level not tried costs tightness, never soundness.
* The proven part and the rest are stored as dyadic leaves of the subpaving, deeper along W only:
  [0, j) and [j, 2^E) in units of 2^-E of the cell's W interval, each a union of at most E
  dyadic intervals (``dyadic_pieces``). Every piece keeps its cell's clearance and endpoint bounds
  (valid over a subset); the pieces of the upper part get the part's infeasibility bound.
* Across the contour's tilt (``range_certificate.cut_at_infeasibility``): over (L, W, x, d) the
  room depends on the near edge d - W, so inside a cell the contour moves along W as d changes,
  and the part above the lowest level proven leaves a wedge below it unproven. A cell the contour
  crosses is halved first along the axis other than W across which the sampled room changes most
  (:func:`tilt_axes`, a choice of work), each half searched as above; a half keeps its cell's
  clearance, endpoint and infeasibility bounds (valid over a subset).
"""

from __future__ import annotations

import itertools

import numpy as np

from pipeline.certify.bisection import lowest_true
from pipeline.certify.end_pose_room import end_pose_room_m
from pipeline.certify.endpoints import infeasibility_upper_bounds
from pipeline.certify.range_model import RangeModel

#: Tips of the sampled poses that bound the levels worth proving from below: 2 circles (the end
#: point and the tolerance) of 72 angles, and how far above the margin they must clear [m].
_ROOM_RINGS = 2
_ROOM_ANGLES = 72
_ROOM_SLACK_M = 1e-6
#: How far the infeasibility bound of a part typically lies above its sampled room [m] (where the
#: search tries first; a choice of work).
_BOUND_GAP_M = 3e-5

__all__ = ["cut_leaves", "dyadic_pieces", "lowest_infeasible_cuts", "tilt_axes"]


def _upper_parts(center: np.ndarray, radius: np.ndarray, j: np.ndarray, cuts: int) -> tuple[np.ndarray, np.ndarray]:
    """The parts W >= W0 + j (W1 - W0) / 2^cuts of cells (centres, half widths (n, k) [m]), as
    centres and half widths."""
    w0, w1 = center[:, 1] - radius[:, 1], center[:, 1] + radius[:, 1]
    low = w0 + (w1 - w0) * (j / 2.0**cuts)
    part_c, part_r = center.copy(), radius.copy()
    part_c[:, 1], part_r[:, 1] = (low + w1) / 2, (w1 - low) / 2
    return part_c, part_r


def _face_room(
    model: RangeModel, center: np.ndarray, radius: np.ndarray, j: np.ndarray, cuts: int, tolerance_m: float
) -> np.ndarray:
    """Per cell (centres, half widths (n, k) [m]), the largest sampled room [m] at the corners of
    the lower face of its part above level ``j`` (every axis but W at either end): points of that
    part."""
    part_c, part_r = _upper_parts(center, radius, j, cuts)
    corner = part_c - part_r
    others = [axis for axis in range(model.k) if axis != 1]
    room = np.full(center.shape[0], -np.inf)
    for ends in itertools.product((0.0, 2.0), repeat=len(others)):
        point = corner.copy()
        for axis, end in zip(others, ends, strict=True):
            point[:, axis] += end * part_r[:, axis]
        room = np.maximum(room, _sampled_room(model, point, tolerance_m))
    return room


def _sampled_room(model: RangeModel, point_m: np.ndarray, tolerance_m: float) -> np.ndarray:
    """The end poses' sampled room [m] at points (n, k) of the axes (``end_pose_room_m`` with this
    module's rings and angles, the obstacle moved by x and d where they are axes)."""
    return end_pose_room_m(
        model,
        point_m[:, 0],
        point_m[:, 1],
        tolerance_m,
        rings=_ROOM_RINGS,
        angles=_ROOM_ANGLES,
        **model.obstacle_moves(point_m),
    )


def _lowest_short(
    model: RangeModel, center: np.ndarray, radius: np.ndarray, cuts: int, tolerance_m: float, below_m: float
) -> np.ndarray:
    """Per cell, the lowest level j in [0, 2^cuts] whose part's lower face has no sampled pose at
    each end with room at least ``below_m`` [m] (2^cuts: even the top part's has one), by
    bisection (the sampled room is non-increasing in W: module docstring)."""
    n, top = center.shape[0], 2**cuts - 1
    lo, hi = np.zeros(n, dtype=np.int64), np.full(n, top)
    roomy = _face_room(model, center, radius, hi, cuts, tolerance_m) >= below_m
    lo[roomy] = hi[roomy] = top + 1  # most cells: even the top part has such a pose
    return lowest_true(
        lo, hi, lambda rows, j: _face_room(model, center[rows], radius[rows], j, cuts, tolerance_m) < below_m
    )


def lowest_infeasible_cuts(
    model: RangeModel,
    center_m: np.ndarray,
    radius_m: np.ndarray,
    cuts: int,
    tolerance_m: float,
    margin_m: float,
) -> np.ndarray:
    """Per cell (centres, half widths (n, k) [m]), the lowest level j in [0, 2^cuts) at which the
    part of the cell above W0 + j (W1 - W0) / 2^cuts was proven infeasible (0: the whole cell) among
    the levels tried, and that part's bound [m] (module docstring), as an (n, 2) array of floats:
    (2^cuts, +inf) where none was."""
    center = np.asarray(center_m, dtype=float).reshape(-1, model.k)
    radius = np.asarray(radius_m, dtype=float).reshape(-1, model.k)
    n, top = center.shape[0], 2**cuts - 1
    out = np.column_stack([np.full(n, float(top + 1)), np.full(n, np.inf), np.full(n, float(top + 1))])
    if n == 0:
        return out

    def proven(rows: np.ndarray, j: np.ndarray) -> np.ndarray:
        if rows.size == 0:
            return np.zeros(0, dtype=bool)
        part_c, part_r = _upper_parts(center[rows], radius[rows], j, cuts)
        bound = infeasibility_upper_bounds(model, part_c, part_r, tolerance_m, margin_m)
        ok = bound < margin_m
        out[rows[ok], :2] = np.column_stack([j[ok], bound[ok]])
        return ok

    floor = _lowest_short(model, center, radius, cuts, tolerance_m, margin_m + _ROOM_SLACK_M)
    out[:, 2] = floor
    tried = np.flatnonzero(floor <= top)
    tried = tried[~proven(tried, floor[tried])]  # proven at the floor: the lowest level there can be
    # Then the lowest level whose sampled room is _BOUND_GAP_M below the margin, and once more
    # halfway towards the floor if proven, towards the top if not (module docstring).
    guess = np.minimum(
        _lowest_short(model, center[tried], radius[tried], cuts, tolerance_m, margin_m - _BOUND_GAP_M), top
    )
    guess = np.maximum(guess, floor[tried] + 1)
    tried, guess = tried[guess <= top], guess[guess <= top]
    ok = proven(tried, guess)
    lower = (floor[tried[ok]] + guess[ok] + 1) // 2
    proven(tried[ok][lower < guess[ok]], lower[lower < guess[ok]])
    higher = (guess[~ok] + top + 1) // 2
    proven(tried[~ok][higher > guess[~ok]], higher[higher > guess[~ok]])
    return out


def tilt_axes(model: RangeModel, center_m: np.ndarray, radius_m: np.ndarray, tolerance_m: float) -> np.ndarray:
    """Per cell (centres, half widths (n, k) [m]), the axis other than W across which the sampled
    room of the end poses changes most between the cell's two faces (the other axes at the
    centre): the axis that tilts the infeasibility contour across the cell, whose halves a cut
    along W resolves best. A choice of work (module docstring); k = 2: L."""
    center = np.asarray(center_m, dtype=float).reshape(-1, model.k)
    radius = np.asarray(radius_m, dtype=float).reshape(-1, model.k)
    others = [axis for axis in range(model.k) if axis != 1]
    change = np.zeros((center.shape[0], len(others)))
    for column, axis in enumerate(others):
        step = np.zeros_like(center)
        step[:, axis] = radius[:, axis]
        rooms = [_sampled_room(model, center + sign * step, tolerance_m) for sign in (-1.0, 1.0)]
        change[:, column] = np.abs(rooms[1] - rooms[0])
    return np.asarray(others, dtype=np.int64)[np.argmax(change, axis=1)]


def dyadic_pieces(start: int, stop: int, cuts: int) -> list[tuple[int, int]]:
    """The interval [start, stop) of units of 2^-cuts as the fewest dyadic intervals, each as (its
    level below the whole, its index at that level), in order along the interval."""
    pieces = []
    while start < stop:
        size = start & -start if start else 1 << cuts  # the largest power of two that divides start
        while start + size > stop:
            size //= 2
        level = cuts - size.bit_length() + 1
        pieces.append((level, start // size))
        start += size
    return pieces


def cut_leaves(
    levels: np.ndarray, index: np.ndarray, cut: np.ndarray, cuts: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Leaves of the subpaving (levels, index (n, k)) cut along W at their levels ``cut`` (n,) of
    2^``cuts`` (module docstring): per piece, the row of its leaf, its levels and index (m, k), and
    whether it lies above the cut (the proven part); the pieces of each leaf in order along W."""
    rows, depth, at, above = [], [], [], []
    for row, j in enumerate(np.asarray(cut, dtype=np.int64).tolist()):
        for is_above, (start, stop) in ((False, (0, j)), (True, (j, 2**cuts))):
            for level, piece in dyadic_pieces(start, stop, cuts):
                rows.append(row)
                depth.append(level)
                at.append(piece)
                above.append(is_above)
    rows_ = np.asarray(rows, dtype=np.int64)
    piece_levels, piece_index = levels[rows_].copy(), index[rows_].copy()
    depth_, at_ = np.asarray(depth, dtype=piece_levels.dtype), np.asarray(at, dtype=piece_index.dtype)
    piece_index[:, 1] = piece_index[:, 1] * (2**depth_).astype(piece_index.dtype) + at_
    piece_levels[:, 1] += depth_
    return rows_, piece_levels, piece_index, np.asarray(above, dtype=bool)
