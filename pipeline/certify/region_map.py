"""The region map: a quadtree over the fitted (L, W) range whose leaves carry the range
certificate's bounds and a status, stored as JSON beside the coefficients it certifies.

A leaf is the node (depth, i_L, i_W), possibly cut further along W only: with ``split_W`` = e,
L in L_lo + [i_L, i_L + 1] (L_hi - L_lo) / 2^depth and W in W_lo + [i_W, i_W + 1] (W_hi - W_lo) /
2^(depth + e) (e = 0 for a plain quadtree leaf; e > 0 only at the deepest level, where the range
certificate cuts the smallest cells that straddle the margin's or the infeasibility's contour,
both of which run along L near W = 0.12 m on the default build). Its area fraction is
2^-(2 depth + e). Statuses:

* ``margin``: clearance certified >= the margin over the whole cell and all of [0, T];
* ``collision_free``: clearance certified > 0, not >= the margin, and not proven infeasible;
* ``infeasible``: no trajectory of the family can keep both the endpoint tolerance and the
  margin in this cell (``pipeline.certify.endpoints``); its clearance bound is still stored
  (and is > 0 where the coefficients are collision-free there);
* ``undecided``: not even collision-free was certified at the smallest cell.

Lookups (:meth:`RegionMap.cell_at`, :meth:`RegionMap.cells_at`) go through a dense index of the
deepest level, so they cost one multiplication and one array read per query (int32: 4 MiB for
cells of 1/1024; the scalar lookup reads a flat ``array.array`` copy, 4 MiB more, where a
Python list of lists would take about 40 MB). A deepest cell that is split along W holds
-(1 + slot) there, and row ``slot`` of a second table holds its 2^E sub-leaves (E the largest
``split_W``): one more read. The sub-cell is found from the same scaled coordinate v = (W -
W_lo) / (W_hi - W_lo) 2^depth as the cell, as floor(v 2^E) - 2^E floor(v): scaling by 2^E is
exact in floating point, so a point is never placed in a sub-cell of a neighbouring cell.
"""

from __future__ import annotations

import array
import hashlib
import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from pipeline.certify.execution_bounds import ExecutionBounds
from pipeline.certify.interval import FLOAT_SLACK_M
from pipeline.exceptions import DataFileError, InvalidParameterError, OutOfFittedRangeError
from pipeline.io.jsonio import json_safe, read_json, write_text_atomic
from pipeline.validation import check_non_negative

