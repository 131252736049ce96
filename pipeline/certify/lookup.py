"""The compiled side of a subpaving (:mod:`pipeline.certify.subpaving`): building its binary tree
from its leaves, and the scalar lookup of the leaf holding one point.

A subpaving over k axes is a binary tree whose every internal node cuts one axis of its box at
the midpoint. :func:`build_tree` finds that tree from the leaves alone (each leaf's level and
index along every axis) and refuses leaves that leave a gap or overlap. :func:`leaf_of` walks it
for one point, by the floating-point operations of the vectorised
:meth:`pipeline.certify.subpaving.Subpaving.leaf_indices` (a division, a product by a power of
two, a truncation; the subpaving's module docstring), so it finds the same leaf, and
:func:`bounds_of` reads that leaf's bounds. The map's scalar lookups (``cell_at``, ``bounds_at``,
``leaf_at``) and the online generator's compiled core (:mod:`pipeline.online.kernel`) both call
them: one scalar lookup; :func:`leaves_of` runs it over a batch (the map's ``leaf_indices``).
Nothing here knows what an axis means: axes are numbered.

All are Numba functions. The three lookups have one signature each and are loaded when this
module is imported (:data:`COMPILED`): compiled ahead of time into an extension module when the
package was built, else compiled by Numba's JIT and cached on disk (``cache=True``;
:mod:`pipeline.native`). :func:`build_tree` is compiled on its first call. The lookup's arrays
are writable copies because Numba's dispatch of a read-only array costs twice as much; do not
modify them.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from pipeline.native import Export, NativeModule

__all__ = [
    "COMPILED",
    "LOOKUP_HEADER",
    "LOOKUP_TREE",
    "NATIVE",
    "NO_MAP",
    "NO_TABLES",
    "TREE_GAP",
    "TREE_OK",
    "TREE_OVERLAP",
    "LookupTables",
    "bounds_of",
    "build_tree",
    "leaf_of",
    "leaves_of",
]

#: The mode (``LookupTables.index[0]``) of no map: every point is outside (:data:`NO_TABLES`).
NO_MAP = 0
#: The mode of a map: a binary tree of one-axis cuts.
LOOKUP_TREE = 1
#: The length of ``LookupTables.index``'s header: mode, deepest level D, root.
LOOKUP_HEADER = 3
#: :func:`build_tree`'s verdicts: a tree, leaves that leave part of a box uncovered, leaves that
#: overlap (or tile a box in no sequence of midpoint cuts).
TREE_OK, TREE_GAP, TREE_OVERLAP = 0, 1, 2


class LookupTables(NamedTuple):
    """The scalar lookup of a map as two flat arrays.

    Attributes:
        index: int32: a header of :data:`LOOKUP_HEADER` (mode, D the deepest level along any
            axis, the root), then per internal node four numbers: the axis it cuts, the shift
            D - 1 - (the node's level along that axis), and its two children (the lower half
            first). A child or root >= 0 is an internal node, -1 - leaf a leaf.
        bounds: float64: the fitted range (lo, hi) of every axis, in the map's axes order, then
            per leaf its clearance bound [m], endpoint-error bound [m] and status (the index
            into ``pipeline.certify.region_map.STATUSES``, exact as a float).
    """

    index: np.ndarray
    bounds: np.ndarray

    def leaf_bounds(self, axes: int, leaf: int) -> tuple[float, float, int]:
        """(clearance bound [m], endpoint-error bound [m], status index) of ``leaf`` of a map over
        ``axes`` axes (:func:`bounds_of`)."""
        return COMPILED["bounds_of"](self.bounds, axes, leaf)


def _no_tables() -> LookupTables:
    header = np.zeros(LOOKUP_HEADER, dtype=np.int32)
    header[0] = NO_MAP
    return LookupTables(header, np.zeros(0))


#: The lookup of no map (every point outside): the arrays' types are a map's, so that one
#: compiled function serves both.
NO_TABLES = _no_tables()


@numba.njit(cache=True, nogil=True)
def bounds_of(bounds: np.ndarray, axes: int, leaf: int) -> tuple[float, float, int]:
    """(clearance bound [m], endpoint-error bound [m], status index) of ``leaf``, read from
    ``LookupTables.bounds`` of a map over ``axes`` axes."""
    at = 2 * axes + 3 * leaf
    return bounds[at], bounds[at + 1], int(bounds[at + 2])


@numba.njit(cache=True, nogil=True)
def _cell(value: float, lo: float, hi: float, n: int) -> int:
    """The cell (0 .. n - 1) of ``value`` in [lo, hi] cut into n, as Subpaving.leaf_indices finds it."""
    return min(int((value - lo) / (hi - lo) * n), n - 1)


@numba.njit(cache=True, nogil=True)
def leaf_of(index: np.ndarray, bounds: np.ndarray, axes: int, v0: float, v1: float, v2: float, v3: float) -> int:
    """The leaf holding the point (v0, ..., v_(axes - 1)) (the map's axes in order; the values
    past ``axes`` are not read), as :meth:`Subpaving.leaf_indices` finds it; -1 outside the fitted
    box, or for :data:`NO_TABLES`."""
    if index[0] == NO_MAP:
        return -1
    values = (v0, v1, v2, v3)
    for a in range(axes):
        if not (bounds[2 * a] <= values[a] <= bounds[2 * a + 1]):
            return -1
    n = 1 << index[1]
    # Each axis's cell at the deepest level, once: the walk reads one bit of one of them per node.
    c0 = _cell(v0, bounds[0], bounds[1], n)
    c1 = _cell(v1, bounds[2], bounds[3], n) if axes > 1 else 0
    c2 = _cell(v2, bounds[4], bounds[5], n) if axes > 2 else 0
    c3 = _cell(v3, bounds[6], bounds[7], n) if axes > 3 else 0
    node = index[2]
    while node >= 0:
        at = LOOKUP_HEADER + 4 * node
        a = index[at]
        cell = c0 if a == 0 else c1 if a == 1 else c2 if a == 2 else c3
        node = index[at + 2 + ((cell >> index[at + 1]) & 1)]
    return -1 - node


@numba.njit(cache=True, nogil=True)
def leaves_of(index: np.ndarray, bounds: np.ndarray, axes: int, points: np.ndarray) -> np.ndarray:
    """:func:`leaf_of` of every row of ``points`` (m, 4) (the map's axes first, the rest not
    read): the batch lookup's compiled route."""
    out = np.empty(points.shape[0], dtype=np.int64)
    for row in range(points.shape[0]):
        out[row] = leaf_of(index, bounds, axes, points[row, 0], points[row, 1], points[row, 2], points[row, 3])
    return out


