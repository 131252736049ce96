"""Sibling leaves whose bounds agree, stored as their parent: fewer, larger leaves carrying the
same statuses.

The certificate cuts a cell wherever a bound needs it (the endpoint bound above the tolerance,
the clearance's gap, the infeasibility close to proven); once both halves are proven, the proof's
result can often be stored coarser than the proof ran. Two leaves that are the two halves of one
node of the subpaving's tree are replaced by that node when

* they have the same status, and their endpoint bounds are on the same side of the tolerance;
* their clearance bounds differ by at most ``spread_m``, and so do their endpoint bounds.

The node then carries the smaller clearance bound and the larger endpoint bound and endpoint
clearance upper bound of the two. Each is a valid bound over the node, since the node is the
union of the two halves and each value bounds its half (a minimum of lower bounds is a lower
bound over the union, a maximum of upper bounds an upper bound). The status is kept: the
statuses are thresholds of those bounds (``range_certificate.statuses``: the margin where the
clearance bound reaches it, collision-free where it is positive, infeasible where the upper
bound is below the margin), and a minimum or maximum of two values on the same side of a
threshold stays on that side. What is lost is at most ``spread_m`` of each bound over either
half. Merged nodes merge again with their siblings by the same rule, from the deepest nodes up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.certify.subpaving import Subpaving
from pipeline.exceptions import InvalidParameterError
from pipeline.validation import check_non_negative

__all__ = ["MergedLeaves", "merge_leaves"]


@dataclass(frozen=True, eq=False)
class MergedLeaves:
    """Leaves after :func:`merge_leaves`, in the order of a walk of the tree from its root.

    Attributes:
        levels: Each leaf's level along every axis, (n, k).
        index: Each leaf's index along every axis, (n, k).
        clearance_bound_m: Lower bound on the clearance over each leaf [m], (n,).
        endpoint_bound_m: Upper bound on the endpoint errors over each leaf [m], (n,).
        endpoint_clearance_upper_m: Upper bound on the end poses' room over each leaf [m], (n,).
    """

    levels: np.ndarray
    index: np.ndarray
    clearance_bound_m: np.ndarray
    endpoint_bound_m: np.ndarray
    endpoint_clearance_upper_m: np.ndarray


def _halves(
    tree: Subpaving, nodes: np.ndarray, levels: np.ndarray, indices: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two halves of each of ``nodes`` (of the given levels and indices (m, k)), lower then
    upper: their levels and indices (2m, k) and child codes (2m,) (a node >= 0, or -1 - leaf)."""
    a = tree.cut_axis[nodes].astype(np.int64)
    rows = np.arange(nodes.size)
    child_levels, child_indices = np.repeat(levels, 2, axis=0), np.repeat(indices, 2, axis=0)
    child_levels[2 * rows, a] += 1
    child_levels[2 * rows + 1, a] += 1
    child_indices[2 * rows, a] *= 2
    child_indices[2 * rows + 1, a] = 2 * child_indices[2 * rows + 1, a] + 1
    return child_levels, child_indices, tree.children[nodes].reshape(-1).astype(np.int64)


