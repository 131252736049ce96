"""The scalar lookup of a region map, compiled: the leaf holding one point, read from the map's
index as two flat arrays.

:class:`LookupTables` holds a map's lookup (:attr:`pipeline.certify.region_map.RegionMap.lookup_tables`
makes it): its index, and the fitted ranges with every leaf's bounds. :func:`leaf_of` finds the
leaf of one point in it, by the floating-point operations of the vectorised
:meth:`pipeline.certify.region_map.RegionMap.leaf_indices` (a division, a product by a power of
two, a truncation; the region map's module docstring), so it finds the same leaf, and
:func:`bounds_of` reads that leaf's bounds. The map's scalar lookups (``cell_at``, ``bounds_at``,
``leaf_at``) and the online generator's compiled core (:mod:`pipeline.online.kernel`) both call
them: one scalar lookup.

Both are compiled with Numba for their one signature when this module is imported, and
cached on disk (``cache=True``). The arrays are writable copies because Numba's dispatch of a
read-only array costs twice as much; do not modify them.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

__all__ = [
    "LOOKUP_HEADER",
    "LOOKUP_SIZE",
    "LOOKUP_TREE",
    "NO_MAP",
    "NO_TABLES",
    "LookupTables",
    "bounds_of",
    "leaf_of",
]

#: The mode (``LookupTables.index[0]``) of no map: every point is outside (:data:`NO_TABLES`).
NO_MAP = 0
#: The mode of a map over (L, W): a dense index of the deepest level, strips along W.
LOOKUP_SIZE = 1
#: The mode of a map over k > 2 axes: a coarse dense index, then rows of 2^k children.
LOOKUP_TREE = 2
#: The length of ``LookupTables.index``'s header.
LOOKUP_HEADER = 6


class LookupTables(NamedTuple):
    """The scalar lookup of a map as two flat arrays.

    Attributes:
        index: int32: a header of :data:`LOOKUP_HEADER` (mode, 2^D, D - C, C, row width, start
            of the rows), then the dense index, flat, then the rows of strips or children, flat.
            The mode is :data:`LOOKUP_SIZE` or :data:`LOOKUP_TREE`, D the deepest depth, C the
            dense index's depth (D over (L, W)); a row holds 2^E strips over (L, W), 2^k
            children over k axes. An entry >= 0 is a leaf, -r - 1 the r-th row.
        bounds: float64: the fitted range (lo, hi) of every axis, in the map's axes order [m],
            then per leaf its clearance bound [m], endpoint-error bound [m] and status (the index
            into ``pipeline.certify.region_map.STATUSES``, exact as a float).
    """

    index: np.ndarray
    bounds: np.ndarray

    def leaf_bounds(self, axes: int, leaf: int) -> tuple[float, float, int]:
        """(clearance bound [m], endpoint-error bound [m], status index) of ``leaf`` of a map over
        ``axes`` axes (:func:`bounds_of`)."""
        return bounds_of(self.bounds, axes, leaf)


def _no_tables() -> LookupTables:
    header = np.zeros(LOOKUP_HEADER, dtype=np.int32)
    header[0] = NO_MAP
    return LookupTables(header, np.zeros(0))


#: The lookup of no map (every point outside): the arrays' types are a map's, so that one
#: compiled function serves both.
NO_TABLES = _no_tables()


@numba.njit("Tuple((float64, float64, int64))(float64[::1], int64, int64)", cache=True, nogil=True)
def bounds_of(bounds: np.ndarray, axes: int, leaf: int) -> tuple[float, float, int]:
    """(clearance bound [m], endpoint-error bound [m], status index) of ``leaf``, read from
    ``LookupTables.bounds`` of a map over ``axes`` axes."""
    at = 2 * axes + 3 * leaf
    return bounds[at], bounds[at + 1], int(bounds[at + 2])


@numba.njit("int64(float64, float64, float64, int64)", cache=True, nogil=True)
def _cell(value: float, lo: float, hi: float, n: int) -> int:
    """The cell (0 .. n - 1) of ``value`` in [lo, hi] cut into n, as RegionMap.leaf_indices finds it."""
    return min(int((value - lo) / (hi - lo) * n), n - 1)


@numba.njit("int64(int32[::1], float64[::1], int64, float64, float64, float64, float64)", cache=True, nogil=True)
def leaf_of(index: np.ndarray, bounds: np.ndarray, axes: int, v0: float, v1: float, v2: float, v3: float) -> int:
    """The leaf holding the point (v0, ..., v_(axes - 1)) [m] (L, W, then the map's other axes in
    order; the values past ``axes`` are not read), as :meth:`RegionMap.leaf_indices` finds it;
    -1 outside the fitted box, or for :data:`NO_TABLES`."""
    if index[0] == NO_MAP:
        return -1
    values = (v0, v1, v2, v3)
    for a in range(axes):
        if not (bounds[2 * a] <= values[a] <= bounds[2 * a + 1]):
            return -1
    mode, n, shift, coarse, width, rows = index[0], index[1], index[2], index[3], index[4], index[5]
    if mode == LOOKUP_SIZE:
        i = _cell(v0, bounds[0], bounds[1], n)
        v = (v1 - bounds[2]) / (bounds[3] - bounds[2]) * n
        j = min(int(v), n - 1)
        leaf = index[LOOKUP_HEADER + i * n + j]
        if leaf >= 0:
            return leaf
        slot = min(max(int(v * width) - j * width, 0), width - 1)
        return index[rows + (-leaf - 1) * width + slot]
    key = 0
    for a in range(axes):
        key = (key << coarse) | (_cell(values[a], bounds[2 * a], bounds[2 * a + 1], n) >> shift)
    leaf = index[LOOKUP_HEADER + key]
    while leaf < 0:
        shift -= 1
        slot = 0
        for a in range(axes):
            slot = (slot << 1) | ((_cell(values[a], bounds[2 * a], bounds[2 * a + 1], n) >> shift) & 1)
        leaf = index[rows + (-leaf - 1) * width + slot]
    return leaf
