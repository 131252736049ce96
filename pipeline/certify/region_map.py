"""The region map: a 2^k-tree over the fitted box of the coefficients' scene variables (a
quadtree over (L, W), an octree over (L, W, x), ...) whose leaves carry the range certificate's
bounds and a status, stored as JSON beside the coefficients it certifies.

The map's ``axes`` are the coefficients' variables in their canonical order
(:mod:`pipeline.offline.variables`): always L and W first, then any of x, d. A leaf is the node
(depth, i_1, ..., i_k): along every axis a it spans a_lo + [i_a, i_a + 1] (a_hi - a_lo) / 2^depth,
so its volume fraction of the box is 2^-(k depth). Over (L, W) alone a leaf may be cut further
along W only: with ``split_W`` = e, W in W_lo + [i_W, i_W + 1] (W_hi - W_lo) / 2^(depth + e)
(e = 0 for a plain quadtree leaf; e > 0 only at the deepest level, where the range certificate
cuts the smallest cells that straddle the margin's or the infeasibility's contour, both of which
run along L near W = 0.12 m on the default build); its area fraction is then 2^-(2 depth + e).
Maps over more axes have no such strips (``split_W`` = 0 throughout). Statuses:

* ``margin``: clearance certified >= the margin over the whole cell and all of [0, T];
* ``collision_free``: clearance certified > 0, not >= the margin, and not proven infeasible;
* ``infeasible``: no trajectory of the family can keep both the endpoint tolerance and the
  margin in this cell (``pipeline.certify.endpoints``); its clearance bound is still stored
  (and is > 0 where the coefficients are collision-free there);
* ``undecided``: not even collision-free was certified at the smallest cell.

Every lookup takes the values in the order of ``axes``: ``cell_at(L, W)`` for a map over (L, W),
``cell_at(L, W, x)`` for one over (L, W, x). A point is placed by its scaled coordinates
u_a = (v_a - a_lo) / (a_hi - a_lo) 2^D along every axis (D the deepest depth): the cell of depth
d holding it has index floor(u_a) >> (D - d) along a (the last cell for v_a = a_hi). Scaling by a
power of two is exact in floating point, so the cells found at different depths are nested.

Over (L, W) the lookups (:meth:`RegionMap.cell_at`, :meth:`RegionMap.cells_at`) go through a
dense index of the deepest level, so they cost one multiplication and one array read per query
(int32: 4 MiB for cells of 1/1024). A deepest cell that is split along W
holds -(1 + slot) there, and row ``slot`` of a second table holds its 2^E sub-leaves (E the
largest ``split_W``): one more read. The sub-cell is found from the same scaled coordinate v =
(W - W_lo) / (W_hi - W_lo) 2^depth as the cell, as floor(v 2^E) - 2^E floor(v): scaling by 2^E
is exact in floating point, so a point is never placed in a sub-cell of a neighbouring cell.

Over k > 2 axes a dense index of the deepest level would hold 2^(k D) entries (2^24 for an
octree of depth 8), so the dense index covers the coarse level C = min(D, floor(22 / k)) (at
most 2^22 entries: 8 MiB of int32 for k = 3, C = 7), and the tree below it is stored as a table
of 2^k-child rows. A coarse entry holds the leaf covering that coarse cell, or -(1 + row) when
the cell is cut further; row ``row`` holds, for each of the node's 2^k children (child number
sum_a b_a 2^(k - 1 - a), b_a the child's half along axis a), again a leaf or -(1 + row') of a
deeper node. A lookup reads the coarse entry, then one row per level below C down to its leaf
(none for a tree no deeper than C). The rows take 4 2^k bytes per cut node of depth C or more,
about 4 bytes per leaf deeper than C: a map of a million such leaves needs about 5 MB beside the
coarse index. The batch lookups descend all points level by level, vectorised.

The scalar lookups (:meth:`RegionMap.cell_at`, :meth:`RegionMap.bounds_at`,
:meth:`RegionMap.leaf_at`) and the online generator's compiled core read a copy of both tables
as flat arrays (:attr:`RegionMap.lookup_tables`) through one compiled function,
:func:`pipeline.certify.lookup.leaf_of`, by the same floating-point operations.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pipeline.certify.execution_bounds import ExecutionBounds
from pipeline.certify.interval import FLOAT_SLACK_M
from pipeline.exceptions import DataFileError, InvalidParameterError, OutOfFittedRangeError
from pipeline.io.jsonio import json_safe, write_text_atomic
from pipeline.offline.variables import NAMES, SIZE
from pipeline.validation import check_non_negative

if TYPE_CHECKING:
    from pipeline.certify.lookup import LookupTables
    from pipeline.certify.near_optimal_cells import NearOptimalCells

#: Format of a map over (L, W).
FORMAT = "twolink-region-map/2"
#: Format of a map over more axes than (L, W): ``axes``, a fitted range and an ``index_<name>``
#: column per axis, no ``split_W`` column.
FORMAT_KD = "twolink-region-map/3"
#: Formats read: /1 has no ``split_W`` column (every leaf a quadtree node).
READABLE_FORMATS = ("twolink-region-map/1", FORMAT, FORMAT_KD)
#: Most entries of the dense index of a map over more than (L, W) (module docstring).
DENSE_INDEX_ENTRIES = 2**22
STATUSES: tuple[str, ...] = ("margin", "collision_free", "infeasible", "undecided")
#: File name of the map written beside a coefficients file.
DEFAULT_MAP_NAME = "region_map.json"
_COLUMNS = (
    "depth",
    "index_L",
    "index_W",
    "clearance_bound_m",
    "endpoint_bound_m",
    "endpoint_clearance_upper_m",
    "status",
)


@dataclass(frozen=True)
class RegionCell:
    """One leaf of the map.

    Attributes:
        length_range_m, width_range_m: The cell's (lo, hi) in L and W [m].
        clearance_bound_m: Lower bound on the clearance of both links over the cell and all of [0, T] [m].
        endpoint_bound_m: Upper bound on max(|tip(0) - P1|, |tip(T) - P5|) over the cell [m].
        endpoint_clearance_upper_m: Upper bound on the clearance of poses within the endpoint
            tolerance of P1 or P5 (the smaller of the two) [m]; below the margin: infeasible.
        status: One of :data:`STATUSES`.
        depth: Tree depth (the cell spans 1 / 2^depth of the range in L and in every extra axis).
        split_w: Further halvings along W (the cell spans 1 / 2^(depth + split_w) of the range in W).
        extra_ranges_m: The cell's (lo, hi) along each axis beyond L and W, in the map's ``axes``
            order [m]; () for a map over (L, W).
    """

    length_range_m: tuple[float, float]
    width_range_m: tuple[float, float]
    clearance_bound_m: float
    endpoint_bound_m: float
    endpoint_clearance_upper_m: float
    status: str
    depth: int
    split_w: int = 0
    extra_ranges_m: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise InvalidParameterError("status", self.status, f"one of {STATUSES}")


@dataclass(frozen=True, eq=False)
class RegionMap:
    """The certified map of one coefficients file, over the box of its ``axes`` (module docstring).

    Attributes:
        family: Trajectory family of the coefficients.
        coefficients_source: File name (or PAPER_SOURCE) of the coefficients, without its folder
            (:func:`source_name`), so that the map's bytes do not depend on where the build ran;
            the link itself is the sha256.
        coefficients_sha256: sha256 of the coefficients file: the link between map and coefficients.
        length_range_m, width_range_m: The fitted range of L and W [m].
        margin_m: The margin the statuses refer to [m].
        endpoint_tolerance_m: The endpoint tolerance of the infeasibility certificate [m].
        depth, index_l, index_w: Leaf nodes, int arrays (n,) (index_w counts cells of W at depth
            + split_w); the indices along the extra axes are in ``extra_index``.
        clearance_bound_m, endpoint_bound_m, endpoint_clearance_upper_m: Per leaf [m], (n,).
        status: Per leaf, index into :data:`STATUSES`, (n,).
        seconds: Wall time of the certificate [s]; NaN for a map read from a file (not stored, so
            that the file's bytes depend only on the coefficients and the settings).
        details: Settings and counters (plain JSON).
        split_w: Per leaf, further halvings along W (module docstring), int array (n,); None: all 0.
        execution: Per leaf, the execution bounds for the arm the map was built with (joint
            angle ranges, the paper timing's speed, acceleration and torque bounds, the
            rest-to-rest timing within the arm's limits; :mod:`pipeline.certify.execution_bounds`),
            or None.
        axes: The map's axes, the coefficients' variables in canonical order: ("L", "W"), or L, W
            and names of :data:`pipeline.offline.variables.NAMES` (e.g. ("L", "W", "x")).
        extra_ranges_m: The fitted range (lo, hi) of each axis beyond L and W, in ``axes`` order [m].
        near_optimal_cells: The certified near-optimal timings per cell of a grid over the range
            (:mod:`pipeline.certify.near_optimal_cells`, stored in files of their own), or None.
        extra_index: Per leaf, its node index along each axis beyond L and W, int array (n, k - 2)
            (counting cells at the leaf's depth); None for a map over (L, W).
    """

    family: str
    coefficients_source: str
    coefficients_sha256: str
    length_range_m: tuple[float, float]
    width_range_m: tuple[float, float]
    margin_m: float
    endpoint_tolerance_m: float
    depth: np.ndarray
    index_l: np.ndarray
    index_w: np.ndarray
    clearance_bound_m: np.ndarray
    endpoint_bound_m: np.ndarray
    endpoint_clearance_upper_m: np.ndarray
    status: np.ndarray
    seconds: float = 0.0
    details: dict = field(default_factory=dict)
    split_w: np.ndarray | None = None
    execution: ExecutionBounds | None = None
    axes: tuple[str, ...] = SIZE
    extra_ranges_m: tuple[tuple[float, float], ...] = ()
    extra_index: np.ndarray | None = None
    near_optimal_cells: NearOptimalCells | None = None
    _index: np.ndarray = field(init=False, repr=False)
    _sub_index: np.ndarray = field(init=False, repr=False)
    _coarse_depth: int = field(init=False, repr=False)

    def __post_init__(self) -> None:
        check_non_negative("margin_m", self.margin_m)
        check_non_negative("endpoint_tolerance_m", self.endpoint_tolerance_m)
        for name in ("length_range_m", "width_range_m"):
            lo, hi = getattr(self, name)
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise InvalidParameterError(name, getattr(self, name), "finite lo < hi")
        axes = _checked_axes(self.axes)
        k = len(axes)
        extra_ranges = _checked_extra_ranges(self.extra_ranges_m, axes)
        arrays = {
            "depth": np.asarray(self.depth, dtype=np.int64),
            "index_l": np.asarray(self.index_l, dtype=np.int64),
            "index_w": np.asarray(self.index_w, dtype=np.int64),
            "clearance_bound_m": np.asarray(self.clearance_bound_m, dtype=float),
            "endpoint_bound_m": np.asarray(self.endpoint_bound_m, dtype=float),
            "endpoint_clearance_upper_m": np.asarray(self.endpoint_clearance_upper_m, dtype=float),
            "status": np.asarray(self.status, dtype=np.int64),
            "split_w": np.zeros_like(np.asarray(self.depth, dtype=np.int64))
            if self.split_w is None
            else np.asarray(self.split_w, dtype=np.int64),
        }
        n = arrays["depth"].size
        if n == 0 or any(a.shape != (n,) for a in arrays.values()):
            raise InvalidParameterError("cells", {k: a.shape for k, a in arrays.items()}, "equal non-empty 1-D arrays")
        if np.any(arrays["status"] < 0) or np.any(arrays["status"] >= len(STATUSES)):
            raise InvalidParameterError("status", "out of range", f"indices into {STATUSES}")
        depth, split = arrays["depth"], arrays["split_w"]
        deepest = 20 if k == 2 else min(20, 60 // k)
        if np.any(depth < 0) or np.any(depth > deepest):
            raise InvalidParameterError("depth", int(depth.max()), f"0..{deepest} for {k} axes")
        top = int(depth.max())
        if k > 2 and np.any(split != 0):
            raise InvalidParameterError("split_w", int(np.abs(split).max()), f"0 for a map over {', '.join(axes)}")
        if np.any(split < 0) or np.any(split > 10) or np.any((split > 0) & (depth < top)):
            raise InvalidParameterError("split_w", int(split.max()), "0..10, non-zero only at the deepest level")
        if np.any(arrays["index_l"] < 0) or np.any(arrays["index_l"] >= 2**depth):
            raise InvalidParameterError("index_l", "out of range", "0 <= index < 2^depth")
        if np.any(arrays["index_w"] < 0) or np.any(arrays["index_w"] >= 2 ** (depth + split)):
            raise InvalidParameterError("index_w", "out of range", "0 <= index < 2^(depth + split_w)")
        extra_index = _checked_extra_index(self.extra_index, axes, depth)
        volume = float(np.sum(2.0 ** (-(k * depth + split).astype(float))))
        if not math.isclose(volume, 1.0, rel_tol=1e-9):
            raise InvalidParameterError("cells", volume, "leaves tiling the range")
        if self.execution is not None and (not isinstance(self.execution, ExecutionBounds) or self.execution.size != n):
            raise InvalidParameterError("execution", type(self.execution).__name__, f"ExecutionBounds of {n} leaves")
        for key, value in arrays.items():
            value.setflags(write=False)
            object.__setattr__(self, key, value)
        object.__setattr__(self, "axes", axes)
        object.__setattr__(self, "extra_ranges_m", extra_ranges)
        object.__setattr__(self, "extra_index", extra_index)
        if extra_index is None:
            index, sub_index = _dense_index(depth, arrays["index_l"], arrays["index_w"], split)
            coarse = top
        else:
            columns = np.column_stack([arrays["index_l"], arrays["index_w"], extra_index])
            index, sub_index, coarse = _tree_index(depth, columns)
        object.__setattr__(self, "_index", index)
        object.__setattr__(self, "_sub_index", sub_index)
        object.__setattr__(self, "_coarse_depth", coarse)

    # ------------------------------------------------------------------ lookup

    def leaf_indices(self, length_m, width_m, *extra) -> np.ndarray:
        """Leaf index of each point (vectorised): L, W [m] and the values of the extra axes in
        ``axes`` order (arrays or scalars, broadcast together); -1 outside the fitted box.

        Raises:
            InvalidParameterError: not one value (array) per axis (the message names the axis
                missing, or the values beyond the map's axes).
        """
        if extra or self.extra_index is not None:
            return self._leaf_indices_kd(length_m, width_m, self._extra_values(extra))
        L, W = np.broadcast_arrays(np.asarray(length_m, dtype=float), np.asarray(width_m, dtype=float))
        shape = L.shape
        L, W = L.ravel(), W.ravel()
        (l_lo, l_hi), (w_lo, w_hi) = self.length_range_m, self.width_range_m
        n = self._index.shape[0]
        u = (L - l_lo) / (l_hi - l_lo) * n
        v = (W - w_lo) / (w_hi - w_lo) * n
        inside = (L >= l_lo) & (L <= l_hi) & (W >= w_lo) & (W <= w_hi)
        i = np.clip(np.floor(np.where(inside, u, 0.0)).astype(np.int64), 0, n - 1)
        j = np.clip(np.floor(np.where(inside, v, 0.0)).astype(np.int64), 0, n - 1)
        leaf = self._index[i, j].astype(np.int64)
        split = leaf < 0
        if np.any(split):  # a split deepest cell: its sub-leaf along W (module docstring)
            s = self._sub_index.shape[1]
            sub = np.clip(np.floor(v[split] * s).astype(np.int64) - j[split] * s, 0, s - 1)
            leaf[split] = self._sub_index[-leaf[split] - 1, sub]
        return np.where(inside, leaf, -1).reshape(shape)

    def cells_at(self, length_m, width_m, *extra) -> dict[str, np.ndarray]:
        """Batch lookup: per point (L, W [m] and the extra axes' values in ``axes`` order), the
        leaf, its clearance bound, endpoint bound and status index (-1 / NaN outside the fitted box)."""
        leaf = self.leaf_indices(length_m, width_m, *extra)
        inside = leaf >= 0
        safe = np.where(inside, leaf, 0)
        return {
            "leaf": leaf,
            "clearance_bound_m": np.where(inside, self.clearance_bound_m[safe], np.nan),
            "endpoint_bound_m": np.where(inside, self.endpoint_bound_m[safe], np.nan),
            "status": np.where(inside, self.status[safe], -1),
        }

    def cell(self, leaf: int) -> RegionCell:
        """The leaf number ``leaf`` as a :class:`RegionCell`."""
        d, e = int(self.depth[leaf]), int(self.split_w[leaf])
        (l_lo, l_hi), (w_lo, w_hi) = self.length_range_m, self.width_range_m
        dl, dw = (l_hi - l_lo) / 2**d, (w_hi - w_lo) / 2 ** (d + e)
        il, iw = int(self.index_l[leaf]), int(self.index_w[leaf])
        extra = ()
        if self.extra_index is not None:
            extra = tuple(
                (lo + int(i) * ((hi - lo) / 2**d), lo + (int(i) + 1) * ((hi - lo) / 2**d))
                for (lo, hi), i in zip(self.extra_ranges_m, self.extra_index[leaf], strict=True)
            )
        return RegionCell(
            length_range_m=(l_lo + il * dl, l_lo + (il + 1) * dl),
            width_range_m=(w_lo + iw * dw, w_lo + (iw + 1) * dw),
            clearance_bound_m=float(self.clearance_bound_m[leaf]),
            endpoint_bound_m=float(self.endpoint_bound_m[leaf]),
            endpoint_clearance_upper_m=float(self.endpoint_clearance_upper_m[leaf]),
            status=STATUSES[int(self.status[leaf])],
            depth=d,
            split_w=e,
            extra_ranges_m=extra,
        )

    def cell_at(self, length_m: float, width_m: float, *extra: float) -> RegionCell:
        """The leaf containing the point (L, W [m] and the extra axes' values in ``axes`` order).

        Raises:
            OutOfFittedRangeError: the point lies outside the fitted box (the message names the axis).
            InvalidParameterError: not one value per axis.
        """
        values = (length_m, width_m, *self._extra_values(extra))
        for name, value, (lo, hi) in zip(self.axes, values, self._ranges, strict=True):
            if not lo <= value <= hi:
                raise OutOfFittedRangeError(name, value, (lo, hi))
        return self.cell(self._leaf_of(values))

    def bounds_at(self, length_m: float, width_m: float, *extra: float) -> tuple[float, float, str] | None:
        """(clearance bound [m], endpoint-error bound [m], status) of the leaf holding the point
        (L, W [m] and the extra axes' values in ``axes`` order), or None outside the fitted box:
        the online generator's lookup (no cell object built).

        Raises:
            InvalidParameterError: not one value per axis.
        """
        leaf = self.leaf_at(length_m, width_m, *extra)
        if leaf is None:
            return None
        clearance, endpoint, status = self.lookup_tables.leaf_bounds(len(self.axes), leaf)
        return clearance, endpoint, STATUSES[status]

    def leaf_at(self, length_m: float, width_m: float, *extra: float) -> int | None:
        """Leaf number of the point (L, W [m] and the extra axes' values in ``axes`` order), or
        None outside the fitted box (scalar lookup: :func:`pipeline.certify.lookup.leaf_of`).

        Raises:
            InvalidParameterError: not one value per axis.
        """
        leaf = self._leaf_of((length_m, width_m, *self._extra_values(extra)))
        return None if leaf < 0 else leaf

    def _leaf_of(self, values: tuple) -> int:
        """Leaf of the point ``values`` (one per axis), -1 outside the fitted box."""
        from pipeline.certify.lookup import leaf_of  # Numba: imported on the first scalar lookup

        padded = (*values, 0.0, 0.0)
        return int(leaf_of(*self.lookup_tables, len(self.axes), padded[0], padded[1], padded[2], padded[3]))

    def _extra_values(self, extra: tuple) -> tuple:
        """``extra`` if it holds one value per axis beyond L and W.

        Raises:
            InvalidParameterError: a value missing (named by its axis) or values beyond the axes.
        """
        wanted = len(self.axes) - 2
        if len(extra) == wanted:
            return extra
        axes = ", ".join(self.axes)
        if len(extra) < wanted:
            missing = self.axes[2 + len(extra)]
            raise InvalidParameterError(missing, None, f"a value: the map's axes are {axes} ({missing} is missing)")
        raise InvalidParameterError(
            "values beyond the map's axes", extra[wanted:], f"one value per axis, the map's axes are {axes} only"
        )

    def _leaf_indices_kd(self, length_m, width_m, extra: tuple) -> np.ndarray:
        """:meth:`leaf_indices` over all the map's axes, vectorised level by level (module docstring)."""
        points = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (length_m, width_m, *extra)))
        shape = points[0].shape
        top, coarse = int(self.depth.max()), self._coarse_depth
        n = 1 << top
        inside = np.ones(points[0].size, dtype=bool)
        for value, (lo, hi) in zip(points, self._ranges, strict=True):
            value = value.ravel()
            inside &= (value >= lo) & (value <= hi)
        cells = []
        key = np.zeros(inside.size, dtype=np.int64)
        for value, (lo, hi) in zip(points, self._ranges, strict=True):
            u = np.where(inside, (value.ravel() - lo) / (hi - lo) * n, 0.0)
            t = np.clip(np.floor(u).astype(np.int64), 0, n - 1)
            cells.append(t)
            key = (key << coarse) | (t >> (top - coarse))
        leaf = self._index[key].astype(np.int64)
        pending = np.flatnonzero(leaf < 0)
        shift = top - coarse
        while pending.size:
            shift -= 1
            slot = np.zeros(pending.size, dtype=np.int64)
            for t in cells:
                slot = (slot << 1) | ((t[pending] >> shift) & 1)
            leaf[pending] = self._sub_index[-leaf[pending] - 1, slot]
            pending = pending[leaf[pending] < 0]
        return np.where(inside, leaf, -1).reshape(shape)

    @cached_property
    def _ranges(self) -> tuple[tuple[float, float], ...]:
        """The fitted range of every axis, in ``axes`` order [m]."""
        return (tuple(self.length_range_m), tuple(self.width_range_m), *self.extra_ranges_m)

    @cached_property
    def lookup_tables(self) -> LookupTables:
        """The scalar lookup as two flat arrays (:class:`pipeline.certify.lookup.LookupTables`;
        copies, not to be modified), built on first use."""
        from pipeline.certify.lookup import LOOKUP_HEADER, LOOKUP_SIZE, LOOKUP_TREE, LookupTables

        top = int(self.depth.max())
        mode, coarse = (LOOKUP_SIZE, top) if self.extra_index is None else (LOOKUP_TREE, self._coarse_depth)
        rows = LOOKUP_HEADER + self._index.size
        header = [mode, 1 << top, top - coarse, coarse, self._sub_index.shape[1], rows]
        index = np.concatenate([header, self._index.reshape(-1), self._sub_index.reshape(-1)]).astype(np.int32)
        leaves = np.column_stack([self.clearance_bound_m, self.endpoint_bound_m, self.status.astype(float)])
        bounds = np.concatenate([np.array(self._ranges, dtype=float).reshape(-1), leaves.reshape(-1)])
        return LookupTables(index, bounds)

    # ------------------------------------------------------------------ summary

    @property
    def area(self) -> np.ndarray:
        """Volume fraction of each leaf in the fitted box (the area fraction over (L, W)), (n,)."""
        return 2.0 ** (-(len(self.axes) * self.depth + self.split_w).astype(float))

    def leaf_sizes_m(self) -> np.ndarray:
        """Side lengths of each leaf [m] along every axis, (n, k): (L, W) over (L, W), (n, 2)."""
        lo = np.array([self.length_range_m[0], self.width_range_m[0]])
        size = np.array([self.length_range_m[1], self.width_range_m[1]]) - lo
        if self.extra_index is None:
            return size / 2.0 ** np.stack([self.depth, self.depth + self.split_w], -1)
        ranges = np.array(self._ranges)
        return (ranges[:, 1] - ranges[:, 0]) / 2.0 ** self.depth[:, None]

    def leaf_centres_m(self) -> np.ndarray:
        """Centre of each leaf [m] along every axis, (n, k): (L, W) over (L, W), (n, 2)."""
        if self.extra_index is None:
            lo = np.array([self.length_range_m[0], self.width_range_m[0]])
            return lo + (np.stack([self.index_l, self.index_w], -1) + 0.5) * self.leaf_sizes_m()
        lo = np.array(self._ranges)[:, 0]
        index = np.column_stack([self.index_l, self.index_w, self.extra_index])
        return lo + (index + 0.5) * self.leaf_sizes_m()

    def summary(self) -> dict:
        """Volume fractions of the fitted box per status (area fractions over (L, W)), extreme
        bounds and time (plain JSON); over more axes than (L, W) also the ``axes``."""
        area = self.area
        fractions = {name: float(np.sum(area[self.status == k])) for k, name in enumerate(STATUSES)}
        feasible = 1.0 - fractions["infeasible"]
        worst = int(np.argmin(self.clearance_bound_m))
        worst_cell = self.cell(worst)
        extra_worst = {
            f"{name}_m": list(bounds) for name, bounds in zip(self.axes[2:], worst_cell.extra_ranges_m, strict=True)
        }
        return (
            ({} if self.extra_index is None else {"axes": list(self.axes)})
            | {
                "area_fraction": fractions,
                "certified_collision_free_fraction": float(np.sum(area[self.clearance_bound_m > 0.0])),
                "margin_fraction_of_feasible": fractions["margin"] / feasible if feasible > 0 else None,
                # Bounds carry the rounding slack, so a tolerance of 0 (pinned endpoints) is met up to it.
                "endpoint_within_tolerance_fraction": float(
                    np.sum(area[self.endpoint_bound_m <= self.endpoint_tolerance_m + FLOAT_SLACK_M])
                ),
                "clearance_bound_min_m": float(self.clearance_bound_m[worst]),
                "worst_cell": {
                    "L_m": list(worst_cell.length_range_m),
                    "W_m": list(worst_cell.width_range_m),
                    **extra_worst,
                },
                "endpoint_bound_max_m": float(np.max(self.endpoint_bound_m)),
                "margin_m": self.margin_m,
                "endpoint_tolerance_m": self.endpoint_tolerance_m,
                "cells": int(self.depth.size),
                "seconds": self.seconds,
            }
            | ({} if self.execution is None else {"execution": self.execution_summary()})
        )

    def execution_summary(self) -> dict | None:
        """Volume fractions of the fitted box (area fractions over (L, W)) where the paper
        timing's bounds break each limit of the map's arm (a leaf counts if its bound exceeds the
        limit: not proven to keep it), where a rest-to-rest timing keeps them all, and the longest
        rest-to-rest duration; None without execution bounds."""
        bounds = self.execution
        if bounds is None:
            return None
        area = self.area
        breaks = bounds.paper_breaks()
        any_break = np.any(np.stack(list(breaks.values())), 0)
        rest = np.isfinite(bounds.columns["speed_scale"]) & ~breaks["angle"]
        return {
            "paper_keeps_limits_fraction": float(np.sum(area[~any_break])),
            "paper_breaks_fraction": {k: float(np.sum(area[v])) for k, v in breaks.items()},
            "rest_to_rest_fraction": float(np.sum(area[rest])),
            "rest_to_rest_duration_max_s": float(np.max(bounds.rest_to_rest_duration_max_s[rest]))
            if rest.any()
            else None,
            "path_duration_max_s": float(np.max(bounds.columns["duration_hi_s"])),
        }

    def belongs_to(self, coefficients) -> bool:
        """True if this map was made from exactly these coefficients (same sha256) and its axes
        are their variables."""
        variables = getattr(getattr(coefficients, "variables", None), "names", SIZE)
        return (
            bool(self.coefficients_sha256)
            and self.coefficients_sha256 == coefficients.source_sha256
            and self.axes == tuple(variables)
        )

    # ------------------------------------------------------------------ JSON

    def header_json(self) -> dict:
        """What describes the map beside its leaves, as plain JSON: the link to its coefficients, the
        axes and the fitted range of each, margin and tolerance, the summary (without the wall time,
        nor the worker count in ``details``: the same coefficients and settings give the same bytes),
        the settings and the statuses."""
        fitted = {"L": list(self.length_range_m), "W": list(self.width_range_m)}
        fitted |= {name: list(bounds) for name, bounds in zip(self.axes[2:], self.extra_ranges_m, strict=True)}
        return {
            "coefficients": {
                "source": self.coefficients_source,
                "sha256": self.coefficients_sha256,
                "family": self.family,
            },
            "axes": list(self.axes),
            "fitted_range": fitted,
            "margin_m": self.margin_m,
            "endpoint_tolerance_m": self.endpoint_tolerance_m,
            "summary": {k: v for k, v in self.summary().items() if k != "seconds"},
            "details": self.details,
            "statuses": list(STATUSES),
        }

    def to_json(self) -> dict:
        """The plain-JSON document (columnar cells): format /2 over (L, W) (no ``axes``), /3 over more
        axes (an ``index_<axis>`` column per axis, no ``split_W`` column)."""
        header = self.header_json()
        columns: dict[str, list] = {"depth": self.depth.tolist()}
        columns["index_L"] = self.index_l.tolist()
        columns["index_W"] = self.index_w.tolist()
        if self.extra_index is not None:
            extra = zip(self.axes[2:], self.extra_index.T, strict=True)
            columns |= {f"index_{name}": index.tolist() for name, index in extra}
        columns |= {
            "clearance_bound_m": self.clearance_bound_m.tolist(),
            "endpoint_bound_m": self.endpoint_bound_m.tolist(),
            "endpoint_clearance_upper_m": self.endpoint_clearance_upper_m.tolist(),
            "status": [STATUSES[k] for k in self.status],
        }
        if self.extra_index is None:
            del header["axes"]
            document = {"format": FORMAT, **header, "cells": columns | {"split_W": self.split_w.tolist()}}
        else:
            document = {"format": FORMAT_KD, **header, "cells": columns}
        return document | ({} if self.execution is None else {"execution": self.execution.to_json()})

    @classmethod
    def from_json(cls, document: dict, source: object = "<memory>") -> RegionMap:
        """Validate a parsed map document.

        Raises:
            DataFileError: a field is missing or malformed.
        """
        if document.get("format") not in READABLE_FORMATS:
            expected = f"one of {', '.join(repr(f) for f in READABLE_FORMATS)}"
            raise DataFileError(source, f"format is {document.get('format')!r}, expected {expected}")
        try:
            fitted, cells = document["fitted_range"], document["cells"]
            axes = _checked_axes(tuple(document["axes"])) if document["format"] == FORMAT_KD else SIZE
            extra = axes[2:]
            missing = [c for c in (*_COLUMNS, *(f"index_{name}" for name in extra)) if c not in cells]
            if missing:
                raise DataFileError(source, f"cells lack {missing}")
            absent = [name for name in extra if name not in fitted]
            if absent:
                raise DataFileError(source, f"fitted_range lacks {absent}")
            status = [STATUSES.index(s) for s in cells["status"]]
            return cls(
                **header_fields(document),
                depth=np.array(cells["depth"], dtype=np.int64),
                index_l=np.array(cells["index_L"], dtype=np.int64),
                index_w=np.array(cells["index_W"], dtype=np.int64),
                clearance_bound_m=np.array([_number(v, -math.inf) for v in cells["clearance_bound_m"]]),
                endpoint_bound_m=np.array([_number(v, math.inf) for v in cells["endpoint_bound_m"]]),
                endpoint_clearance_upper_m=np.array(
                    [_number(v, math.inf) for v in cells["endpoint_clearance_upper_m"]]
                ),
                status=np.array(status, dtype=np.int64),
                seconds=float(document.get("summary", {}).get("seconds", math.nan)),  # NaN unless the summary has it
                split_w=np.array(cells.get("split_W", [0] * len(status)), dtype=np.int64),
                execution=None
                if document.get("execution") is None
                else ExecutionBounds.from_json(document["execution"], source),
                axes=axes,
                extra_ranges_m=tuple((float(fitted[name][0]), float(fitted[name][1])) for name in extra),
                extra_index=np.column_stack([np.array(cells[f"index_{name}"], dtype=np.int64) for name in extra])
                if extra
                else None,
            )
        except DataFileError:
            raise
        except (KeyError, TypeError, ValueError, IndexError, InvalidParameterError) as exc:
            raise DataFileError(source, f"malformed region map ({exc.__class__.__name__}: {exc})") from None


def _dense_index(
    depth: np.ndarray, index_l: np.ndarray, index_w: np.ndarray, split: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The lookup tables (module docstring): the dense index of the deepest level (leaf, or -(1 +
    slot) for a split cell) and the sub-leaf table (slots x 2^E); both read-only.

    Raises:
        InvalidParameterError: the leaves leave a gap or overlap.
    """
    gap = np.iinfo(np.int32).max
    top = int(depth.max())
    index = np.full((2**top, 2**top), gap, dtype=np.int32)
    plain = np.flatnonzero(split == 0)
    for level in np.unique(depth[plain]).tolist():  # the leaves of one depth at once: their blocks of cells
        leaves = plain[depth[plain] == level]
        scale = 2 ** (top - level)
        blocks = index.reshape(2**level, scale, 2**level, scale)  # a view: block (i, j) of the deepest cells
        rows, columns = index_l[leaves], index_w[leaves]
        if np.any(blocks[rows, :, columns, :] != gap):
            raise InvalidParameterError("cells", "overlaps", "leaves tiling the range")
        blocks[rows, :, columns, :] = leaves[:, None, None]
    cut = np.flatnonzero(split > 0)
    e_max = int(split.max())
    # The deepest cell of each split leaf, and the leaf's place among that cell's 2^E sub-cells.
    cell_w = index_w[cut] >> split[cut]
    unique, slot = np.unique(index_l[cut] * 2**top + cell_w, return_inverse=True)
    sub_index = np.full((unique.size, 2**e_max), gap, dtype=np.int32)
    first = (index_w[cut] - (cell_w << split[cut])) << (e_max - split[cut])
    for offset in range(2**e_max):  # sub-cell k0 + offset of every split leaf that spans it
        spans = offset < 2 ** (e_max - split[cut])
        rows, columns = slot[spans], first[spans] + offset
        if np.any(sub_index[rows, columns] != gap):
            raise InvalidParameterError("cells", "overlaps", "leaves tiling the range")
        sub_index[rows, columns] = cut[spans]
    i_cut, j_cut = unique // 2**top, unique % 2**top
    if np.any(index[i_cut, j_cut] != gap):
        raise InvalidParameterError("cells", "overlaps", "leaves tiling the range")
    index[i_cut, j_cut] = -1 - np.arange(unique.size, dtype=np.int32)
    if np.any(index == gap) or np.any(sub_index == gap):
        raise InvalidParameterError("cells", "gaps", "leaves tiling the range")
    index.setflags(write=False)
    sub_index.setflags(write=False)
    return index, sub_index


def _checked_axes(axes: object) -> tuple[str, ...]:
    """``axes`` as a tuple: L, W, then names of :data:`NAMES`, each once, in the canonical order.

    Raises:
        InvalidParameterError: anything else (the message names the axes).
    """
    given = (axes,) if isinstance(axes, str) else tuple(axes) if isinstance(axes, tuple | list) else None
    if given is None or given[:2] != SIZE:
        raise InvalidParameterError("axes", axes, "a tuple of names starting with 'L', 'W'")
    for name in given[2:]:
        if name not in NAMES[2:]:
            raise InvalidParameterError("axes", axes, f"L, W, then names among {', '.join(NAMES[2:])}")
    if sorted(given, key=NAMES.index) != list(given) or len(set(given)) != len(given):
        raise InvalidParameterError("axes", axes, f"each name once, in the order {', '.join(NAMES)}")
    return given


def _checked_extra_ranges(ranges: object, axes: tuple[str, ...]) -> tuple[tuple[float, float], ...]:
    """``ranges`` as floats: one finite (lo, hi), lo < hi, per axis beyond L and W.

    Raises:
        InvalidParameterError: a missing, surplus or invalid range (the message names its axis).
    """
    extra = axes[2:]
    try:
        pairs = tuple((float(lo), float(hi)) for lo, hi in ranges)
    except (TypeError, ValueError):
        raise InvalidParameterError("extra_ranges_m", ranges, f"one (lo, hi) [m] per axis of {extra}") from None
    if len(pairs) != len(extra):
        raise InvalidParameterError("extra_ranges_m", ranges, f"one (lo, hi) [m] per axis of {extra}")
    for name, (lo, hi) in zip(extra, pairs, strict=True):
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise InvalidParameterError(f"extra_ranges_m of {name}", (lo, hi), "finite lo < hi")
    return pairs


def _checked_extra_index(extra_index: object, axes: tuple[str, ...], depth: np.ndarray) -> np.ndarray | None:
    """``extra_index`` as a read-only int array (n, k - 2) of indices within 2^depth; None for (L, W).

    Raises:
        InvalidParameterError: a shape or an index out of range (the message names the axis).
    """
    k, n = len(axes), depth.size
    if k == 2:
        if extra_index is not None:
            raise InvalidParameterError("extra_index", np.shape(extra_index), "None for a map over L, W")
        return None
    if extra_index is None:
        raise InvalidParameterError("extra_index", None, f"an int array ({n}, {k - 2}) for the axes {axes[2:]}")
    index = np.array(extra_index, dtype=np.int64)
    if index.shape != (n, k - 2):
        raise InvalidParameterError("extra_index", index.shape, f"an int array ({n}, {k - 2}) for the axes {axes[2:]}")
    for a, name in enumerate(axes[2:]):
        if np.any(index[:, a] < 0) or np.any(index[:, a] >= 2**depth):
            raise InvalidParameterError(f"extra_index of {name}", "out of range", "0 <= index < 2^depth")
    index.setflags(write=False)
    return index


def _tree_index(depth: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """The lookup tables of a map over k > 2 axes (module docstring): the dense index of the
    coarse level C (flat, row-major, axis L slowest: a leaf, or -(1 + row)), the rows of children
    (rows x 2^k) and C; both tables read-only.

    Raises:
        InvalidParameterError: the leaves (depth (n,), node index (n, k)) leave a gap or overlap.
    """
    k = index.shape[1]
    top = int(depth.max())
    coarse = min(top, int(math.log2(DENSE_INDEX_ENTRIES)) // k)
    gap = np.iinfo(np.int32).max
    table = np.full(2 ** (k * coarse), gap, dtype=np.int32)
    leaves = np.arange(depth.size, dtype=np.int32)
    # Leaves no deeper than C: the block of coarse cells each covers (the volume check has bounded
    # the blocks' total size by the table's).
    for d in np.unique(depth[depth <= coarse]).tolist():
        chosen = np.flatnonzero(depth == d)
        scale = coarse - d
        offsets = _flat(np.indices((2**scale,) * k).reshape(k, -1).T, coarse)
        corners = _flat(index[chosen] << scale, coarse)
        _claim(table, (corners[:, None] + offsets[None, :]).ravel(), np.repeat(leaves[chosen], offsets.size))
    # The cut nodes of each level from C down: ancestors of the deeper leaves, one row each.
    levels = []
    rows = 0
    for q in range(coarse, top):
        chosen = depth > q
        keys = np.unique(_flat(index[chosen] >> (depth[chosen] - q)[:, None], q))
        levels.append((keys, rows))
        rows += keys.size
    children = np.full((rows, 2**k), gap, dtype=np.int32)
    flat_children = children.reshape(-1)
    for q, (keys, first) in enumerate(levels, start=coarse):
        pointers = -1 - np.arange(first, first + keys.size, dtype=np.int32)
        if q == coarse:
            _claim(table, keys, pointers)
        else:
            nodes = _unflat(keys, q, k)
            _claim(flat_children, _child_position(nodes, q, levels[q - 1 - coarse], k), pointers)
    deep = np.flatnonzero(depth > coarse)
    for d in np.unique(depth[deep]).tolist():
        chosen = deep[depth[deep] == d]
        _claim(flat_children, _child_position(index[chosen], d, levels[d - 1 - coarse], k), leaves[chosen])
    if np.any(table == gap) or np.any(children == gap):
        raise InvalidParameterError("cells", "gaps", "leaves tiling the range")
    table.setflags(write=False)
    children.setflags(write=False)
    return table, children, coarse


def _flat(nodes: np.ndarray, level: int) -> np.ndarray:
    """Row-major flat index of nodes (m, k) of depth ``level`` (axis L slowest), int64."""
    key = np.zeros(nodes.shape[0], dtype=np.int64)
    for a in range(nodes.shape[1]):
        key = (key << level) | nodes[:, a].astype(np.int64)
    return key


def _unflat(keys: np.ndarray, level: int, k: int) -> np.ndarray:
    """The nodes (m, k) of depth ``level`` with flat indices ``keys`` (inverse of :func:`_flat`)."""
    mask = (1 << level) - 1
    return np.stack([(keys >> (level * (k - 1 - a))) & mask for a in range(k)], -1)


def _child_position(nodes: np.ndarray, level: int, parents: tuple[np.ndarray, int], k: int) -> np.ndarray:
    """Flat position in the rows of children of each node (m, k) of depth ``level`` (> C): its
    parent's row times 2^k plus its child number (module docstring)."""
    keys, first = parents
    row = first + np.searchsorted(keys, _flat(nodes >> 1, level - 1))
    slot = np.zeros(nodes.shape[0], dtype=np.int64)
    for a in range(k):
        slot = (slot << 1) | (nodes[:, a].astype(np.int64) & 1)
    return row * 2**k + slot


def _claim(table: np.ndarray, positions: np.ndarray, values: np.ndarray) -> None:
    """Write ``values`` at ``positions`` of the flat ``table``, which must all be empty (int32 max).

    Raises:
        InvalidParameterError: a position already taken, or taken twice here (overlapping leaves).
    """
    gap = np.iinfo(np.int32).max
    if np.any(table[positions] != gap):
        raise InvalidParameterError("cells", "overlaps", "leaves tiling the range")
    table[positions] = values
    if not np.array_equal(table[positions], values):  # two of ``positions`` alike
        raise InvalidParameterError("cells", "overlaps", "leaves tiling the range")


def header_fields(document: dict) -> dict:
    """The map's fields that every format stores alike, from its document (or header): the link to
    the coefficients, the fitted range of L and W, the margin and tolerance, the settings.

    Raises:
        KeyError, TypeError, ValueError, IndexError: a field missing or malformed.
    """
    link, fitted = document["coefficients"], document["fitted_range"]
    return {
        "family": str(link["family"]),
        "coefficients_source": str(link["source"]),
        "coefficients_sha256": str(link["sha256"]),
        "length_range_m": (float(fitted["L"][0]), float(fitted["L"][1])),
        "width_range_m": (float(fitted["W"][0]), float(fitted["W"][1])),
        "margin_m": float(document["margin_m"]),
        "endpoint_tolerance_m": float(document["endpoint_tolerance_m"]),
        "details": dict(document.get("details", {})),
    }


def source_name(source: object) -> str:
    """The name a map records for its coefficients' source: the file name of a path (no folder),
    a non-path source (the paper's ``"paper"``) as it is."""
    return Path(str(source)).name if source else ""


def _number(value, infinite: float) -> float:
    """A JSON number; null stands for the column's infinite value (json_safe writes non-finite
    values as null): -inf for lower bounds, +inf for upper bounds."""
    return infinite if value is None else float(value)


def region_map_text(region_map: RegionMap) -> str:
    """The map's file content: compact JSON, newline-terminated (the bytes its sha256 is of)."""
    return json.dumps(json_safe(region_map.to_json()), separators=(",", ":"), allow_nan=False) + "\n"


def save_region_map_json(region_map: RegionMap, path: str | Path, overwrite: bool = True) -> str:
    """Write the map atomically as compact JSON (formats /2, /3: the leaves as JSON columns, as
    :func:`pipeline.certify.map_files.save_region_map`'s header and table replace); returns the
    sha256 of the bytes written."""
    text = region_map_text(region_map)
    write_text_atomic(path, text, overwrite)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()
