"""The region map: a subpaving (:mod:`pipeline.certify.subpaving`) of the fitted box of the
coefficients' scene variables whose leaves carry the range certificate's bounds and a status.

The map's ``axes`` are the coefficients' variables in their canonical order
(:mod:`pipeline.offline.variables`); the map itself knows them only as names in that order:
every lookup takes one value per axis, in the order of ``axes``. Its leaves are boxes made by
cuts of one axis at a time (a leaf has its own level along every axis), so a leaf can be cut
along the one axis that dominates its bound's gap: a quadtree leaf, a strip cut further along
one axis and a box cut along one axis only are all ordinary leaves. Statuses:

* ``margin``: clearance certified >= the margin over the whole cell and all of [0, T];
* ``collision_free``: clearance certified > 0, not >= the margin, and not proven infeasible;
* ``infeasible``: no trajectory of the family can keep both the endpoint tolerance and the
  margin in this cell (``pipeline.certify.endpoints``); its clearance bound is still stored
  (and is > 0 where the coefficients are collision-free there);
* ``undecided``: not even collision-free was certified at the smallest cell.

A point is placed as the subpaving's module docstring says. The scalar lookups
(:meth:`RegionMap.cell_at`, :meth:`RegionMap.bounds_at`, :meth:`RegionMap.leaf_at`) and the
online generator's compiled core read the tree and the leaves' bounds as two flat arrays
(:attr:`RegionMap.lookup_tables`) through one compiled function,
:func:`pipeline.certify.lookup.leaf_of`, by the same floating-point operations as the
vectorised :meth:`RegionMap.leaf_indices`.

On disk a map is a JSON header and a NumPy table (:mod:`pipeline.certify.map_files`);
:meth:`RegionMap.to_json` gives it as one JSON document (format :data:`FORMAT_JSON`). The JSON
formats of the earlier 2^k-trees (/1 to /3: a depth per leaf, the same along every axis, and
over two axes a further count of halvings of the second) are read and turned into the same
subpaving, keeping every number.
"""

from __future__ import annotations

import hashlib
import json
import math
import numbers
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pipeline.certify.execution_bounds import ExecutionBounds
from pipeline.certify.interval import FLOAT_SLACK_M
from pipeline.certify.subpaving import Subpaving
from pipeline.exceptions import DataFileError, InvalidParameterError, OutOfFittedRangeError
from pipeline.io.jsonio import json_safe, write_text_atomic
from pipeline.offline.variables import NAMES, SIZE
from pipeline.validation import check_non_negative

if TYPE_CHECKING:
    from pipeline.certify.lookup import LookupTables
    from pipeline.certify.near_optimal_cells import NearOptimalCells

#: Format of a map as one JSON document (:meth:`RegionMap.to_json`): the tree as JSON columns.
FORMAT_JSON = "twolink-region-map/json-5"
#: The JSON formats of the earlier 2^k-trees, read and converted (module docstring).
TREE_FORMATS = ("twolink-region-map/1", "twolink-region-map/2", "twolink-region-map/3")
#: Formats :meth:`RegionMap.from_json` reads.
READABLE_FORMATS = (*TREE_FORMATS, FORMAT_JSON)
STATUSES: tuple[str, ...] = ("margin", "collision_free", "infeasible", "undecided")
#: File name of the map written beside a coefficients file.
DEFAULT_MAP_NAME = "region_map.json"
#: The bound columns of every map.
BOUND_COLUMNS = ("clearance_bound_m", "endpoint_bound_m", "endpoint_clearance_upper_m")


