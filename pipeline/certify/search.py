"""Branch and bound over a subpaving of the coefficients' axes x s for the clearance range certificate.

The fitted box of the k axes ((L, W), or (L, W, x): ``RangeModel.axes``) is cut into nodes, each
a box with its own level and index along every axis (:mod:`pipeline.certify.subpaving`); the
search starts from the uniform grid of ``initial_depth_lw`` cuts of every axis. s in [0, 1] is
cut dyadically as well (depth_s, j). A box is one node times one s interval. Each round bounds
every open box (:func:`pipeline.certify.clearance_bound.box_clearance_bounds`) and closes it when

* its bound reaches the margin; or
* the margin is out of reach in its node (the clearance at the box centre, a value the
  clearance takes there, is below the margin), its bound is positive and within
  ``resolution_m`` of that centre value, or the centre itself is in collision, its node is as
  small as a cell of the boundary depth (its levels sum to k times it), and the centre lies
  below the margin by more than the bound's gap below the centre (2 centre - bound < margin:
  the clearance rises above its centre value by about as much as it falls below it, so the
  node most likely holds no point at the margin); a node closer to the margin is cut on, to
  the smallest cell, so the map resolves the margin's contour at the smallest cell from both
  sides (measured on the default build: with nodes closed at the boundary depth wherever their
  centre missed the margin, the leaves beside the contour inherited bounds 0.23 mm (median)
  below their own clearance); or
* it cannot be cut further (s at its deepest and no axis of its node below ``max_depth_lw``)
  or the box budget is spent.

Otherwise it is cut in two along s, or sent to its node's two halves along one axis, whichever
dominates its gap (``BoxBounds.split_s``), and closed if that one cannot be cut. **A node is cut
once, along one axis**, when its first boxes ask: among its axes below the deepest level, the one
whose share of the gap (``BoxBounds.axis_gap_m``: how far the tip and the obstacle move along
that axis alone), summed over the node's boxes asking in that round, is largest. A cell's gap
is usually dominated by one axis, so cutting that one alone shrinks it at half the cells a cut
of every axis would make (interval subpavings, SIVIA, bisect one direction the same way). Every
later box of the node that asks goes to the same two halves. So the nodes form a binary tree
from each root, and every point (v, s) lies in a closed box of its leaf or of one of the leaf's
ancestors (an s interval of a node is closed there, cut along s, or handed to both halves).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.certify.clearance_bound import box_clearance_bounds, tightened_lower_m
from pipeline.certify.range_model import RangeModel
from pipeline.certify.subpaving import open_axes
from pipeline.exceptions import InvalidParameterError
from pipeline.validation import check_bool, check_non_negative, check_positive, check_positive_int

_CHUNK = 20_000
#: How many times smaller than the mean-value form's gap the second-order form's is assumed to be
#: when choosing the boxes to bound with it (:func:`_worth_second_order`); measured 15 to 40 at the median
#: on boxes of 1/16 to 1/128 (``python scripts/clearance_gap.py``).
_SECOND_ORDER_GAIN = 4.0


@dataclass(frozen=True)
class SearchSettings:
    """Limits of the branch and bound.

    Attributes:
        margin_m: Clearance the certificate tries to prove [m].
        max_depth_lw: Level of the smallest node (1 / 2^depth of the range along every axis): a
            node whose levels sum to k times it is cut no further.
        extra_depth_lw: Levels beyond ``max_depth_lw`` a node may reach along one axis (at the
            smallest node's volume, the others coarser).
        boundary_depth_lw: Depth to which regions below the margin are resolved (a node as
            small as a cell of this depth along every axis: its levels sum to k times it).
        max_depth_s: Deepest s interval (1 / 2^depth).
        initial_depth_lw: Depth of the starting grid along every axis.
        initial_depth_s: Depth of the starting grid in s.
        max_boxes: Budget of box evaluations (the search stops with valid, looser bounds).
        resolution_m: Where the margin is out of reach, boxes are cut until their bound is within
            this of the clearance at their centre [m] (so the map's minimum is close to the truth).
        second_order: Bound the boxes the mean-value form leaves open with the second-order
            form as well (``clearance_bound.box_clearance_bounds``; decide coarse, refine only
            where undecided).
    """

    margin_m: float = 0.01
    max_depth_lw: int = 8
    extra_depth_lw: int = 0
    boundary_depth_lw: int = 6
    max_depth_s: int = 16
    initial_depth_lw: int = 2
    initial_depth_s: int = 4
    max_boxes: int = 5_000_000
    resolution_m: float = 5e-4
    second_order: bool = False

    def __post_init__(self) -> None:
        check_non_negative("margin_m", self.margin_m)
        check_positive("resolution_m", self.resolution_m)
        check_positive_int("max_depth_lw", self.max_depth_lw, minimum=0)
        check_positive_int("extra_depth_lw", self.extra_depth_lw, minimum=0)
        check_positive_int("max_depth_s", self.max_depth_s, minimum=0)
        check_positive_int("initial_depth_lw", self.initial_depth_lw, minimum=0)
        check_positive_int("initial_depth_s", self.initial_depth_s, minimum=0)
        check_positive_int("boundary_depth_lw", self.boundary_depth_lw, minimum=0)
        check_positive_int("max_boxes", self.max_boxes, minimum=1)
        check_bool("second_order", self.second_order)
        if self.initial_depth_lw > self.max_depth_lw or self.initial_depth_s > self.max_depth_s:
            raise InvalidParameterError("initial_depth", (self.initial_depth_lw, self.initial_depth_s), "<= max depths")
        if self.max_depth_lw + self.extra_depth_lw > 20 or self.max_depth_s > 40:
            raise InvalidParameterError(
                "max_depth", (self.max_depth_lw + self.extra_depth_lw, self.max_depth_s), "<= 20 (axes) and <= 40 (s)"
            )

    def open_axes(self, levels: np.ndarray) -> np.ndarray:
        """Per node (levels (n, k)) and axis, whether a cut along it is allowed: the axis is below
        ``max_depth_lw + extra_depth_lw`` and the node larger than the smallest node's volume."""
        return open_axes(levels, self.max_depth_lw, self.extra_depth_lw)


@dataclass(frozen=True, eq=False)
class SearchLeaves:
    """The leaves of one search's nodes, as arrays of length n.

    Attributes:
        levels: Each leaf's level along every axis, (n, k).
        index: Each leaf's index along every axis, (n, k).
        bound_m: The least clearance bound of the closed boxes of the leaf and its ancestors [m].
        center_clearance_m: The least clearance at those boxes' centres [m].
        evaluations: Boxes evaluated in all.
        boxes_closed: Boxes closed in all.
        nodes: With ``keep_nodes``, every node (leaf or not) as (levels (N, k), index (N, k), the
            least bound of its own closed boxes (N,), +inf for none) [m]; else None.
    """

    levels: np.ndarray
    index: np.ndarray
    bound_m: np.ndarray
    center_clearance_m: np.ndarray
    evaluations: int
    boxes_closed: int
    nodes: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None


class _Nodes:
    """The nodes of one search, grown as they are cut: level and index (N, k), parent, the round
    each was made in, the axis it is cut along (-1: not cut) and its lower half (the upper is next).
    Stored with room to grow (doubled when full), so a round's cuts do not copy every node."""

    def __init__(self, levels: np.ndarray, index: np.ndarray) -> None:
        n = levels.shape[0]
        self._size = n
        self._level, self._index = levels.astype(np.int64), index.astype(np.int64)
        self._parent, self._made = np.full(n, -1, dtype=np.int64), np.zeros(n, dtype=np.int64)
        self._axis, self._child = np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64)

    level = property(lambda self: self._level[: self._size], doc="Levels (N, k).")
    index = property(lambda self: self._index[: self._size], doc="Indices (N, k).")
    parent = property(lambda self: self._parent[: self._size], doc="Parent node (N,), -1 for a root.")
    made = property(lambda self: self._made[: self._size], doc="Round each node was made in (N,).")
    axis = property(lambda self: self._axis[: self._size], doc="Axis each node is cut along (N,), -1: not cut.")
    child = property(lambda self: self._child[: self._size], doc="Lower half of each node (N,), -1: not cut.")

    def _reserve(self, extra: int) -> None:
        """Room for ``extra`` more nodes (capacity doubled as needed; new rows not cut)."""
        need = self._size + extra
        if need <= self._axis.size:
            return
        capacity = max(need, 2 * self._axis.size)
        for name in ("_level", "_index", "_parent", "_made", "_axis", "_child"):
            old = getattr(self, name)
            grown = np.full((capacity, *old.shape[1:]), -1, dtype=old.dtype)
            grown[: self._size] = old[: self._size]
            setattr(self, name, grown)

    def cut(self, nodes: np.ndarray, axes: np.ndarray, round_: int) -> None:
        """Cut ``nodes`` (not yet cut) in two along ``axes``: their halves are appended."""
        m = 2 * nodes.size
        self._reserve(m)
        first = self._size + 2 * np.arange(nodes.size)
        self._axis[nodes], self._child[nodes] = axes, first
        new = slice(self._size, self._size + m)
        level = np.repeat(self._level[nodes], 2, axis=0)
        index = np.repeat(self._index[nodes], 2, axis=0)
        rows = np.arange(m)
        along = np.repeat(axes, 2)
        level[rows, along] += 1
        index[rows, along] = 2 * index[rows, along] + (rows % 2)
        self._level[new], self._index[new] = level, index
        self._parent[new], self._made[new] = np.repeat(nodes, 2), round_
        self._axis[new], self._child[new] = -1, -1
        self._size += m

    def leaves(self, bound: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, ...]:
        """The uncut nodes' levels, indices and the least of the per-node ``bound`` and ``centre``
        over each and its ancestors (handed down round by round: a parent is older than its halves)."""
        bound, centre = bound.copy(), centre.copy()
        for round_ in range(1, int(self.made.max()) + 1):
            rows = np.flatnonzero(self.made == round_)
            bound[rows] = np.minimum(bound[rows], bound[self.parent[rows]])
            centre[rows] = np.minimum(centre[rows], centre[self.parent[rows]])
        leaf = self.axis < 0
        return self.level[leaf], self.index[leaf], bound[leaf], centre[leaf]


def cell_boxes(model: RangeModel, levels: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres and half widths (n, k) [m] of cells of the given levels and indices (n, k)."""
    levels = np.asarray(levels, dtype=float).reshape(-1, model.k)
    index = np.asarray(index).reshape(levels.shape)
    size = model.range_size / 2.0**levels
    return model.range_lo + (index + 0.5) * size, size / 2


def node_boxes(
    model: RangeModel, depth: np.ndarray, index: np.ndarray, split_w: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Centres and half widths (n, k) [m] of nodes of one depth along every axis (depth (n,),
    index (n, k)); with ``split_w`` = e, of their strips along W (1 / 2^(depth + e) of the range
    in W, index[:, 1] counting the latter: ``pipeline.certify.strip_split``)."""
    depth = np.asarray(depth, dtype=np.int64).reshape(-1)
    return cell_boxes(model, strip_levels(depth, model.k, split_w), index)


def strip_levels(depth: np.ndarray, k: int, split_w: int = 0) -> np.ndarray:
    """Levels (n, k) of nodes of one depth along every axis (``depth`` (n,)), W ``split_w``
    halvings deeper (their strips along W: ``pipeline.certify.strip_split``)."""
    levels = np.repeat(np.asarray(depth)[:, None], k, axis=1)
    levels[:, 1] += split_w
    return levels


def _bounds(
    model: RangeModel, nodes: _Nodes, node: np.ndarray, ds: np.ndarray, js: np.ndarray, settings: SearchSettings
) -> tuple:
    """The bound, centre clearance, split_s and axis gaps of the boxes (node, s interval), in chunks.
    With ``settings.second_order`` the boxes the mean-value form leaves open (:func:`_worth_second_order`)
    are bounded again with the second-order form too, and the larger bound kept (both hold)."""
    bound, centre = np.empty(node.size), np.empty(node.size)
    split_s, gaps = np.empty(node.size, dtype=bool), np.empty((node.size, model.k))
    for start in range(0, node.size, _CHUNK):
        part = slice(start, start + _CHUNK)
        c, r = cell_boxes(model, nodes.level[node[part]], nodes.index[node[part]])
        hs = 0.5 / 2.0 ** ds[part].astype(float)
        center, radius = np.column_stack([c, (js[part] + 0.5) * 2 * hs]), np.column_stack([r, hs])
        b = box_clearance_bounds(model, center, radius)
        rows = np.flatnonzero(_worth_second_order(settings, b.lower_m, b.center_m)) if settings.second_order else []
        lower = tightened_lower_m(model, center, radius, b.lower_m, rows)
        bound[part], centre[part], split_s[part], gaps[part] = lower, b.center_m, b.split_s, b.axis_gap_m
    return bound, centre, split_s, gaps


def _worth_second_order(settings: SearchSettings, bound: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The boxes the mean-value bound leaves open (:func:`_decide`) that a bound
    :data:`_SECOND_ORDER_GAIN` times closer to the centre's clearance would close: below the
    margin with the centre above it by more than that smaller gap, or with the margin out of reach
    and the gap above ``resolution_m`` but not that smaller one. Only which boxes get the tighter
    bound depends on this guess; every bound kept holds."""
    gap = centre - bound
    closer = gap / _SECOND_ORDER_GAIN
    to_margin = (bound < settings.margin_m) & (centre - closer >= settings.margin_m)
    to_resolution = (centre < settings.margin_m) & (centre > 0.0) & (gap > settings.resolution_m)
    return to_margin | (to_resolution & (closer <= settings.resolution_m))


def initial_roots(k: int, depth: int) -> np.ndarray:
    """Every node of the grid at ``depth``, rows (depth, i_1..i_k), lexicographic."""
    n = 2**depth
    grid = np.stack(np.meshgrid(*[np.arange(n)] * k, indexing="ij"), -1).reshape(-1, k)
    return np.column_stack([np.full(grid.shape[0], depth), grid]).astype(np.int64)


def _cut_along(nodes: _Nodes, rows_node: np.ndarray, gaps: np.ndarray, settings: SearchSettings, round_: int) -> None:
    """Cut the nodes of ``rows_node`` not yet cut, each along its open axis
    (:meth:`SearchSettings.open_axes`) with the largest summed share of the gap of its rows
    (``gaps``) (module docstring)."""
    fresh = nodes.axis[rows_node] < 0
    if not np.any(fresh):
        return
    unique, owner = np.unique(rows_node[fresh], return_inverse=True)
    score = np.zeros((unique.size, nodes.level.shape[1]))
    np.add.at(score, owner, gaps[fresh])
    score[~settings.open_axes(nodes.level[unique])] = -np.inf
    nodes.cut(unique, np.argmax(score, axis=1), round_)


def search(
    model: RangeModel, settings: SearchSettings, roots: np.ndarray | None = None, keep_nodes: bool = False
) -> SearchLeaves:
    """Run the branch and bound from the given nodes (rows depth, i_1..i_k), default the whole
    initial grid, each with the initial s grid (``keep_nodes``: :attr:`SearchLeaves.nodes` too)."""
    k = model.k
    if roots is None:
        roots = initial_roots(k, settings.initial_depth_lw)
    roots = np.asarray(roots, dtype=np.int64).reshape(-1, k + 1)
    nodes = _Nodes(np.repeat(roots[:, :1], k, axis=1), roots[:, 1:])
    m = 2**settings.initial_depth_s
    node = np.repeat(np.arange(roots.shape[0]), m)
    ds = np.full(node.size, settings.initial_depth_s, dtype=np.int64)
    js = np.tile(np.arange(m, dtype=np.int64), roots.shape[0])
    closed: list[tuple[np.ndarray, ...]] = []
    evaluations, round_ = 0, 0
    while node.size:
        bound, centre, split_s, gaps = _bounds(model, nodes, node, ds, js, settings)
        evaluations += node.size
        done, cut_s, cut_lw = _decide(settings, nodes, node, ds, bound, centre, split_s)
        if evaluations + 2 * np.count_nonzero(cut_s | cut_lw) > settings.max_boxes:
            done[:] = True
            cut_s[:] = cut_lw[:] = False
        closed.append((node[done], bound[done], centre[done]))
        round_ += 1
        lw_rows = np.flatnonzero(cut_lw)
        _cut_along(nodes, node[lw_rows], gaps[lw_rows], settings, round_)
        s_rows = np.flatnonzero(cut_s)
        first = nodes.child[node[lw_rows]]
        node, ds, js = (
            np.concatenate([np.repeat(node[s_rows], 2), np.column_stack([first, first + 1]).ravel()]),
            np.concatenate([np.repeat(ds[s_rows] + 1, 2), np.repeat(ds[lw_rows], 2)]),
            np.concatenate([(2 * js[s_rows][:, None] + np.array([0, 1])).ravel(), np.repeat(js[lw_rows], 2)]),
        )
    owner, low, mid = (np.concatenate(column) for column in zip(*closed, strict=True))
    own_bound, own_centre = np.full(nodes.axis.size, np.inf), np.full(nodes.axis.size, np.inf)
    np.minimum.at(own_bound, owner, low)
    np.minimum.at(own_centre, owner, mid)
    kept = (nodes.level, nodes.index, own_bound) if keep_nodes else None
    return SearchLeaves(
        *nodes.leaves(own_bound, own_centre), evaluations=evaluations, boxes_closed=owner.size, nodes=kept
    )


def _decide(
    settings: SearchSettings,
    nodes: _Nodes,
    node: np.ndarray,
    ds: np.ndarray,
    bound: np.ndarray,
    centre: np.ndarray,
    split_s: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per open box: closed, cut along s, or handed to its node's halves (module docstring)."""
    level = nodes.level[node]
    out_of_reach = centre < settings.margin_m
    done = bound >= settings.margin_m
    # Certified free to within the resolution of the clearance seen, or a collision seen at the centre.
    resolved = ((bound > 0.0) & (centre - bound <= settings.resolution_m)) | (centre <= 0.0)
    far = 2.0 * centre - bound < settings.margin_m  # not near the margin's contour (module docstring)
    small = level.sum(axis=1) >= level.shape[1] * settings.boundary_depth_lw
    done |= out_of_reach & resolved & far & small
    can_s = ds < settings.max_depth_s
    can_lw = np.any(settings.open_axes(level), axis=1) | (nodes.axis[node] >= 0)
    # Resolve the boundary of the margin over the axes before anything else.
    want_s = np.where(out_of_reach & resolved, False, split_s)
    # A box whose gap is dominated by the axes at the deepest node is closed: cutting s cannot help.
    cut_s = ~done & want_s & can_s
    cut_lw = ~done & ~want_s & can_lw
    cut_lw |= ~done & want_s & ~can_s & can_lw
    done |= ~(cut_s | cut_lw)
    return done, cut_s, cut_lw