#: The scalar and batch lookups' machine code (:mod:`pipeline.native`): compiled ahead of time
#: into ``pipeline.certify.lookup_native`` when the package is built, else by the JIT.
NATIVE = NativeModule(
    "pipeline.certify.lookup_native",
    (
        Export("bounds_of", bounds_of, "Tuple((float64, float64, int64))(float64[::1], int64, int64)"),
        Export("leaf_of", leaf_of, "int64(int32[::1], float64[::1], int64, float64, float64, float64, float64)"),
        Export("leaves_of", leaves_of, "int64[::1](int32[::1], float64[::1], int64, float64[:, ::1])"),
    ),
    (__file__,),
)
#: The lookups' callables, loaded when this module is imported (:meth:`NativeModule.load`); for
#: callers whose arrays are C-contiguous and of the signatures' dtypes.
COMPILED = NATIVE.load()


@numba.njit(cache=True, nogil=True)
def _node_verdict(level, order, start: int, end: int, node, deeper) -> int:
    """For the leaves ``order[start:end]`` inside a node of levels ``node``: -1 if the node is one
    of them, the first axis every one of them is deeper along (the node's cut), or -2 - verdict
    (:data:`TREE_GAP`, :data:`TREE_OVERLAP`) if neither. ``deeper`` is scratch of k booleans."""
    k = node.size
    if end == start:
        return -2 - TREE_GAP
    deeper[:] = True
    for row in range(start, end):
        same = True
        for a in range(k):
            if level[order[row], a] < node[a]:
                return -2 - TREE_OVERLAP
            if level[order[row], a] == node[a]:
                deeper[a] = False
            else:
                same = False
        if same:
            return -1 if end - start == 1 else -2 - TREE_OVERLAP
    for a in range(k):
        if deeper[a]:
            return a
    return -2 - TREE_GAP if end - start == 1 else -2 - TREE_OVERLAP