@dataclass(frozen=True)
class RegionCell:
    """One leaf of the map.

    Attributes:
        axes: The map's axes (names, in order).
        ranges_m: The cell's (lo, hi) along every axis, in ``axes`` order [m].
        levels: The cell's level along every axis (it spans 1 / 2^level of the range there).
        clearance_bound_m: Lower bound on the clearance of both links over the cell and all of [0, T] [m].
        endpoint_bound_m: Upper bound on max(|tip(0) - P1|, |tip(T) - P5|) over the cell [m].
        endpoint_clearance_upper_m: Upper bound on the clearance of poses within the endpoint
            tolerance of P1 or P5 (the smaller of the two) [m]; below the margin: infeasible.
        status: One of :data:`STATUSES`.
    """

    axes: tuple[str, ...]
    ranges_m: tuple[tuple[float, float], ...]
    levels: tuple[int, ...]
    clearance_bound_m: float
    endpoint_bound_m: float
    endpoint_clearance_upper_m: float
    status: str

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise InvalidParameterError("status", self.status, f"one of {STATUSES}")

    def range_of(self, axis: str) -> tuple[float, float]:
        """The cell's (lo, hi) along the axis named ``axis`` [m]."""
        return self.ranges_m[self.axes.index(axis)]


@dataclass(frozen=True, eq=False)
class RegionMap:
    """The certified map of one coefficients file, over the box of its ``axes`` (module docstring).

    Attributes:
        family: Trajectory family of the coefficients.
        coefficients_source: File name (or PAPER_SOURCE) of the coefficients, without its folder
            (:func:`source_name`), so that the map's bytes do not depend on where the build ran;
            the link itself is the sha256.
        coefficients_sha256: sha256 of the coefficients file: the link between map and coefficients.
        axes: The map's axes, the coefficients' variables in canonical order (e.g. ("L", "W") or
            ("L", "W", "x")).
        subpaving: The leaves, over the fitted range of every axis in ``axes`` order [m].
        margin_m: The margin the statuses refer to [m].
        endpoint_tolerance_m: The endpoint tolerance of the infeasibility certificate [m].
        clearance_bound_m, endpoint_bound_m, endpoint_clearance_upper_m: Per leaf [m], (n,).
        status: Per leaf, index into :data:`STATUSES`, (n,).
        seconds: Wall time of the certificate [s]; NaN for a map read from a file (not stored, so
            that the file's bytes depend only on the coefficients and the settings).
        details: Settings and counters (plain JSON).
        execution: Per leaf, the execution bounds for the arm the map was built with (joint
            angle ranges, the paper timing's speed, acceleration and torque bounds, the
            rest-to-rest timing within the arm's limits; :mod:`pipeline.certify.execution_bounds`),
            or None.
        near_optimal_cells: The certified near-optimal timings per cell of a grid over the range
            (:mod:`pipeline.certify.near_optimal_cells`, stored in files of their own), or None.
    """

    family: str
    coefficients_source: str
    coefficients_sha256: str
    axes: tuple[str, ...]
    subpaving: Subpaving
    margin_m: float
    endpoint_tolerance_m: float
    clearance_bound_m: np.ndarray
    endpoint_bound_m: np.ndarray
    endpoint_clearance_upper_m: np.ndarray
    status: np.ndarray
    seconds: float = 0.0
    details: dict = field(default_factory=dict)
    execution: ExecutionBounds | None = None
    near_optimal_cells: NearOptimalCells | None = None

    def __post_init__(self) -> None:
        check_non_negative("margin_m", self.margin_m)
        check_non_negative("endpoint_tolerance_m", self.endpoint_tolerance_m)
        axes = _checked_axes(self.axes)
        if not isinstance(self.subpaving, Subpaving) or self.subpaving.k != len(axes):
            raise InvalidParameterError(
                "subpaving", type(self.subpaving).__name__, f"a Subpaving over {len(axes)} axes"
            )
        n = self.subpaving.size
        arrays = {name: np.asarray(getattr(self, name), dtype=float) for name in BOUND_COLUMNS}
        arrays["status"] = np.asarray(self.status, dtype=np.int64)
        if any(a.shape != (n,) for a in arrays.values()):
            raise InvalidParameterError("cells", {k: a.shape for k, a in arrays.items()}, f"({n},) per leaf")
        if np.any(arrays["status"] < 0) or np.any(arrays["status"] >= len(STATUSES)):
            raise InvalidParameterError("status", "out of range", f"indices into {STATUSES}")
        if self.execution is not None and (not isinstance(self.execution, ExecutionBounds) or self.execution.size != n):
            raise InvalidParameterError("execution", type(self.execution).__name__, f"ExecutionBounds of {n} leaves")
        for key, value in arrays.items():
            value.setflags(write=False)
            object.__setattr__(self, key, value)
        object.__setattr__(self, "axes", axes)

    @classmethod
    def of_leaves(cls, ranges_m, levels: np.ndarray, indices: np.ndarray, **fields) -> RegionMap:
        """The map of leaves given by their levels and indices (n, k) (the subpaving's tree is
        found from them; :meth:`Subpaving.from_leaves`), with the other fields as keywords.

        Raises:
            InvalidParameterError: leaves that do not tile the range, or a field out of range.
        """
        _checked_axes(fields.get("axes"))  # named before the leaves are
        return cls(subpaving=Subpaving.from_leaves(ranges_m, levels, indices), **fields)

    @property
    def ranges_m(self) -> tuple[tuple[float, float], ...]:
        """The fitted range (lo, hi) of every axis, in ``axes`` order [m]."""
        return self.subpaving.ranges

    def range_of(self, axis: str) -> tuple[float, float]:
        """The fitted range (lo, hi) of the axis named ``axis`` [m]."""
        return self.ranges_m[self.axes.index(axis)]

    @property
    def size(self) -> int:
        """The number of leaves."""
        return self.subpaving.size

    # ------------------------------------------------------------------ lookup

    def leaf_indices(self, *values) -> np.ndarray:
        """Leaf index of each point: one value (array or scalar) per axis, in ``axes`` order,
        broadcast together; -1 outside the fitted box. The compiled walk of
        :func:`pipeline.certify.lookup.leaves_of`; :meth:`Subpaving.leaf_indices` is the NumPy
        route it equals (tested).

        Raises:
            InvalidParameterError: not one value (array) per axis (the message names the axis
                missing, or the values beyond the map's axes).
        """
        from pipeline.certify.lookup import COMPILED  # machine code: loaded on the first lookup

        points = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in self._values(values)))
        table = np.zeros((points[0].size, 4))
        for a, value in enumerate(points):
            table[:, a] = value.ravel()
        return COMPILED["leaves_of"](*self.lookup_tables, len(self.axes), table).reshape(points[0].shape)

    def cells_at(self, *values) -> dict[str, np.ndarray]:
        """Batch lookup: per point (one value per axis, in ``axes`` order), the leaf, its
        clearance bound, endpoint bound and status index (-1 / NaN outside the fitted box)."""
        leaf = self.leaf_indices(*values)
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
        return RegionCell(
            axes=self.axes,
            ranges_m=self.subpaving.box(leaf),
            levels=tuple(int(v) for v in self.subpaving.levels[leaf]),
            clearance_bound_m=float(self.clearance_bound_m[leaf]),
            endpoint_bound_m=float(self.endpoint_bound_m[leaf]),
            endpoint_clearance_upper_m=float(self.endpoint_clearance_upper_m[leaf]),
            status=STATUSES[int(self.status[leaf])],
        )

    def cell_at(self, *values: float) -> RegionCell:
        """The leaf containing the point (one value per axis, in ``axes`` order).

        Raises:
            OutOfFittedRangeError: the point lies outside the fitted box (the message names the axis).
            InvalidParameterError: not one value per axis.
        """
        values = self._values(values)
        for name, value, (lo, hi) in zip(self.axes, values, self.ranges_m, strict=True):
            if not lo <= value <= hi:
                raise OutOfFittedRangeError(name, value, (lo, hi))
        return self.cell(self._leaf_of(values))

    def bounds_at(self, *values: float) -> tuple[float, float, str] | None:
        """(clearance bound [m], endpoint-error bound [m], status) of the leaf holding the point
        (one value per axis, in ``axes`` order), or None outside the fitted box: the online
        generator's lookup (no cell object built).

        Raises:
            InvalidParameterError: not one real number per axis.
        """
        leaf = self.leaf_at(*values)
        if leaf is None:
            return None
        clearance, endpoint, status = self.lookup_tables.leaf_bounds(len(self.axes), leaf)
        return clearance, endpoint, STATUSES[status]

    def leaf_at(self, *values: float) -> int | None:
        """Leaf number of the point (one value per axis, in ``axes`` order), or None outside the
        fitted box (scalar lookup: :func:`pipeline.certify.lookup.leaf_of`).

        Raises:
            InvalidParameterError: not one real number per axis.
        """
        leaf = self._leaf_of(self._values(values))
        return None if leaf < 0 else leaf

    def _leaf_of(self, values: tuple) -> int:
        """Leaf of the point ``values`` (one per axis), -1 outside the fitted box."""
        from pipeline.certify.lookup import COMPILED  # machine code: loaded on the first scalar lookup

        for name, value in zip(self.axes, values, strict=True):
            if not isinstance(value, numbers.Real):
                raise InvalidParameterError(name, value, "a real number [m]")
        padded = (*values, 0.0, 0.0, 0.0)
        leaf_of = COMPILED["leaf_of"]
        return int(leaf_of(*self.lookup_tables, len(self.axes), padded[0], padded[1], padded[2], padded[3]))

    def _values(self, values: tuple) -> tuple:
        """``values`` if it holds one value per axis.

        Raises:
            InvalidParameterError: a value missing (named by its axis) or values beyond the axes.
        """
        wanted = len(self.axes)
        if len(values) == wanted:
            return values
        axes = ", ".join(self.axes)
        if len(values) < wanted:
            missing = self.axes[len(values)]
            raise InvalidParameterError(missing, None, f"a value: the map's axes are {axes} ({missing} is missing)")
        raise InvalidParameterError(
            "values beyond the map's axes", values[wanted:], f"one value per axis, the map's axes are {axes} only"
        )

    @cached_property
    def lookup_tables(self) -> LookupTables:
        """The scalar lookup as two flat arrays (:class:`pipeline.certify.lookup.LookupTables`;
        copies, not to be modified), built on first use."""
        from pipeline.certify.lookup import LOOKUP_HEADER, LOOKUP_TREE, LookupTables

        index = self.subpaving.lookup_index(LOOKUP_TREE, LOOKUP_HEADER)
        leaves = np.column_stack([self.clearance_bound_m, self.endpoint_bound_m, self.status.astype(float)])
        bounds = np.concatenate([np.array(self.ranges_m, dtype=float).reshape(-1), leaves.reshape(-1)])
        # The compiled lookups read them as these dtypes, C-contiguous (pipeline.native).
        return LookupTables(np.ascontiguousarray(index, dtype=np.int32), np.ascontiguousarray(bounds, dtype=np.float64))

    # ------------------------------------------------------------------ summary

    @property
    def area(self) -> np.ndarray:
        """Volume fraction of each leaf in the fitted box (the area fraction over two axes), (n,)."""
        return self.subpaving.volume_fraction

    def leaf_sizes_m(self) -> np.ndarray:
        """Side lengths of each leaf [m] along every axis, (n, k)."""
        return self.subpaving.sizes()

    def leaf_centres_m(self) -> np.ndarray:
        """Centre of each leaf [m] along every axis, (n, k)."""
        return self.subpaving.centres()

    def summary(self) -> dict:
        """The ``axes``, volume fractions of the fitted box per status (area fractions over two
        axes), extreme bounds and time (plain JSON)."""
        area = self.area
        fractions = {name: float(np.sum(area[self.status == k])) for k, name in enumerate(STATUSES)}
        feasible = 1.0 - fractions["infeasible"]
        worst = int(np.argmin(self.clearance_bound_m))
        worst_cell = self.cell(worst)
        return {
            "axes": list(self.axes),
            "area_fraction": fractions,
            "certified_collision_free_fraction": float(np.sum(area[self.clearance_bound_m > 0.0])),
            "margin_fraction_of_feasible": fractions["margin"] / feasible if feasible > 0 else None,
            # Bounds carry the rounding slack, so a tolerance of 0 (pinned endpoints) is met up to it.
            "endpoint_within_tolerance_fraction": float(
                np.sum(area[self.endpoint_bound_m <= self.endpoint_tolerance_m + FLOAT_SLACK_M])
            ),
            "clearance_bound_min_m": float(self.clearance_bound_m[worst]),
            "worst_cell": {f"{name}_m": list(r) for name, r in zip(self.axes, worst_cell.ranges_m, strict=True)},
            "endpoint_bound_max_m": float(np.max(self.endpoint_bound_m)),
            "margin_m": self.margin_m,
            "endpoint_tolerance_m": self.endpoint_tolerance_m,
            "cells": self.size,
            "deepest_level": [int(v) for v in np.max(self.subpaving.levels, axis=0)],
            "seconds": self.seconds,
        } | ({} if self.execution is None else {"execution": self.execution_summary()})

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
    # ------------------------------------------------------------------ JSON

    def header_json(self) -> dict:
        """What describes the map beside its leaves, as plain JSON: the link to its coefficients, the
        axes and the fitted range of each, margin and tolerance, the summary (without the wall time,
        nor the worker count in ``details``: the same coefficients and settings give the same bytes),
        the settings and the statuses."""
        return {
            "coefficients": {
                "source": self.coefficients_source,
                "sha256": self.coefficients_sha256,
                "family": self.family,
            },
            "axes": list(self.axes),
            "fitted_range": {name: list(r) for name, r in zip(self.axes, self.ranges_m, strict=True)},
            "margin_m": self.margin_m,
            "endpoint_tolerance_m": self.endpoint_tolerance_m,
            "summary": {k: v for k, v in self.summary().items() if k != "seconds"},
            "details": self.details,
            "statuses": list(STATUSES),
        }

    def to_json(self) -> dict:
        """The map as one plain-JSON document (format :data:`FORMAT_JSON`): the header, the tree's
        columns and the leaves' columns."""
        tree = self.subpaving
        cells = {
            "cut_axis": tree.cut_axis.tolist(),
            "cut_level": tree.cut_level.tolist(),
            "children": tree.children.tolist(),
            **{name: getattr(self, name).tolist() for name in BOUND_COLUMNS},
            "status": [STATUSES[k] for k in self.status],
        }
        document = {"format": FORMAT_JSON, **self.header_json(), "cells": cells}
        return document | ({} if self.execution is None else {"execution": self.execution.to_json()})

    @classmethod
    def from_json(cls, document: dict, source: object = "<memory>") -> RegionMap:
        """Validate a parsed map document (:data:`READABLE_FORMATS`).

        Raises:
            DataFileError: a field is missing or malformed.
        """
        if document.get("format") not in READABLE_FORMATS:
            expected = f"one of {', '.join(repr(f) for f in READABLE_FORMATS)}"
            raise DataFileError(source, f"format is {document.get('format')!r}, expected {expected}")
        try:
            head = header_fields(document)
            cells = document["cells"]
            status = np.array([STATUSES.index(s) for s in cells["status"]], dtype=np.int64)
            fields = head | {
                **{name: _column(cells[name], name) for name in BOUND_COLUMNS},
                "status": status,
                "seconds": float(document.get("summary", {}).get("seconds", math.nan)),  # NaN unless the summary has it
                "execution": None
                if document.get("execution") is None
                else ExecutionBounds.from_json(document["execution"], source),
            }
            if document["format"] == FORMAT_JSON:
                tree = Subpaving(head_ranges(document), cells["cut_axis"], cells["cut_level"], cells["children"])
                return cls(subpaving=tree, **fields)
            levels, indices = tree_leaves(document, cells)
            return cls.of_leaves(head_ranges(document), levels, indices, **fields)
        except DataFileError:
            raise
        except (KeyError, TypeError, ValueError, IndexError, InvalidParameterError) as exc:
            raise DataFileError(source, f"malformed region map ({exc.__class__.__name__}: {exc})") from None


