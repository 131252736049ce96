"""A region map on disk: a small JSON header and its leaves as one NumPy ``.npy`` table.

``region_map.json`` (format ``twolink-region-map/5``) holds what describes the map: the sha256
link to its coefficients, the axes and fitted range, margin and tolerance, the statuses, the
summary, the settings, the execution bounds' limits and dynamics, and ``leaves``: the file name
of the table beside it (``region_map.npy``), its sha256, its row count (leaves) and its fields.
The table is one record of columns (a 0-d structured array whose fields each hold a column,
stored one after the other: a column read from the memory-mapped file is contiguous),
little-endian: the subpaving's tree (:mod:`pipeline.certify.subpaving`: ``cut_axis``,
``cut_level`` and ``children``, one row per internal node, n - 1 rows), then per leaf its
``status`` (index into the header's statuses), its three bounds and, with execution bounds,
their columns
(:data:`pipeline.certify.execution_bounds.COLUMNS`), every number as the map holds it: a float
column as float64, or, where every value of it is a short decimal (the execution bounds, rounded
outward to 7 digits), as an int32 mantissa and an int8 exponent (fields ``<name>.mantissa``,
``<name>.exponent``: :mod:`pipeline.io.decimal_columns`, 5 bytes instead of 8), chosen only where
the round trip keeps every bit. ``numpy.save`` writes no timestamp, so the same map gives the
same bytes.

Reading checks, before anything is built from them: the header's format, the table's sha256
(a table truncated or edited after it was written is refused), and its fields and row count
against the header, and that the tree is one (each leaf and node reached once); the table is
read with ``numpy.load(mmap_mode="r")``. Maps of the earlier formats are read too, keeping every
number: the JSON formats /1 to /3 (:meth:`RegionMap.from_json`) and /4, whose table held a
2^k-tree's nodes (``depth``, an ``index_<axis>`` per axis, the halvings ``split_<axis>`` of the
second) in place of the tree; ``python -m pipeline.certify_range --convert OLD`` rewrites such a
map in this format.

Writing puts the table first and the header last, each atomically, so a header on disk always
names a complete table; an interrupted write leaves the previous header, whose sha256 then
refuses a table that changed under it.
"""

from __future__ import annotations

import hashlib
import io
import math
from pathlib import Path

import numpy as np

from pipeline.certify.execution_bounds import COLUMNS as EXECUTION_COLUMNS
from pipeline.certify.execution_bounds import ExecutionBounds
from pipeline.certify.region_map import (
    BOUND_COLUMNS,
    DEFAULT_MAP_NAME,
    READABLE_FORMATS,
    STATUSES,
    RegionMap,
    head_ranges,
    header_fields,
    tree_leaves,
)
from pipeline.certify.subpaving import Subpaving
from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.io.decimal_columns import FloatColumns, decimal_parts, from_decimal_parts
from pipeline.io.jsonio import dumps, read_json, write_bytes_atomic

__all__ = [
    "FORMAT_ARRAYS",
    "LEAVES_SUFFIX",
    "load_region_map",
    "region_map_files",
    "region_map_of",
    "save_region_map",
    "table_name",
]

#: Format of a map stored as a JSON header and a ``.npy`` table of its tree and leaves.
FORMAT_ARRAYS = "twolink-region-map/5"
#: The earlier format of a JSON header and a table, whose table held a 2^k-tree's nodes.
FORMAT_NODES = "twolink-region-map/4"
#: The tree's fields, one row per internal node (n - 1 rows).
TREE_FIELDS = ("cut_axis", "cut_level", "children")
#: Suffix of the leaf table beside the header (``region_map.json`` -> ``region_map.npy``).
LEAVES_SUFFIX = ".npy"
#: Bytes read at a time while hashing a table.
_HASH_BLOCK = 1 << 20
#: Suffixes of the two fields of a float column stored as short decimals.
_MANTISSA, _EXPONENT = ".mantissa", ".exponent"


def table_name(header_name: str) -> str:
    """The file name of the leaf table beside a header named ``header_name``."""
    return Path(header_name).with_suffix(LEAVES_SUFFIX).name


