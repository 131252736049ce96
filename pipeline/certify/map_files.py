"""A region map on disk: a small JSON header and its leaves as one NumPy ``.npy`` table.

``region_map.json`` (format ``twolink-region-map/4``) holds what describes the map: the sha256
link to its coefficients, the axes and fitted range, margin and tolerance, the statuses, the
summary, the settings, the execution bounds' limits and dynamics, and ``leaves``: the file name
of the table beside it (``region_map.npy``), its sha256, its row count and its fields. The table
is one structured array, one row per leaf, little-endian, with the leaf's node (``depth``, an
``index_<axis>`` per axis, ``split_W``), its ``status`` (index into the header's statuses), its
three bounds and, with execution bounds, their columns
(:data:`pipeline.certify.execution_bounds.COLUMNS`), every number as the map holds it
(float64: a round trip keeps every bit). ``numpy.save`` writes no timestamp, so the same map
gives the same bytes.

Reading checks, before anything is built from them: the header's format, the table's sha256
(a table truncated or edited after it was written is refused), and its fields and row count
against the header; the table is read with ``numpy.load(mmap_mode="r")``. The JSON formats /1 to
/3 (the leaves as JSON columns) are read too (:meth:`RegionMap.from_json`); ``python -m
pipeline.certify_range --convert OLD`` rewrites such a map in this format, keeping every number.

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
from pipeline.certify.region_map import DEFAULT_MAP_NAME, READABLE_FORMATS, STATUSES, RegionMap, header_fields
from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.io.jsonio import dumps, read_json, write_bytes_atomic
from pipeline.offline.variables import SIZE

__all__ = [
    "FORMAT_ARRAYS",
    "LEAVES_SUFFIX",
    "load_region_map",
    "region_map_files",
    "region_map_of",
    "save_region_map",
    "table_name",
]

#: Format of a map stored as a JSON header and a ``.npy`` table of leaves.
FORMAT_ARRAYS = "twolink-region-map/4"
#: Suffix of the leaf table beside the header (``region_map.json`` -> ``region_map.npy``).
LEAVES_SUFFIX = ".npy"
#: The bound columns of every map, in the table's order.
_BOUNDS = ("clearance_bound_m", "endpoint_bound_m", "endpoint_clearance_upper_m")


def table_name(header_name: str) -> str:
    """The file name of the leaf table beside a header named ``header_name``."""
    return Path(header_name).with_suffix(LEAVES_SUFFIX).name


def _dtype(axes: tuple[str, ...], execution: bool) -> np.dtype:
    """The table's row type for a map over ``axes`` (with execution columns if ``execution``)."""
    fields = [("depth", "<i1"), *((f"index_{axis}", "<i4") for axis in axes), ("split_W", "<i1"), ("status", "<i1")]
    fields += [(name, "<f8") for name in _BOUNDS]
    fields += [(name, "<f8") for name in EXECUTION_COLUMNS] if execution else []
    return np.dtype(fields)


def _table(region_map: RegionMap) -> np.ndarray:
    """The map's leaves as one structured array (module docstring)."""
    table = np.zeros(region_map.depth.size, dtype=_dtype(region_map.axes, region_map.execution is not None))
    table["depth"], table["split_W"], table["status"] = region_map.depth, region_map.split_w, region_map.status
    table["index_L"], table["index_W"] = region_map.index_l, region_map.index_w
    for column, axis in enumerate(region_map.axes[2:]):
        table[f"index_{axis}"] = region_map.extra_index[:, column]
    for name in _BOUNDS:
        table[name] = getattr(region_map, name)
    if region_map.execution is not None:
        for name in EXECUTION_COLUMNS:
            table[name] = region_map.execution.columns[name]
    return table


def _header(region_map: RegionMap, table_bytes: bytes, name: str, rows: int, fields: tuple[str, ...]) -> dict:
    """The header document (module docstring): the JSON document without its leaves."""
    document = region_map.to_json()
    del document["cells"]
    document["format"] = FORMAT_ARRAYS
    document["axes"] = list(region_map.axes)
    if region_map.execution is not None:
        del document["execution"]["columns"]
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
    header = _header(region_map, table_bytes, name, table.size, table.dtype.names)
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
    if document.get("format") != FORMAT_ARRAYS:
        expected = ", ".join(repr(f) for f in (*READABLE_FORMATS, FORMAT_ARRAYS))
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
    try:
        data = table_path.read_bytes()
    except OSError as exc:
        raise DataFileError(table_path, f"the region map's leaf table cannot be read ({exc.strerror})") from None
    if hashlib.sha256(data).hexdigest() != leaves["sha256"]:
        raise DataFileError(
            table_path, f"sha256 differs from the one {path.name} records: the table changed after the map was written"
        )
    table = np.load(table_path, mmap_mode="r", allow_pickle=False)
    if table.dtype.names != tuple(leaves["fields"]) or table.shape != (int(leaves["rows"]),):
        raise DataFileError(
            table_path,
            f"holds {table.shape[0]} rows of {table.dtype.names}, "
            f"the header says {leaves['rows']} of {tuple(leaves['fields'])}",
        )
    return table


def _from_table(document: dict, table: np.ndarray, source: Path) -> RegionMap:
    """The map of a checked header and table."""
    fitted = document["fitted_range"]
    axes = tuple(document["axes"])
    statuses = tuple(document["statuses"])
    if statuses != STATUSES:
        raise DataFileError(source, f"statuses are {list(statuses)}, expected {list(STATUSES)}")
    extra = axes[2:]
    execution = document.get("execution")
    return RegionMap(
        **header_fields(document),
        depth=table["depth"],
        index_l=table["index_L"],
        index_w=table["index_W"],
        clearance_bound_m=table["clearance_bound_m"],
        endpoint_bound_m=table["endpoint_bound_m"],
        endpoint_clearance_upper_m=table["endpoint_clearance_upper_m"],
        status=table["status"],
        seconds=math.nan,
        split_w=table["split_W"],
        execution=None
        if execution is None
        else ExecutionBounds.from_json(
            {**execution, "columns": {name: table[name] for name in EXECUTION_COLUMNS}}, source
        ),
        axes=axes if axes != SIZE else SIZE,
        extra_ranges_m=tuple((float(fitted[name][0]), float(fitted[name][1])) for name in extra),
        extra_index=np.column_stack([table[f"index_{name}"] for name in extra]) if extra else None,
    )