def tree_leaves(document: dict, cells: dict) -> tuple[np.ndarray, np.ndarray]:
    """The leaves (levels, indices (n, k)) of a map of the earlier 2^k-trees (module docstring):
    every axis at the leaf's ``depth``, the second further by its halvings (``split_<axis>``,
    absent in /1 and over more than two axes), an ``index_<axis>`` column per axis, ``cells``
    the document's columns (JSON lists or a table's arrays).

    Raises:
        KeyError, TypeError, ValueError: a column missing or malformed.
    """
    axes = head_axes(document)
    depth = np.asarray(cells["depth"], dtype=np.int64)
    levels = np.repeat(depth[:, None], len(axes), axis=1)
    halvings = f"split_{axes[1]}"
    if halvings in _names(cells):
        levels[:, 1] += np.asarray(cells[halvings], dtype=np.int64)
    indices = np.column_stack([np.asarray(cells[f"index_{name}"], dtype=np.int64) for name in axes])
    return levels, indices


def _names(cells) -> tuple[str, ...]:
    """The column names of a JSON ``cells`` object or of a structured table."""
    names = getattr(getattr(cells, "dtype", None), "names", None)
    return tuple(names) if names is not None else tuple(cells)


def _checked_axes(axes: object) -> tuple[str, ...]:
    """``axes`` as a tuple of names of :data:`NAMES`, each once, in the canonical order, starting
    with the obstacle's size (:data:`SIZE`).

    Raises:
        InvalidParameterError: anything else (the message names the axes).
    """
    given = tuple(axes) if isinstance(axes, tuple | list) else None
    if given is None or given[: len(SIZE)] != SIZE or any(name not in NAMES for name in given):
        raise InvalidParameterError("axes", axes, f"names among {', '.join(NAMES)} starting with {', '.join(SIZE)}")
    if sorted(given, key=NAMES.index) != list(given) or len(set(given)) != len(given):
        raise InvalidParameterError("axes", axes, f"each name once, in the order {', '.join(NAMES)}")
    return given