def _columns(region_map: RegionMap) -> dict[str, np.ndarray]:
    """The map's columns in the table's order, by field name: the tree, the status, then the
    float columns, each as short decimals where that keeps every bit (``<name>.mantissa``,
    ``<name>.exponent``: :mod:`pipeline.io.decimal_columns`), else as float64."""
    tree = region_map.subpaving
    columns = {
        "cut_axis": tree.cut_axis.astype("<i1"),
        "cut_level": tree.cut_level.astype("<i1"),
        "children": tree.children.astype("<i4"),
        "status": region_map.status.astype("<i1"),
    }
    floats = {name: getattr(region_map, name) for name in BOUND_COLUMNS}
    if region_map.execution is not None:
        floats |= {name: region_map.execution.columns[name] for name in EXECUTION_COLUMNS}
    for name, values in floats.items():
        parts = decimal_parts(values)
        if parts is None:
            columns[name] = np.asarray(values, dtype="<f8")
        else:
            columns[f"{name}{_MANTISSA}"], columns[f"{name}{_EXPONENT}"] = parts[0].astype("<i4"), parts[1]
    return columns


def _table(region_map: RegionMap) -> np.ndarray:
    """The map's leaves as one record of columns (module docstring): a 0-d structured array whose
    every field is one column of n values, stored one after the other, so that a column read from
    the memory-mapped file is contiguous."""
    columns = _columns(region_map)
    table = np.zeros((), dtype=np.dtype([(name, c.dtype.str, c.shape) for name, c in columns.items()]))
    for name, column in columns.items():
        table[name] = column
    return table


def _float_column(table: np.ndarray, name: str) -> np.ndarray:
    """The float64 column ``name`` of a table: stored as such, or as short decimals."""
    stored = _stored_column(table, name)
    return from_decimal_parts(*stored) if isinstance(stored, tuple) else stored


def _stored_column(table: np.ndarray, name: str) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """The float column ``name`` of a table as stored: float64, or (mantissa, exponent)."""
    if name in table.dtype.names:
        return table[name]
    return table[f"{name}{_MANTISSA}"], table[f"{name}{_EXPONENT}"]


def _header(region_map: RegionMap, table_bytes: bytes, name: str, rows: int, fields: tuple[str, ...]) -> dict:
    """The header document (module docstring): the JSON document without its leaves."""
    document = {"format": FORMAT_ARRAYS, **region_map.header_json()}
    if region_map.execution is not None:
        document["execution"] = region_map.execution.header_json()
    document["leaves"] = {
        "file": name,
        "sha256": hashlib.sha256(table_bytes).hexdigest(),
        "rows": rows,
        "fields": list(fields),
    }
    return document


def region_map_files(region_map: RegionMap, header_name: str = DEFAULT_MAP_NAME) -> dict[str, bytes]:
    """The map's two files by name, table first: ``{table_name: .npy bytes, header_name: JSON bytes}``."""
    table = _table(region_map)
    buffer = io.BytesIO()
    np.save(buffer, table, allow_pickle=False)
    table_bytes = buffer.getvalue()
    name = table_name(header_name)
    header = _header(region_map, table_bytes, name, region_map.size, table.dtype.names)
    return {name: table_bytes, header_name: dumps(header).encode("utf-8")}


def save_region_map(region_map: RegionMap, path: str | Path, overwrite: bool = True) -> str:
    """Write the map's header at ``path`` and its table beside it, each atomically (table first).

    Returns:
        The sha256 of the header's bytes.

    Raises:
        OutputExistsError: a file exists and ``overwrite`` is False, or the path is a folder.
    """
    path = Path(path)
    files = region_map_files(region_map, path.name)
    for name, data in files.items():
        write_bytes_atomic(path.with_name(name), data, overwrite)
    return hashlib.sha256(files[path.name]).hexdigest()


