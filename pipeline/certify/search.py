"""Branch and bound over dyadic boxes of the coefficients' axes x s for the clearance range certificate.

The fitted box of the k axes ((L, W), or (L, W, x): ``RangeModel.axes``) is the root of a
2^k-tree (node = (depth, i_1..i_k), side 1 / 2^depth of the range on every axis; a quadtree for
(L, W)); s in [0, 1] is cut dyadically as well (depth_s, j).
A box is one node times one s interval. Each round bounds every open box
(:func:`pipeline.certify.clearance_bound.box_clearance_bounds`) and closes it when

* its bound reaches the margin; or
* the margin is out of reach in its node (the clearance at the box centre, a value the
  clearance takes there, is below the margin), its bound is positive and within
  ``resolution_m`` of that centre value, or the centre itself is in collision, its node is
  at the boundary depth (so the region map resolves where the margin or the clearance is
  lost), and the centre lies below the margin by more than the bound's gap below the centre
  (2 centre - bound < margin: the clearance rises above its centre value by about as much as
  it falls below it, so the node most likely holds no point at the margin); a node closer to
  the margin is cut on, to the smallest cell, so the map resolves the margin's contour at the
  smallest cell from both sides (measured on the default build: with nodes closed at the
  boundary depth wherever their centre missed the margin, the leaves beside the contour
  inherited bounds 0.23 mm (median) below their own clearance); or
* it cannot be cut further (both depths at their limits) or the box budget is spent.

Otherwise it is cut in two along s or in 2^k along the axes, whichever dominates its gap
(``BoxBounds.split_s``), and closed if that one is at its depth limit. Boxes of a node's
children always come in complete sets of 2^k, so the nodes of the closed boxes form a
2^k-tree whose leaves tile the box, and every point (v, s) lies in exactly one closed box.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from pipeline.certify.clearance_bound import box_clearance_bounds
from pipeline.certify.range_model import RangeModel
from pipeline.exceptions import InvalidParameterError
from pipeline.validation import check_non_negative, check_positive, check_positive_int

_CHUNK = 20_000


@dataclass(frozen=True)
class SearchSettings:
    """Limits of the branch and bound.

    Attributes:
        margin_m: Clearance the certificate tries to prove [m].
        max_depth_lw: Deepest (L, W) node (cells of 1 / 2^depth of the range per side).
        boundary_depth_lw: Depth to which regions below the margin are resolved.
        max_depth_s: Deepest s interval (1 / 2^depth).
        initial_depth_lw: Depth of the starting grid in (L, W).
        initial_depth_s: Depth of the starting grid in s.
        max_boxes: Budget of box evaluations (the search stops with valid, looser bounds).
        resolution_m: Where the margin is out of reach, boxes are cut until their bound is within
            this of the clearance at their centre [m] (so the map's minimum is close to the truth).
    """

    margin_m: float = 0.01
    max_depth_lw: int = 8
    boundary_depth_lw: int = 6
    max_depth_s: int = 16
    initial_depth_lw: int = 2
    initial_depth_s: int = 4
    max_boxes: int = 5_000_000
    resolution_m: float = 5e-4

    def __post_init__(self) -> None:
        check_non_negative("margin_m", self.margin_m)
        check_positive("resolution_m", self.resolution_m)
        check_positive_int("max_depth_lw", self.max_depth_lw, minimum=0)
        check_positive_int("max_depth_s", self.max_depth_s, minimum=0)
        check_positive_int("initial_depth_lw", self.initial_depth_lw, minimum=0)
        check_positive_int("initial_depth_s", self.initial_depth_s, minimum=0)
        check_positive_int("boundary_depth_lw", self.boundary_depth_lw, minimum=0)
        check_positive_int("max_boxes", self.max_boxes, minimum=1)
        if self.initial_depth_lw > self.max_depth_lw or self.initial_depth_s > self.max_depth_s:
            raise InvalidParameterError("initial_depth", (self.initial_depth_lw, self.initial_depth_s), "<= max depths")
        if self.max_depth_lw > 20 or self.max_depth_s > 40:
            raise InvalidParameterError(
                "max_depth", (self.max_depth_lw, self.max_depth_s), "<= 20 (L, W) and <= 40 (s)"
            )


@dataclass(frozen=True, eq=False)
class ClosedBoxes:
    """The closed boxes of one search, as arrays of length n.

    Attributes:
        depth_lw: Depth of the node of each box (the same on every axis).
        index: Node index of each box along each axis, (n, k) (columns in the axes' order).
        depth_s, index_s: s interval of each box.
        bound_m: Lower bound on the clearance over the box [m].
        center_clearance_m: Clearance at the box centre [m].
        evaluations: Boxes evaluated in all.
    """

    depth_lw: np.ndarray
    index: np.ndarray
    depth_s: np.ndarray
    index_s: np.ndarray
    bound_m: np.ndarray
    center_clearance_m: np.ndarray
    evaluations: int


def child_offsets(k: int) -> np.ndarray:
    """The 2^k children of a node as index offsets (2^k, k), in lexicographic order (for (L, W):
    (0, 0), (0, 1), (1, 0), (1, 1))."""
    return np.array(list(itertools.product((0, 1), repeat=k)), dtype=np.int64).reshape(2**k, k)


def node_boxes(
    model: RangeModel, depth: np.ndarray, index: np.ndarray, split_w: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Centres and half widths (n, k) [m] of nodes (depth, index (n, k)); with ``split_w`` = e, of
    their strips along W (1 / 2^(depth + e) of the range in W, index[:, 1] counting the latter:
    ``pipeline.certify.strip_split``)."""
    depth = np.asarray(depth, dtype=float)
    index = np.asarray(index).reshape(depth.size, model.k)
    depths = np.repeat(depth[:, None], model.k, axis=1)
    depths[:, 1] += split_w
    size = model.range_size / 2.0**depths
    center = model.range_lo + (index + 0.5) * size
    return center, size / 2


def _boxes(model: RangeModel, dl, index, ds, js) -> tuple[np.ndarray, np.ndarray]:
    c, r = node_boxes(model, dl, index)
    hs = 0.5 / 2.0 ** ds.astype(float)
    return np.column_stack([c, (js + 0.5) * 2 * hs]), np.column_stack([r, hs])


def initial_roots(k: int, depth: int) -> np.ndarray:
    """Every node of the grid at ``depth``, rows (depth, i_1..i_k), lexicographic."""
    n = 2**depth
    grid = np.stack(np.meshgrid(*[np.arange(n)] * k, indexing="ij"), -1).reshape(-1, k)
    return np.column_stack([np.full(grid.shape[0], depth), grid]).astype(np.int64)


def search(model: RangeModel, settings: SearchSettings, roots: np.ndarray | None = None) -> ClosedBoxes:
    """Run the branch and bound from the given nodes (rows depth, i_1..i_k), default the whole
    initial grid, each with the initial s grid."""
    k = model.k
    if roots is None:
        roots = initial_roots(k, settings.initial_depth_lw)
    roots = np.asarray(roots, dtype=np.int64).reshape(-1, k + 1)
    m = 2**settings.initial_depth_s
    dl = np.repeat(roots[:, 0], m)
    ix = np.repeat(roots[:, 1:], m, axis=0)
    ds = np.full(dl.size, settings.initial_depth_s, dtype=np.int64)
    js = np.tile(np.arange(m, dtype=np.int64), roots.shape[0])
    offsets = child_offsets(k)
    fan = offsets.shape[0]
    closed: list[tuple[np.ndarray, ...]] = []
    evaluations = 0
    while dl.size:
        bound = np.empty(dl.size)
        centre = np.empty(dl.size)
        split_s = np.empty(dl.size, dtype=bool)
        for start in range(0, dl.size, _CHUNK):
            part = slice(start, start + _CHUNK)
            c, r = _boxes(model, dl[part], ix[part], ds[part], js[part])
            b = box_clearance_bounds(model, c, r)
            bound[part], centre[part], split_s[part] = b.lower_m, b.center_m, b.split_s
        evaluations += dl.size
        out_of_reach = centre < settings.margin_m
        done = bound >= settings.margin_m
        # Certified free to within the resolution of the clearance seen, or a collision seen at the centre.
        resolved = ((bound > 0.0) & (centre - bound <= settings.resolution_m)) | (centre <= 0.0)
        far = 2.0 * centre - bound < settings.margin_m  # not near the margin's contour (module docstring)
        done |= out_of_reach & resolved & far & (dl >= settings.boundary_depth_lw)
        can_s, can_lw = ds < settings.max_depth_s, dl < settings.max_depth_lw
        # Resolve the boundary of the margin over the axes before anything else.
        want_s = np.where(out_of_reach & resolved, False, split_s)
        # A box whose gap is dominated by the axes at the deepest node is closed: cutting s cannot help.
        cut_s = ~done & want_s & can_s
        cut_lw = ~done & ~want_s & can_lw
        cut_lw |= ~done & want_s & ~can_s & can_lw
        done |= ~(cut_s | cut_lw)
        if evaluations + 2 * np.count_nonzero(cut_s) + fan * np.count_nonzero(cut_lw) > settings.max_boxes:
            done[:] = True
            cut_s[:] = cut_lw[:] = False
        closed.append((dl[done], ix[done], ds[done], js[done], bound[done], centre[done]))
        # Children along s.
        s_rows = np.flatnonzero(cut_s)
        s_children = (
            np.repeat(dl[s_rows], 2),
            np.repeat(ix[s_rows], 2, axis=0),
            np.repeat(ds[s_rows] + 1, 2),
            (2 * js[s_rows][:, None] + np.array([0, 1])).ravel(),
        )
        lw_rows = np.flatnonzero(cut_lw)
        lw_children = (
            np.repeat(dl[lw_rows] + 1, fan),
            (2 * ix[lw_rows][:, None, :] + offsets[None]).reshape(-1, k),
            np.repeat(ds[lw_rows], fan),
            np.repeat(js[lw_rows], fan),
        )
        dl, ix, ds, js = (np.concatenate([a, b]) for a, b in zip(s_children, lw_children, strict=True))
    parts = [np.concatenate(column) for column in zip(*closed, strict=True)]
    return ClosedBoxes(*parts, evaluations=evaluations)
