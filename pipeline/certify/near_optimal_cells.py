"""Near-optimal timings from the map: one certified timing per cell of a grid over the fitted
range, as a table with its files and its lookups.

The cells are certified by :mod:`pipeline.certify.cell_timings` (the build's step; its derivation
is there): every path of a cell's box of obstacles shares the cell's timing in the normalised path
time u = s / T, proven within the limits over all of [0, T'] in continuous time. A query of the
cell then executes ``T sigma``: its T' and its bounds are the cell's, read off the table (a
lookup); its timing is rebuilt from the stored profile when the motion is asked for. This module
is what a loaded map needs, without the build's machinery.

**The grid.** ``cells_per_axis`` equal cells per axis of the fitted box (any axes the
coefficients vary), indexed in C order; a point on a shared face belongs to the cell above it,
the fitted box's upper faces to the last cell. A cell whose timing is not certified holds NaN:
its queries are timed per query.

**Stored.** ``near_optimal_cells.json`` (format :data:`FORMAT`: the sha256 link to the
coefficients, the axes, the fitted box, the grid, the limits and inertias the timings were made
for, the settings, and the table's name, sha256, fields and rows) and ``near_optimal_cells.npy``:
one structured row per cell, the profile (x, ramp widths) in float32 exactly as certified
(:func:`pipeline.motion.near_optimal.profile_timing` rebuilds the timing float for float),
T' [s] and the 12 certified bounds in the execution certificate's order (the angles' maxima, the
negated minima, |dq|, |ddq|, |tau|, |jerk| per joint). ``numpy.save`` writes no timestamp: the
same cells give the same bytes.
"""

from __future__ import annotations

import hashlib
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.certify.execution_bounds import dynamics_json, limits_json
from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.io.jsonio import dumps, read_json
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.execution_certificate import ExecutionCertificate
from pipeline.motion.near_optimal import NearOptimalSettings, profile_timing
from pipeline.motion.smooth_timing import SmoothTiming

__all__ = [
    "CELLS_NAME",
    "FORMAT",
    "NearOptimalCells",
    "cells_file_names",
    "cells_files",
    "load_near_optimal_cells",
    "uncertified_rows",
]

FORMAT = "twolink-near-optimal-cells/1"
CELLS_NAME = "near_optimal_cells.json"


def _limits_json(limits: ArmLimits) -> dict:
    return {**limits_json(limits), "jerk_rad_s3": list(limits.jerk_rad_s3)}


def _limits_of(document: dict) -> ArmLimits:
    def finite(values, infinite):
        return tuple(infinite if v is None else float(v) for v in values)

    return ArmLimits(
        position_rad=tuple(
            (finite([lo], -math.inf)[0], finite([hi], math.inf)[0]) for lo, hi in document["position_rad"]
        ),
        velocity_rad_s=finite(document["velocity_rad_s"], math.inf),
        acceleration_rad_s2=finite(document["acceleration_rad_s2"], math.inf),
        effort_n_m=finite(document["effort_n_m"], math.inf),
        jerk_rad_s3=finite(document["jerk_rad_s3"], math.inf),
    )


def _dtype(pieces: int) -> np.dtype:
    return np.dtype(
        [
            ("x", "<f4", (pieces + 1,)),
            ("windows_s", "<f4", (pieces + 1,)),
            ("duration_s", "<f8"),
            ("bounds", "<f8", (12,)),
        ]
    )


def uncertified_rows(rows: int, pieces: int) -> np.ndarray:
    """``rows`` table rows of profiles of ``pieces`` pieces holding no certified timing (T' and the
    bounds NaN)."""
    table = np.zeros(rows, dtype=_dtype(pieces))
    table["duration_s"], table["bounds"] = np.nan, np.nan
    return table