@numba.njit(cache=True, nogil=True)
def _partition(level, index, order, scratch, start: int, end: int, node_level: int, a: int) -> int:
    """Order ``order[start:end]`` stably by the half of the node's axis ``a`` each leaf lies in;
    returns where the upper half starts."""
    low = start
    high = 0
    for row in range(start, end):
        leaf = order[row]
        if (index[leaf, a] >> (level[leaf, a] - node_level - 1)) & 1:
            scratch[high] = leaf
            high += 1
        else:
            order[low] = leaf
            low += 1
    for j in range(high):
        order[low + j] = scratch[j]
    return low


@numba.njit(cache=True, nogil=True)
def _push(span, levels, slots, at: int, start: int, end: int, node, slot: int) -> None:
    """Put the task (leaves ``start:end``, node levels ``node``, code slot ``slot``) at ``at``."""
    span[at, 0], span[at, 1] = start, end
    levels[at] = node
    slots[at] = slot


@numba.njit(cache=True, nogil=True)
def build_tree(level: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The binary tree of the leaves (levels and indices (n, k), int64): its internal nodes in
    depth-first order (the root first, a node's lower half before its upper half) as the axis
    each cuts (n - 1,), the node's level along it (n - 1,) and its two children (n - 1, 2) (an
    internal node >= 0, -1 - leaf a leaf), and :data:`TREE_OK`, or the verdict on leaves that
    do not tile the box (then the arrays are partial)."""
    n, k = level.shape
    axis = np.zeros(max(n - 1, 0), dtype=np.int8)
    cut = np.zeros(max(n - 1, 0), dtype=np.int8)
    children = np.zeros((max(n - 1, 0), 2), dtype=np.int32)
    order = np.arange(n)
    scratch = np.empty(n, dtype=np.int64)
    node = np.zeros(k, dtype=np.int64)
    deeper = np.ones(k, dtype=np.bool_)
    top = 0
    for row in range(n):
        for a in range(k):
            top = max(top, level[row, a])
    capacity = k * (top + 1) + 2
    task_span = np.zeros((capacity, 2), dtype=np.int64)
    task_level = np.zeros((capacity, k), dtype=np.int64)
    task_slot = np.full(capacity, -1, dtype=np.int64)  # where its code goes: 2 row + half, -1 the root
    tasks, rows = 1, 0
    task_span[0, 1] = n
    while tasks:
        tasks -= 1
        start, end, slot = task_span[tasks, 0], task_span[tasks, 1], task_slot[tasks]
        node[:] = task_level[tasks]
        verdict = _node_verdict(level, order, start, end, node, deeper)
        if verdict <= -2:
            return axis, cut, children, -2 - verdict
        code = -1 - order[start] if verdict == -1 else rows
        if slot >= 0:
            children[slot // 2, slot % 2] = code
        if verdict == -1:
            continue
        a = verdict
        if rows >= n - 1:  # more cuts than n leaves can fill: one is empty
            return axis, cut, children, TREE_GAP
        axis[rows], cut[rows] = a, node[a]
        middle = _partition(level, index, order, scratch, start, end, node[a], a)
        node[a] += 1
        _push(task_span, task_level, task_slot, tasks, middle, end, node, 2 * rows + 1)
        _push(task_span, task_level, task_slot, tasks + 1, start, middle, node, 2 * rows)  # the lower half first
        tasks += 2
        rows += 1
    return axis, cut, children, TREE_OK
