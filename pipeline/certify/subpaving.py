"""A subpaving: boxes tiling a box of k axes, each made from the whole box by cuts of one axis at
the midpoint of the current box, the cuts forming a binary tree (as the subpavings of interval
analysis, SIVIA, are).

Along axis a of range [lo_a, hi_a], a leaf of level l_a and index i_a spans lo_a + [i_a, i_a + 1]
(hi_a - lo_a) / 2^l_a; its volume fraction of the box is 2^-(l_1 + ... + l_k). A quadtree
leaf of depth d has l_a = d on both axes; a strip cut e more times along the second axis has
l = (d, d + e). The axes are numbered: what they mean is the owner's data.

**The tree.** Internal nodes are stored in depth-first order, the root first and a node's lower
half before its upper half: per node the axis it cuts, its level along that axis (its children
have that level + 1 there) and its two children, a node (>= 0, after its parent) or -1 - leaf.
:meth:`Subpaving.from_leaves` finds the tree from the leaves alone (each node cuts the first
axis along which every leaf in it is deeper than the node; if the leaves tile the box by
midpoint cuts, that cut crosses none of them, so the tree is found whatever order the cuts were
made in) and refuses leaves that leave a gap or overlap; the leaves' levels and indices are
found back from the tree by walking it (:attr:`Subpaving.levels`, :attr:`Subpaving.indices`).

**Placing a point.** A point v is placed by its scaled coordinates u_a = (v_a - lo_a) / (hi_a -
lo_a) 2^D along every axis (D the deepest level along any axis), truncated to the cell t_a =
min(floor(u_a), 2^D - 1) (the last cell for v_a = hi_a); a node at level l along its axis a
sends the point to the half (t_a >> (D - 1 - l)) & 1. Scaling by a power of two is exact in
floating point, so the halves chosen at different levels are nested, and
:meth:`Subpaving.leaf_indices` (vectorised, level by level) and
:func:`pipeline.certify.lookup.leaf_of` (compiled, one point) find the same leaf by the same
operations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from pipeline.exceptions import InvalidParameterError

__all__ = ["MAX_LEVEL", "Subpaving", "open_axes"]

#: Deepest level along any axis (cells of 1 / 2^30 of the range).
MAX_LEVEL = 30


@dataclass(frozen=True, eq=False)
class Subpaving:
    """Leaves tiling the box ``ranges`` by midpoint cuts of one axis at a time (module docstring).

    Attributes:
        ranges: (lo, hi) of every axis, finite, lo < hi (in the axes' own units).
        cut_axis: Per internal node (depth-first, the root first), the axis it cuts, (n - 1,).
        cut_level: Per internal node, its level along that axis, (n - 1,).
        children: Per internal node, its lower and upper half: a node >= 0 or -1 - leaf, (n - 1, 2).
    """

    ranges: tuple[tuple[float, float], ...]
    cut_axis: np.ndarray
    cut_level: np.ndarray
    children: np.ndarray

    def __post_init__(self) -> None:
        ranges = _checked_ranges(self.ranges)
        k = len(ranges)
        axis = np.ascontiguousarray(self.cut_axis, dtype=np.int8)
        level = np.ascontiguousarray(self.cut_level, dtype=np.int8)
        children = np.ascontiguousarray(self.children, dtype=np.int32)
        m = axis.size
        if axis.shape != (m,) or level.shape != (m,) or children.shape != (m, 2):
            shapes = (axis.shape, level.shape, children.shape)
            raise InvalidParameterError("tree", shapes, "(n - 1,), (n - 1,) and (n - 1, 2) arrays")
        if np.any(axis < 0) or np.any(axis >= k) or np.any(level < 0) or np.any(level >= MAX_LEVEL):
            raise InvalidParameterError("tree", "cut out of range", f"axes 0..{k - 1}, levels 0..{MAX_LEVEL - 1}")
        _check_tree_shape(children)
        for name, value in (("cut_axis", axis), ("cut_level", level), ("children", children)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "ranges", ranges)

    @classmethod
    def from_leaves(cls, ranges, levels: np.ndarray, indices: np.ndarray) -> Subpaving:
        """The subpaving of the given leaves (levels and indices (n, k)), numbered as given.

        Raises:
            InvalidParameterError: levels or indices out of range, or leaves that leave a gap or
                overlap (or tile the box in no sequence of midpoint cuts).
        """
        from pipeline.certify.lookup import TREE_GAP, TREE_OK, build_tree  # Numba: building, not loading

        k = len(ranges)
        levels = np.ascontiguousarray(levels, dtype=np.int64)
        indices = np.ascontiguousarray(indices, dtype=np.int64)
        if levels.ndim != 2 or levels.shape[1] != k or indices.shape != levels.shape or levels.shape[0] == 0:
            raise InvalidParameterError("cells", (levels.shape, indices.shape), f"(n, {k}) levels and indices, n >= 1")
        if np.any(levels < 0) or np.any(levels > MAX_LEVEL):
            worst = int(levels.min()) if np.any(levels < 0) else int(levels.max())
            raise InvalidParameterError("cell levels", worst, f"0..{MAX_LEVEL}")
        if np.any(indices < 0) or np.any(indices >= 2**levels):
            raise InvalidParameterError("cell indices", "out of range", "0 <= index < 2^level")
        axis, level, children, verdict = build_tree(levels, indices)
        if verdict != TREE_OK:
            raise InvalidParameterError(
                "cells", "gaps" if verdict == TREE_GAP else "overlaps", "leaves tiling the range"
            )
        tree = cls(ranges, axis, level, children)
        object.__setattr__(tree, "_leaves", (levels, indices))
        return tree

    @property
    def k(self) -> int:
        """The number of axes."""
        return len(self.ranges)

    @property
    def size(self) -> int:
        """The number of leaves."""
        return self.cut_axis.size + 1

    @cached_property
    def top(self) -> int:
        """D, the deepest level along any axis (0 for a single leaf)."""
        return int(self.cut_level.max()) + 1 if self.cut_level.size else 0

    @cached_property
    def _leaves(self) -> tuple[np.ndarray, np.ndarray]:
        return _walk(self.cut_axis, self.cut_level, self.children, self.k)

    @property
    def levels(self) -> np.ndarray:
        """Per leaf, its level along every axis, int64 (n, k)."""
        return self._leaves[0]

    @property
    def indices(self) -> np.ndarray:
        """Per leaf, its index along every axis (at its level there), int64 (n, k)."""
        return self._leaves[1]

    @cached_property
    def volume_fraction(self) -> np.ndarray:
        """Per leaf, its fraction of the box's volume, (n,)."""
        return 2.0 ** (-np.sum(self.levels, axis=1).astype(float))

    def sizes(self) -> np.ndarray:
        """Per leaf, its side along every axis, (n, k)."""
        ranges = np.array(self.ranges)
        return (ranges[:, 1] - ranges[:, 0]) / 2.0 ** self.levels.astype(float)

    def centres(self) -> np.ndarray:
        """Per leaf, its centre along every axis, (n, k)."""
        return np.array(self.ranges)[:, 0] + (self.indices + 0.5) * self.sizes()

    def box(self, leaf: int) -> tuple[tuple[float, float], ...]:
        """The leaf's (lo, hi) along every axis."""
        out = []
        for (lo, hi), level, i in zip(self.ranges, self.levels[leaf], self.indices[leaf], strict=True):
            side = (hi - lo) / 2 ** int(level)
            out.append((lo + int(i) * side, lo + (int(i) + 1) * side))
        return tuple(out)

    def leaf_indices(self, values: tuple) -> np.ndarray:
        """The leaf of each point (vectorised; module docstring): ``values`` one array (or scalar)
        per axis, broadcast together; -1 outside the box."""
        points = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in values))
        shape = points[0].shape
        n = 1 << self.top
        inside = np.ones(points[0].size, dtype=bool)
        for value, (lo, hi) in zip(points, self.ranges, strict=True):
            inside &= (value.ravel() >= lo) & (value.ravel() <= hi)
        cells = np.empty((inside.size, self.k), dtype=np.int64)
        for a, (value, (lo, hi)) in enumerate(zip(points, self.ranges, strict=True)):
            u = np.where(inside, (value.ravel() - lo) / (hi - lo) * n, 0.0)
            cells[:, a] = np.clip(np.floor(u).astype(np.int64), 0, n - 1)
        node = np.full(inside.size, 0 if self.cut_axis.size else -1, dtype=np.int64)
        pending = np.flatnonzero(node >= 0)
        while pending.size:
            at = node[pending]
            axis = self.cut_axis[at].astype(np.int64)
            shift = self.top - 1 - self.cut_level[at].astype(np.int64)
            node[pending] = self.children[at, (cells[pending, axis] >> shift) & 1]
            pending = pending[node[pending] >= 0]
        return np.where(inside, -1 - node, -1).reshape(shape)

    def lookup_index(self, mode: int, header: int) -> np.ndarray:
        """The tree as :class:`pipeline.certify.lookup.LookupTables`' ``index``: (mode, D, root),
        padded to ``header`` numbers, then per node (axis, D - 1 - level, lower, upper), int32."""
        head = np.zeros(header, dtype=np.int64)
        head[:3] = (mode, self.top, 0 if self.cut_axis.size else -1)
        rows = np.column_stack([self.cut_axis, self.top - 1 - self.cut_level.astype(np.int64), self.children])
        return np.concatenate([head, rows.reshape(-1)]).astype(np.int32)