@dataclass(frozen=True, eq=False)
class NearOptimalCells:
    """Certified near-optimal timings per cell of a grid over the fitted range (module docstring).

    Attributes:
        coefficients_sha256: sha256 of the coefficients file the cells were made from.
        axes: The coefficients' axes, in order (("L", "W"), or with x, d).
        range_lo_m, range_size_m: The fitted box's lower corner and sides [m], (k,).
        cells_per_axis: Cells along each axis.
        limits: The limits the timings keep (with their acceleration and jerk limits).
        dynamics: The inertias the torques were bounded with.
        settings: How each cell's timing was built.
        table: One structured row per cell (fields x, windows_s, duration_s [s], bounds).
    """

    coefficients_sha256: str
    axes: tuple[str, ...]
    range_lo_m: np.ndarray
    range_size_m: np.ndarray
    cells_per_axis: tuple[int, ...]
    limits: ArmLimits
    dynamics: PlanarDynamics
    settings: NearOptimalSettings
    table: np.ndarray

    def __post_init__(self) -> None:
        count = int(np.prod(self.cells_per_axis))
        if len(self.cells_per_axis) != len(self.axes) or self.table.shape != (count,):
            raise InvalidParameterError("table", self.table.shape, f"one row per cell of {self.cells_per_axis}")
        # What the queries reuse, owned by these cells: the box as Python floats for the scalar
        # lookup, and each cell's timing rebuilt once, on first use.
        object.__setattr__(self, "_box", tuple(zip(self.range_lo_m.tolist(), self.range_size_m.tolist(), strict=True)))
        object.__setattr__(self, "_durations", np.asarray(self.table["duration_s"]).tolist())
        object.__setattr__(self, "_rebuilt", {})
        object.__setattr__(self, "_certificates", {})
        object.__setattr__(self, "_made_for", {})

    @property
    def certified(self) -> np.ndarray:
        """Per cell, whether it holds a certified timing (bool, (cells,))."""
        return np.isfinite(self.table["duration_s"])

    def cells_of(self, points_m: np.ndarray) -> np.ndarray:
        """The cell of each point (n, k) [m] in the axes' order; -1 outside the fitted box."""
        points = np.atleast_2d(np.asarray(points_m, dtype=float))
        grid = np.asarray(self.cells_per_axis)
        scaled = (points - self.range_lo_m) / self.range_size_m
        inside = np.all((scaled >= 0.0) & (scaled <= 1.0), axis=1)
        index = np.minimum(np.floor(np.where(inside[:, None], scaled, 0.0) * grid).astype(np.int64), grid - 1)
        return np.where(inside, np.ravel_multi_index(tuple(index.T), tuple(grid)), -1)

    def made_for(self, limits: ArmLimits, dynamics: PlanarDynamics) -> bool:
        """Whether these cells' timings keep ``limits`` with the servo defaults filled in
        (:meth:`ArmLimits.with_servo_defaults`, what the near-optimal timing keeps) for the arm of
        ``dynamics``: they were made for exactly those."""
        key = (limits, dynamics)
        made = self._made_for.get(key)
        if made is None:
            made = self._made_for.setdefault(
                key, limits.with_servo_defaults() == self.limits and dynamics == self.dynamics
            )
        return made

    def cell_of(self, *values_m: float) -> int | None:
        """The certified cell holding the point (its coordinates in the axes' order) [m], or None
        (the scalar twin of :meth:`cells_of`, in Python floats)."""
        if len(values_m) != len(self._box):
            return None
        cell = 0
        for value, (lo, size), count in zip(values_m, self._box, self.cells_per_axis, strict=True):
            scaled = (value - lo) / size
            if not 0.0 <= scaled <= 1.0:
                return None
            cell = cell * count + min(math.floor(scaled * count), count - 1)
        return cell if math.isfinite(self._durations[cell]) else None

    def timing(self, cell: int, path_duration_s: float) -> SmoothTiming:
        """The cell's timing of a path of duration T = ``path_duration_s`` [s] (``T sigma``)."""
        normalised = self._rebuilt.get(cell)
        if normalised is None:
            row = self.table[cell]
            normalised = self._rebuilt.setdefault(cell, profile_timing(row["x"], row["windows_s"]))
        return normalised.scaled(float(path_duration_s))

    def certificate(self, cell: int) -> ExecutionCertificate:
        """The cell's bounds as a certificate (source "range": proven for every obstacle of the
        cell); one read-only certificate per cell, made on first use."""
        found = self._certificates.get(cell)
        if found is not None:
            return found
        b = np.array(self.table[cell]["bounds"])
        b.flags.writeable = False
        certificate = ExecutionCertificate(
            "near-optimal",
            self._durations[cell],
            ((-float(b[2]), float(b[0])), (-float(b[3]), float(b[1]))),
            b[4:6],
            b[6:8],
            b[8:10],
            {},
            0,
            self.limits,
            "range",
            b[10:12],
        )
        return self._certificates.setdefault(cell, certificate)

    def header_json(self, table_bytes: bytes, table_name: str) -> dict:
        """The JSON header describing the cells and naming their table."""
        return {
            "format": FORMAT,
            "coefficients": {"sha256": self.coefficients_sha256},
            "axes": list(self.axes),
            "range_lo_m": self.range_lo_m.tolist(),
            "range_size_m": self.range_size_m.tolist(),
            "cells_per_axis": list(self.cells_per_axis),
            "limits": _limits_json(self.limits),
            "dynamics": dynamics_json(self.dynamics),
            "settings": {"pieces": self.settings.pieces, "tries": self.settings.tries},
            "certified_cells": int(self.certified.sum()),
            "table": {
                "file": table_name,
                "sha256": hashlib.sha256(table_bytes).hexdigest(),
                "rows": int(self.table.shape[0]),
                "pieces": self.settings.pieces,
            },
        }