def load_region_map(path: str | Path) -> RegionMap:
    """Read a map written by :func:`save_region_map`, or a JSON map of the earlier formats.

    Raises:
        DataFileError: a file is missing, unreadable or malformed; the table's sha256, fields or
            rows differ from its header's; a format this version does not read.
    """
    path = Path(path)
    return region_map_of(read_json(path), path)


def region_map_of(document: dict, path: Path) -> RegionMap:
    """The map of a header (or an earlier format's whole document) read from ``path``, with its
    table beside it: :func:`load_region_map` after the JSON is parsed.

    Raises:
        DataFileError: as :func:`load_region_map`.
    """
    if not isinstance(document, dict):
        raise DataFileError(path, f"holds a {type(document).__name__}, expected a region map object")
    if document.get("format") in READABLE_FORMATS:
        return RegionMap.from_json(document, path)
    if document.get("format") not in (FORMAT_ARRAYS, FORMAT_NODES):
        expected = ", ".join(repr(f) for f in (*READABLE_FORMATS, FORMAT_NODES, FORMAT_ARRAYS))
        raise DataFileError(path, f"format is {document.get('format')!r}, expected one of {expected}")
    try:
        table = _checked_table(path, document["leaves"])
        return _from_table(document, table, path)
    except DataFileError:
        raise
    except (KeyError, TypeError, ValueError, IndexError, InvalidParameterError) as exc:
        raise DataFileError(path, f"malformed region map ({exc.__class__.__name__}: {exc})") from None


def _checked_table(path: Path, leaves: dict) -> np.ndarray:
    """The table the header ``leaves`` names, memory-mapped, after checking its sha256, fields and rows."""
    table_path = path.with_name(Path(str(leaves["file"])).name)
    digest = hashlib.sha256()
    try:
        with table_path.open("rb") as stream:  # in blocks: the table is never held twice in memory
            for block in iter(lambda: stream.read(_HASH_BLOCK), b""):
                digest.update(block)
    except OSError as exc:
        raise DataFileError(table_path, f"the region map's leaf table cannot be read ({exc.strerror})") from None
    if digest.hexdigest() != leaves["sha256"]:
        raise DataFileError(
            table_path, f"sha256 differs from the one {path.name} records: the table changed after the map was written"
        )
    table = np.load(table_path, mmap_mode="r", allow_pickle=False)
    names, fields = table.dtype.names or (), tuple(leaves["fields"])
    # A record of columns (each field n values, the tree's n - 1), or a table of rows (each field one value).
    rows = sorted(
        {
            (table.dtype[name].shape[0] + (name in TREE_FIELDS)) if table.dtype[name].shape else table.size
            for name in names
        }
    )
    if table.ndim > 1 or names != fields or rows != [int(leaves["rows"])]:
        missing = sorted(set(fields) - set(names)) or sorted(set(names) - set(fields))
        raise DataFileError(
            table_path,
            f"holds {'/'.join(map(str, rows))} rows of {len(names)} columns, the header says {leaves['rows']} rows "
            f"of {len(fields)} columns" + (f" (differing: {', '.join(missing[:3])})" if missing else ""),
        )
    return table


def _from_table(document: dict, table: np.ndarray, source: Path) -> RegionMap:
    """The map of a checked header and table (format /5, or /4's nodes turned into the tree)."""
    statuses = tuple(document["statuses"])
    if statuses != STATUSES:
        raise DataFileError(source, f"statuses are {list(statuses)}, expected {list(STATUSES)}")
    execution = document.get("execution")
    fields = header_fields(document) | {
        **{name: _float_column(table, name) for name in BOUND_COLUMNS},
        "status": table["status"],
        "seconds": math.nan,
        "execution": None
        if execution is None
        else ExecutionBounds.from_json(
            {**execution, "columns": FloatColumns({name: _stored_column(table, name) for name in EXECUTION_COLUMNS})},
            source,
        ),
    }
    ranges = head_ranges(document)
    if document["format"] == FORMAT_NODES:
        return RegionMap.of_leaves(ranges, *tree_leaves(document, table), **fields)
    tree = Subpaving(ranges, table["cut_axis"], table["cut_level"], table["children"])
    return RegionMap(subpaving=tree, **fields)