def open_axes(levels: np.ndarray, max_depth: int, extra_depth: int) -> np.ndarray:
    """Per box (levels (n, k)) and axis, whether a cut along it is allowed: the axis is below
    ``max_depth + extra_depth`` and the box larger than a cube of level ``max_depth`` (its levels
    sum to less than k times it)."""
    levels = np.asarray(levels)
    roomy = levels.sum(axis=1) < levels.shape[1] * max_depth
    return (levels < max_depth + extra_depth) & roomy[:, None]


def _checked_ranges(ranges: object) -> tuple[tuple[float, float], ...]:
    """``ranges`` as floats: one finite (lo, hi), lo < hi, per axis, at least one axis.

    Raises:
        InvalidParameterError: anything else.
    """
    try:
        pairs = tuple((float(lo), float(hi)) for lo, hi in ranges)
    except (TypeError, ValueError):
        raise InvalidParameterError("ranges", ranges, "one (lo, hi) per axis") from None
    if not pairs or not all(math.isfinite(lo) and math.isfinite(hi) and lo < hi for lo, hi in pairs):
        raise InvalidParameterError("ranges", ranges, "one finite (lo, hi), lo < hi, per axis")
    return pairs


def _check_tree_shape(children: np.ndarray) -> None:
    """Refuse child codes that do not make a tree: each leaf 0..n-1 once, each node but the root
    once, every node after its parent (so there is no cycle).

    Raises:
        InvalidParameterError: anything else.
    """
    m = children.shape[0]
    if m == 0:  # a single leaf: the root
        return
    codes = children.reshape(-1).astype(np.int64)
    nodes, leaves = codes[codes >= 0], -1 - codes[codes < 0]
    parents = np.repeat(np.arange(m), 2)[codes >= 0]
    ok = (
        leaves.size == m + 1
        and int(leaves.max()) <= m
        and bool(np.all(np.bincount(leaves, minlength=m + 1) == 1))
        and (nodes.size == 0 or (int(nodes.min()) >= 1 and int(nodes.max()) < m))
        and bool(np.all(np.bincount(nodes, minlength=m)[1:] == 1))
        and bool(np.all(nodes > parents))
    )
    if not ok:
        raise InvalidParameterError("tree", "malformed children", "each leaf and each node but the root once")