def _nodes_by_depth(tree: Subpaving) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per depth of the tree, its internal nodes with their levels and indices (m, k)."""
    k = tree.k
    node = np.array([0], dtype=np.int64)
    levels, indices = np.zeros((1, k), dtype=np.int64), np.zeros((1, k), dtype=np.int64)
    out = []
    while node.size:
        out.append((node, levels, indices))
        child_levels, child_indices, codes = _halves(tree, node, levels, indices)
        inner = codes >= 0
        node, levels, indices = codes[inner], child_levels[inner], child_indices[inner]
    return out


def merge_leaves(
    ranges,
    levels: np.ndarray,
    index: np.ndarray,
    status: np.ndarray,
    bounds: tuple[np.ndarray, np.ndarray, np.ndarray],
    tolerance_m: float,
    spread_m: float,
) -> MergedLeaves:
    """Merge sibling leaves whose bounds agree (module docstring).

    Args:
        ranges: (lo, hi) of every axis.
        levels: Each leaf's level along every axis, (n, k).
        index: Each leaf's index along every axis, (n, k).
        status: Each leaf's status (any integer code), (n,).
        bounds: Per leaf, the clearance bound, the endpoint bound and the endpoint clearance
            upper bound [m], each (n,).
        tolerance_m: The endpoint tolerance [m].
        spread_m: How far two leaves' clearance bounds, and their endpoint bounds, may differ [m].

    Raises:
        InvalidParameterError: a negative spread, or columns of other lengths than the leaves.
    """
    check_non_negative("spread_m", spread_m)
    columns = [np.asarray(status), *(np.asarray(b, dtype=float) for b in bounds)]
    n = np.asarray(levels).shape[0]
    if any(c.shape != (n,) for c in columns):
        raise InvalidParameterError("columns", [c.shape for c in columns], f"({n},) per leaf")
    tree = Subpaving.from_leaves(ranges, levels, index)
    if tree.cut_axis.size == 0:  # one leaf: nothing to merge
        return MergedLeaves(tree.levels, tree.indices, *columns[1:])
    leaf = np.column_stack([columns[0], *columns[1:], columns[1], columns[2]]).astype(float)
    # Per leaf and per node: status, least and largest clearance bound, largest endpoint bound,
    # largest upper bound, then the largest clearance bound and least endpoint bound (spreads).
    node = np.full((tree.cut_axis.size, 6), np.nan)
    merged = np.zeros(tree.cut_axis.size, dtype=bool)
    for nodes, _, _ in reversed(_nodes_by_depth(tree)):
        halves = []
        for side in (0, 1):
            code = tree.children[nodes, side].astype(np.int64)
            value = np.where((code < 0)[:, None], leaf[np.maximum(-1 - code, 0)], node[np.maximum(code, 0)])
            ready = (code < 0) | merged[np.maximum(code, 0)]
            halves.append((value, ready))
        (a, ready_a), (b, ready_b) = halves
        low, high = np.minimum(a, b), np.maximum(a, b)
        ok = ready_a & ready_b & (a[:, 0] == b[:, 0])
        ok &= (a[:, 2] <= tolerance_m) == (b[:, 2] <= tolerance_m)
        ok &= high[:, 4] - low[:, 1] <= spread_m
        ok &= high[:, 2] - low[:, 5] <= spread_m
        node[nodes[ok]] = np.column_stack([a[ok, 0], low[ok, 1], high[ok, 2], high[ok, 3], high[ok, 4], low[ok, 5]])
        merged[nodes[ok]] = True
    return _leaves_of(tree, leaf, node, merged)


def _leaves_of(tree: Subpaving, leaf: np.ndarray, node: np.ndarray, merged: np.ndarray) -> MergedLeaves:
    """The leaves of the tree with its merged nodes as leaves, walking down from the root."""
    k = tree.k
    if merged[0]:
        return MergedLeaves(np.zeros((1, k), dtype=np.int64), np.zeros((1, k), dtype=np.int64), *node[0, 1:4, None])
    out: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    frontier = np.array([0], dtype=np.int64)
    levels, indices = np.zeros((1, k), dtype=np.int64), np.zeros((1, k), dtype=np.int64)
    while frontier.size:
        levels, indices, codes = _halves(tree, frontier, levels, indices)
        is_leaf = codes < 0
        is_merged = ~is_leaf & merged[np.maximum(codes, 0)]
        values = np.where(is_leaf[:, None], leaf[np.maximum(-1 - codes, 0)], node[np.maximum(codes, 0)])
        done = is_leaf | is_merged
        out.append((levels[done], indices[done], values[done, 1:4]))
        frontier, levels, indices = codes[~done], levels[~done], indices[~done]
    levels, indices, values = (np.concatenate(part) for part in zip(*out, strict=True))
    return MergedLeaves(levels, indices, *values.T)