def head_axes(document: dict) -> tuple[str, ...]:
    """The axes a map document (or header) names; the obstacle's size for formats /1 and /2,
    which name none."""
    return _checked_axes(tuple(document.get("axes", SIZE)))


def head_ranges(document: dict) -> tuple[tuple[float, float], ...]:
    """The fitted range (lo, hi) of every axis of a map document (or header), in axes order [m].

    Raises:
        KeyError, TypeError, ValueError: a range missing or malformed.
    """
    fitted = document["fitted_range"]
    return tuple((float(fitted[name][0]), float(fitted[name][1])) for name in head_axes(document))


def header_fields(document: dict) -> dict:
    """The map's fields that every format stores alike, from its document (or header): the link to
    the coefficients, the axes, the margin and tolerance, the settings.

    Raises:
        KeyError, TypeError, ValueError, IndexError: a field missing or malformed.
    """
    link = document["coefficients"]
    return {
        "family": str(link["family"]),
        "coefficients_source": str(link["source"]),
        "coefficients_sha256": str(link["sha256"]),
        "axes": head_axes(document),
        "margin_m": float(document["margin_m"]),
        "endpoint_tolerance_m": float(document["endpoint_tolerance_m"]),
        "details": dict(document.get("details", {})),
    }


def source_name(source: object) -> str:
    """The name a map records for its coefficients' source: the file name of a path (no folder),
    a non-path source (the paper's ``"paper"``) as it is."""
    return Path(str(source)).name if source else ""


def _column(values: list, name: str) -> np.ndarray:
    """A bound column read from JSON (:func:`_number`: null is -inf for the clearance bound, +inf
    for the upper bounds)."""
    infinite = -math.inf if name == "clearance_bound_m" else math.inf
    return np.array([_number(v, infinite) for v in values], dtype=float)


def _number(value, infinite: float) -> float:
    """A JSON number; null stands for the column's infinite value (json_safe writes non-finite
    values as null): -inf for lower bounds, +inf for upper bounds."""
    return infinite if value is None else float(value)


def region_map_text(region_map: RegionMap) -> str:
    """The map's file content: compact JSON, newline-terminated (the bytes its sha256 is of)."""
    return json.dumps(json_safe(region_map.to_json()), separators=(",", ":"), allow_nan=False) + "\n"


def save_region_map_json(region_map: RegionMap, path: str | Path, overwrite: bool = True) -> str:
    """Write the map atomically as one compact JSON document (:data:`FORMAT_JSON`; the files a build
    writes are :func:`pipeline.certify.map_files.save_region_map`'s header and table); returns the
    sha256 of the bytes written."""
    text = region_map_text(region_map)
    write_text_atomic(path, text, overwrite)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()