def _walk(axis: np.ndarray, level: np.ndarray, children: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The leaves' levels and indices (n, k), found by walking the tree from the root, one
    depth of nodes at a time."""
    n = axis.size + 1
    levels = np.zeros((n, k), dtype=np.int64)
    indices = np.zeros((n, k), dtype=np.int64)
    if axis.size == 0:
        return levels, indices
    node = np.array([0])
    node_levels = np.zeros((1, k), dtype=np.int64)
    node_indices = np.zeros((1, k), dtype=np.int64)
    while node.size:
        a = axis[node].astype(np.int64)
        rows = np.arange(node.size)
        child_levels = np.repeat(node_levels, 2, axis=0)
        child_indices = np.repeat(node_indices, 2, axis=0)
        child_levels[2 * rows, a] += 1
        child_levels[2 * rows + 1, a] += 1
        child_indices[2 * rows, a] *= 2
        child_indices[2 * rows + 1, a] = 2 * child_indices[2 * rows + 1, a] + 1
        codes = children[node].reshape(-1).astype(np.int64)
        leaf = codes < 0
        levels[-1 - codes[leaf]] = child_levels[leaf]
        indices[-1 - codes[leaf]] = child_indices[leaf]
        node, node_levels, node_indices = codes[~leaf], child_levels[~leaf], child_indices[~leaf]
    return levels, indices