def cells_file_names(header_name: str = CELLS_NAME) -> tuple[str, str]:
    """The names of the cells' two files: the table, then the header."""
    return Path(header_name).with_suffix(".npy").name, header_name


def cells_files(cells: NearOptimalCells, header_name: str = CELLS_NAME) -> dict[str, bytes]:
    """The cells' two files by name, table first: ``{table: .npy bytes, header: JSON bytes}``."""
    buffer = io.BytesIO()
    np.save(buffer, cells.table, allow_pickle=False)
    table_bytes = buffer.getvalue()
    table_name, _ = cells_file_names(header_name)
    return {table_name: table_bytes, header_name: dumps(cells.header_json(table_bytes, table_name)).encode("utf-8")}


def load_near_optimal_cells(path: str | Path) -> NearOptimalCells:
    """Read the cells written by :func:`cells_files` (the table checked against its header's sha256).

    Raises:
        DataFileError: missing, malformed, another format, or a table that is not the header's.
    """
    path = Path(path)
    document = read_json(path)
    if document.get("format") != FORMAT:
        raise DataFileError(path, f"format {document.get('format')!r}, expected {FORMAT!r}")
    try:
        table_path = path.with_name(document["table"]["file"])
        data = table_path.read_bytes()
        if hashlib.sha256(data).hexdigest() != document["table"]["sha256"]:
            raise DataFileError(
                table_path, "its sha256 is not the one its header records: changed after it was written"
            )
        pieces = int(document["table"]["pieces"])
        table = np.load(table_path, mmap_mode="r", allow_pickle=False)
        if table.dtype != _dtype(pieces) or table.shape != (int(document["table"]["rows"]),):
            raise DataFileError(table_path, f"fields or rows {table.dtype}, {table.shape} are not its header's")
        dyn = document["dynamics"]
        return NearOptimalCells(
            document["coefficients"]["sha256"],
            tuple(document["axes"]),
            np.array(document["range_lo_m"], dtype=float),
            np.array(document["range_size_m"], dtype=float),
            tuple(int(v) for v in document["cells_per_axis"]),
            _limits_of(document["limits"]),
            PlanarDynamics(*(tuple(tuple(float(v) for v in row) for row in dyn[k]) for k in ("m0", "mc", "ms"))),
            NearOptimalSettings(pieces=pieces, tries=int(document["settings"]["tries"])),
            table,
        )
    except (KeyError, TypeError, ValueError, OSError, InvalidParameterError) as exc:
        raise DataFileError(path, f"malformed near-optimal cells ({exc.__class__.__name__}: {exc})") from None