FORMAT = "twolink-region-map/2"
#: Formats read: /1 has no ``split_W`` column (every leaf a quadtree node).
READABLE_FORMATS = ("twolink-region-map/1", FORMAT)
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
        depth: Quadtree depth (the cell spans 1 / 2^depth of the range in L).
        split_w: Further halvings along W (the cell spans 1 / 2^(depth + split_w) of the range in W).
    """

    length_range_m: tuple[float, float]
    width_range_m: tuple[float, float]
    clearance_bound_m: float
    endpoint_bound_m: float
    endpoint_clearance_upper_m: float
    status: str
    depth: int
    split_w: int = 0

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise InvalidParameterError("status", self.status, f"one of {STATUSES}")


@dataclass(frozen=True, eq=False)
class RegionMap:
    """The certified map of one coefficients file.

    Attributes:
        family: Trajectory family of the coefficients.
        coefficients_source: File name (or PAPER_SOURCE) of the coefficients, without its folder
            (:func:`source_name`), so that the map's bytes do not depend on where the build ran;
            the link itself is the sha256.
        coefficients_sha256: sha256 of the coefficients file: the link between map and coefficients.
        length_range_m, width_range_m: The fitted range [m].
        margin_m: The margin the statuses refer to [m].
        endpoint_tolerance_m: The endpoint tolerance of the infeasibility certificate [m].
        depth, index_l, index_w: Leaf nodes, int arrays (n,) (index_w counts cells of W at depth
            + split_w).
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
    _index: np.ndarray = field(init=False, repr=False)
    _sub_index: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        check_non_negative("margin_m", self.margin_m)
        check_non_negative("endpoint_tolerance_m", self.endpoint_tolerance_m)
        for name in ("length_range_m", "width_range_m"):
            lo, hi = getattr(self, name)
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise InvalidParameterError(name, getattr(self, name), "finite lo < hi")
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
        if np.any(depth < 0) or np.any(depth > 20):
            raise InvalidParameterError("depth", int(depth.max()), "0..20")
        top = int(depth.max())
        if np.any(split < 0) or np.any(split > 10) or np.any((split > 0) & (depth < top)):
            raise InvalidParameterError("split_w", int(split.max()), "0..10, non-zero only at the deepest level")
        if np.any(arrays["index_l"] < 0) or np.any(arrays["index_l"] >= 2**depth):
            raise InvalidParameterError("index_l", "out of range", "0 <= index < 2^depth")
        if np.any(arrays["index_w"] < 0) or np.any(arrays["index_w"] >= 2 ** (depth + split)):
            raise InvalidParameterError("index_w", "out of range", "0 <= index < 2^(depth + split_w)")
        area = float(np.sum(2.0 ** (-(2 * depth + split).astype(float))))
        if not math.isclose(area, 1.0, rel_tol=1e-9):
            raise InvalidParameterError("cells", area, "leaves tiling the range")
        if self.execution is not None and (not isinstance(self.execution, ExecutionBounds) or self.execution.size != n):
            raise InvalidParameterError("execution", type(self.execution).__name__, f"ExecutionBounds of {n} leaves")
        for key, value in arrays.items():
            value.setflags(write=False)
            object.__setattr__(self, key, value)
        index, sub_index = _dense_index(depth, arrays["index_l"], arrays["index_w"], split)
        object.__setattr__(self, "_index", index)
        object.__setattr__(self, "_sub_index", sub_index)

    # ------------------------------------------------------------------ lookup

    def leaf_indices(self, length_m, width_m) -> np.ndarray:
        """Leaf index of each (L, W) [m] (vectorised); -1 outside the fitted range."""
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

    def cells_at(self, length_m, width_m) -> dict[str, np.ndarray]:
        """Batch lookup: per (L, W), the leaf's clearance bound, endpoint bound and status index
        (NaN / -1 outside the fitted range)."""
        leaf = self.leaf_indices(length_m, width_m)
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
        return RegionCell(
            length_range_m=(l_lo + il * dl, l_lo + (il + 1) * dl),
            width_range_m=(w_lo + iw * dw, w_lo + (iw + 1) * dw),
            clearance_bound_m=float(self.clearance_bound_m[leaf]),
            endpoint_bound_m=float(self.endpoint_bound_m[leaf]),
            endpoint_clearance_upper_m=float(self.endpoint_clearance_upper_m[leaf]),
            status=STATUSES[int(self.status[leaf])],
            depth=d,
            split_w=e,
        )

    def cell_at(self, length_m: float, width_m: float) -> RegionCell:
        """The leaf containing (L, W) [m].

        Raises:
            OutOfFittedRangeError: (L, W) outside the fitted range.
        """
        (l_lo, l_hi), (w_lo, w_hi) = self.length_range_m, self.width_range_m
        if not l_lo <= length_m <= l_hi:
            raise OutOfFittedRangeError("L", length_m, self.length_range_m)
        if not w_lo <= width_m <= w_hi:
            raise OutOfFittedRangeError("W", width_m, self.width_range_m)
        return self.cell(self._leaf_at(length_m, width_m))

    def bounds_at(self, length_m: float, width_m: float) -> tuple[float, float, str] | None:
        """(clearance bound [m], endpoint-error bound [m], status) of the leaf holding (L, W), or
        None outside the fitted range: the online generator's lookup (no cell object built)."""
        (l_lo, l_hi), (w_lo, w_hi) = self.length_range_m, self.width_range_m
        if not (l_lo <= length_m <= l_hi and w_lo <= width_m <= w_hi):
            return None
        return self._leaf_bounds[self._leaf_at(length_m, width_m)]

    def leaf_at(self, length_m: float, width_m: float) -> int | None:
        """Leaf number of (L, W) [m], or None outside the fitted range (scalar lookup)."""
        (l_lo, l_hi), (w_lo, w_hi) = self.length_range_m, self.width_range_m
        if not (l_lo <= length_m <= l_hi and w_lo <= width_m <= w_hi):
            return None
        return self._leaf_at(length_m, width_m)

    def _leaf_at(self, length_m: float, width_m: float) -> int:
        """Leaf of (L, W) [m] inside the fitted range (scalar; the same cells as :meth:`leaf_indices`)."""
        (l_lo, l_hi), (w_lo, w_hi) = self.length_range_m, self.width_range_m
        n = self._index.shape[0]
        i = min(int((length_m - l_lo) / (l_hi - l_lo) * n), n - 1)
        v = (width_m - w_lo) / (w_hi - w_lo) * n
        j = min(int(v), n - 1)
        leaf = self._lookup[i * n + j]
        if leaf >= 0:
            return leaf
        s = self._sub_index.shape[1]
        return self._sub_lookup[(-leaf - 1) * s + min(max(int(v * s) - j * s, 0), s - 1)]

    @cached_property
    def _lookup(self) -> array.array:
        """The dense index, row-major, as a flat ``array.array`` (fast scalar reads)."""
        flat = array.array("i")
        flat.frombytes(np.ascontiguousarray(self._index, dtype=np.int32).tobytes())
        return flat

    @cached_property
    def _sub_lookup(self) -> array.array:
        """The sub-leaf table, row-major, as a flat ``array.array``."""
        flat = array.array("i")
        flat.frombytes(np.ascontiguousarray(self._sub_index, dtype=np.int32).tobytes())
        return flat

    @cached_property
    def _leaf_bounds(self) -> list[tuple[float, float, str]]:
        return [
            (float(c), float(e), STATUSES[int(k)])
            for c, e, k in zip(self.clearance_bound_m, self.endpoint_bound_m, self.status, strict=True)
        ]

    # ------------------------------------------------------------------ summary

    @property
    def area(self) -> np.ndarray:
        """Area fraction of each leaf, (n,)."""
        return 2.0 ** (-(2 * self.depth + self.split_w).astype(float))

    def leaf_sizes_m(self) -> np.ndarray:
        """Side lengths (L, W) [m] of each leaf, (n, 2)."""
        lo = np.array([self.length_range_m[0], self.width_range_m[0]])
        size = np.array([self.length_range_m[1], self.width_range_m[1]]) - lo
        return size / 2.0 ** np.stack([self.depth, self.depth + self.split_w], -1)

    def leaf_centres_m(self) -> np.ndarray:
        """Centre (L, W) [m] of each leaf, (n, 2)."""
        lo = np.array([self.length_range_m[0], self.width_range_m[0]])
        return lo + (np.stack([self.index_l, self.index_w], -1) + 0.5) * self.leaf_sizes_m()

    def summary(self) -> dict:
        """Area fractions per status, extreme bounds and time (plain JSON)."""
        area = self.area
        fractions = {name: float(np.sum(area[self.status == k])) for k, name in enumerate(STATUSES)}
        feasible = 1.0 - fractions["infeasible"]
        worst = int(np.argmin(self.clearance_bound_m))
        worst_cell = self.cell(worst)
        return {
            "area_fraction": fractions,
            "certified_collision_free_fraction": float(np.sum(area[self.clearance_bound_m > 0.0])),
            "margin_fraction_of_feasible": fractions["margin"] / feasible if feasible > 0 else None,
            # Bounds carry the rounding slack, so a tolerance of 0 (pinned endpoints) is met up to it.
            "endpoint_within_tolerance_fraction": float(
                np.sum(area[self.endpoint_bound_m <= self.endpoint_tolerance_m + FLOAT_SLACK_M])
            ),
            "clearance_bound_min_m": float(self.clearance_bound_m[worst]),
            "worst_cell": {"L_m": list(worst_cell.length_range_m), "W_m": list(worst_cell.width_range_m)},
            "endpoint_bound_max_m": float(np.max(self.endpoint_bound_m)),
            "margin_m": self.margin_m,
            "endpoint_tolerance_m": self.endpoint_tolerance_m,
            "cells": int(self.depth.size),
            "seconds": self.seconds,
        } | ({} if self.execution is None else {"execution": self.execution_summary()})

    def execution_summary(self) -> dict | None:
        """Area fractions of the range where the paper timing's bounds break each limit of the map's
        arm (a leaf counts if its bound exceeds the limit: not proven to keep it), where a
        rest-to-rest timing keeps them all, and the longest rest-to-rest duration; None without
        execution bounds."""
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
        """True if this map was made from exactly these coefficients (same sha256)."""
        return bool(self.coefficients_sha256) and self.coefficients_sha256 == coefficients.source_sha256

    # ------------------------------------------------------------------ JSON

    def to_json(self) -> dict:
        """The plain-JSON document (columnar cells)."""
        return {
            "format": FORMAT,
            "coefficients": {
                "source": self.coefficients_source,
                "sha256": self.coefficients_sha256,
                "family": self.family,
            },
            "fitted_range": {"L": list(self.length_range_m), "W": list(self.width_range_m)},
            "margin_m": self.margin_m,
            "endpoint_tolerance_m": self.endpoint_tolerance_m,
            # No wall time in the file (nor the worker count in ``details``): the same
            # coefficients and settings give the same bytes.
            "summary": {k: v for k, v in self.summary().items() if k != "seconds"},
            "details": self.details,
            "statuses": list(STATUSES),
            "cells": {
                "depth": self.depth.tolist(),
                "index_L": self.index_l.tolist(),
                "index_W": self.index_w.tolist(),
                "clearance_bound_m": self.clearance_bound_m.tolist(),
                "endpoint_bound_m": self.endpoint_bound_m.tolist(),
                "endpoint_clearance_upper_m": self.endpoint_clearance_upper_m.tolist(),
                "status": [STATUSES[k] for k in self.status],
                "split_W": self.split_w.tolist(),
            },
        } | ({} if self.execution is None else {"execution": self.execution.to_json()})

    @classmethod
    def from_json(cls, document: dict, source: object = "<memory>") -> RegionMap:
        """Validate a parsed map document.

        Raises:
            DataFileError: a field is missing or malformed.
        """
        if document.get("format") not in READABLE_FORMATS:
            raise DataFileError(source, f"format is {document.get('format')!r}, expected {FORMAT!r}")
        try:
            link, fitted, cells = document["coefficients"], document["fitted_range"], document["cells"]
            missing = [c for c in _COLUMNS if c not in cells]
            if missing:
                raise DataFileError(source, f"cells lack {missing}")
            status = [STATUSES.index(s) for s in cells["status"]]
            return cls(
                family=str(link["family"]),
                coefficients_source=str(link["source"]),
                coefficients_sha256=str(link["sha256"]),
                length_range_m=(float(fitted["L"][0]), float(fitted["L"][1])),
                width_range_m=(float(fitted["W"][0]), float(fitted["W"][1])),
                margin_m=float(document["margin_m"]),
                endpoint_tolerance_m=float(document["endpoint_tolerance_m"]),
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
                details=dict(document.get("details", {})),
                split_w=np.array(cells.get("split_W", [0] * len(status)), dtype=np.int64),
                execution=None
                if document.get("execution") is None
                else ExecutionBounds.from_json(document["execution"], source),
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
    for leaf in np.flatnonzero(split == 0):
        scale = 2 ** (top - int(depth[leaf]))
        i0, j0 = int(index_l[leaf]) * scale, int(index_w[leaf]) * scale
        index[i0 : i0 + scale, j0 : j0 + scale] = leaf
    cut = np.flatnonzero(split > 0)
    e_max = int(split.max())
    # The deepest cell of each split leaf, and the leaf's place among that cell's 2^E sub-cells.
    cell_w = index_w[cut] >> split[cut]
    unique, slot = np.unique(index_l[cut] * 2**top + cell_w, return_inverse=True)
    sub_index = np.full((unique.size, 2**e_max), gap, dtype=np.int32)
    for leaf, row, w in zip(cut, slot, cell_w, strict=True):
        scale = 2 ** (e_max - int(split[leaf]))
        k0 = (int(index_w[leaf]) - (int(w) << int(split[leaf]))) * scale
        sub_index[row, k0 : k0 + scale] = leaf
    i_cut, j_cut = unique // 2**top, unique % 2**top
    if np.any(index[i_cut, j_cut] != gap):
        raise InvalidParameterError("cells", "overlaps", "leaves tiling the range")
    index[i_cut, j_cut] = -1 - np.arange(unique.size, dtype=np.int32)
    if np.any(index == gap) or np.any(sub_index == gap):
        raise InvalidParameterError("cells", "gaps", "leaves tiling the range")
    index.setflags(write=False)
    sub_index.setflags(write=False)
    return index, sub_index


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


def save_region_map(region_map: RegionMap, path: str | Path, overwrite: bool = True) -> str:
    """Write the map atomically as compact JSON; returns the sha256 of the bytes written."""
    text = region_map_text(region_map)
    write_text_atomic(path, text, overwrite)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def load_region_map(path: str | Path) -> RegionMap:
    """Read a map written by :func:`save_region_map`.

    Raises:
        DataFileError: missing, unreadable or malformed.
    """
    return RegionMap.from_json(read_json(path), path)
