"""Near-optimal timings from the map: one certified timing per cell of a grid over the fitted range.

The near time-optimal timing (:mod:`pipeline.motion.near_optimal`) of one path costs about a
millisecond. Over a small box of obstacles the regression's paths differ little, and in the
normalised path time u = s / T they share one timing (:mod:`pipeline.motion.path_box`): the
box's parameters and T are enclosed like a region map leaf's, with their gradients over the box
and their values at its centre (:func:`pipeline.certify.execution_range.leaf_jets`), so that the
path's derivatives are enclosed both in intervals and in the mean-value form; the profile is
built on the box's worst-case constraints, and the execution certificate proves its bounds for
every path of the box over all of [0, T'] in continuous time. The regression's answer and its T,
as the online core computes them, lie in those enclosures (they carry their rounding bounds:
:mod:`pipeline.certify.execution_range`).
A query of the cell then executes ``T sigma``: its T' and its bounds are the cell's, read off a
table (a lookup); its timing is rebuilt from the stored profile when the motion is asked for.

**The grid.** ``cells_per_axis`` equal cells per axis of the fitted box (any axes the
coefficients vary), indexed in C order; a point on a shared face belongs to the cell above it,
the fitted box's upper faces to the last cell. Each cell is enclosed 1e-9 of its side wider than
it is, so that a point the lookup's floating-point arithmetic assigns to it lies in the box
enclosed. A cell whose timing is not certified within the attempts holds NaN: its queries are
timed per query.

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

import functools
import hashlib
import io
import math
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from pipeline.certify.execution_bounds import dynamics_json, limits_json
from pipeline.certify.execution_range import LeafJets, leaf_jets
from pipeline.certify.range_model import RangeModel
from pipeline.exceptions import DataFileError, InvalidParameterError, TimingRefusedError
from pipeline.io.executor import Executor, map_tasks
from pipeline.io.jsonio import dumps, read_json
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.execution_certificate import ExecutionCertificate
from pipeline.motion.near_optimal import NearOptimalSettings, near_optimal_box_timing, profile_timing
from pipeline.motion.path_box import PathBox, normalised_mean_value
from pipeline.motion.smooth_timing import SmoothTiming
from pipeline.offline.coefficients import Coefficients

__all__ = [
    "CELLS_NAME",
    "FORMAT",
    "NearOptimalCells",
    "cells_file_names",
    "cells_files",
    "load_near_optimal_cells",
    "near_optimal_cells",
]

FORMAT = "twolink-near-optimal-cells/1"
CELLS_NAME = "near_optimal_cells.json"
#: Cells per axis by the number of axes (the table's size grows as its power).
DEFAULT_CELLS_PER_AXIS = MappingProxyType({2: 64, 3: 16, 4: 8})
#: Pieces of each cell's profile.
DEFAULT_PIECES = NearOptimalSettings().pieces
#: How each cell's timing is built by default.
CELL_SETTINGS = NearOptimalSettings(pieces=DEFAULT_PIECES)
_CHUNK = 128
#: Each cell's box is enclosed this much wider (relative) than its side: a point the lookup's
#: rounded arithmetic puts in the cell lies within the box enclosed.
_FACE_SLACK = 1e-9


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


def _uncertified(rows: int, pieces: int) -> np.ndarray:
    """``rows`` table rows holding no certified timing (T' and the bounds NaN)."""
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


def _cell_box(jets: LeafJets, n: int, half_m: np.ndarray) -> PathBox | None:
    """Cell n's box of paths with its mean-value form, or None where its enclosures are not finite."""
    lower = np.array([p.lo[n] for p in jets.parameters])
    upper = np.array([p.hi[n] for p in jets.parameters])
    point = (np.array([p.lo[n] for p in jets.point]), np.array([p.hi[n] for p in jets.point]))
    duration = (float(jets.duration.lo[n]), float(jets.duration.hi[n]))
    point_T = (float(jets.point_duration.lo[n]), float(jets.point_duration.hi[n]))
    gradient = (np.array([g.lo[n] for g in jets.gradients]), np.array([g.hi[n] for g in jets.gradients]))
    finite = [lower, upper, *point, *gradient, np.array([*duration, *point_T])]
    if not all(np.all(np.isfinite(v)) for v in finite):
        return None
    form = normalised_mean_value(
        point,
        gradient,
        (point_T, duration),
        (jets.duration_gradient.lo[n], jets.duration_gradient.hi[n]),
        (lower, upper),
        half_m,
    )
    centre = 0.5 * (point[0] + point[1])
    return PathBox.of_intervals(lower, upper, duration, centre, 0.5 * (point_T[0] + point_T[1]), form)


def _cell_rows(
    model: RangeModel, dynamics: PlanarDynamics, limits: ArmLimits, settings: NearOptimalSettings, chunk
) -> np.ndarray:
    """The table rows of a chunk of cells (centres, half widths (n, k))."""
    centres, halves = chunk
    jets = leaf_jets(model, centres, halves)
    rows = _uncertified(centres.shape[0], settings.pieces)
    for n in range(centres.shape[0]):
        try:
            box = _cell_box(jets, n, halves[n])
            if box is None:
                continue
            result = near_optimal_box_timing(box, dynamics, limits, settings)
        except (TimingRefusedError, InvalidParameterError):
            continue
        c = result.certificate
        (lo1, hi1), (lo2, hi2) = c.angle_range_rad
        rows["x"][n], rows["windows_s"][n] = result.profile
        rows["duration_s"][n] = result.executed.duration_s
        rows["bounds"][n] = np.concatenate(
            [[hi1, hi2, -lo1, -lo2], c.speed_bound_rad_s, c.acceleration_bound_rad_s2]
            + [c.torque_bound_n_m, c.jerk_bound_rad_s3]
        )
    return rows


def near_optimal_cells(
    coefficients: Coefficients,
    dynamics: PlanarDynamics,
    limits: ArmLimits,
    cells_per_axis: int | None = None,
    settings: NearOptimalSettings = CELL_SETTINGS,
    executor: int | Executor = 1,
    only: np.ndarray | None = None,
) -> NearOptimalCells:
    """The certified near-optimal timing of every cell of the grid (module docstring).

    Args:
        coefficients: The coefficients (read from a file: the cells link to its sha256).
        dynamics: The arm's dynamics.
        limits: The limits to keep, with finite jerk limits (:meth:`ArmLimits.with_servo_defaults`).
        cells_per_axis: Cells along each axis (default :data:`DEFAULT_CELLS_PER_AXIS` by the axes' count).
        settings: How each cell's timing is built.
        executor: Where the fixed chunks of cells run (local processes or an executor); the rows
            do not depend on it.
        only: Compute only these cells (indices); the others hold NaN, as cells without a
            certified timing do (for a question about a few obstacles).
    """
    model = RangeModel.from_coefficients(coefficients)
    k = model.k
    grid_n = DEFAULT_CELLS_PER_AXIS.get(k, 4) if cells_per_axis is None else cells_per_axis
    if not (isinstance(grid_n, int) and not isinstance(grid_n, bool) and grid_n >= 1):
        raise InvalidParameterError("cells_per_axis", grid_n, "an integer >= 1")
    grid = (grid_n,) * k
    index = np.stack(np.unravel_index(np.arange(grid_n**k), grid), axis=1)
    size = model.range_size / grid_n
    centres = model.range_lo + (index + 0.5) * size
    halves = np.broadcast_to(size / 2.0 * (1.0 + _FACE_SLACK), centres.shape).copy()
    wanted = np.arange(centres.shape[0]) if only is None else np.unique(np.asarray(only, dtype=np.int64))
    chunks = [(centres[wanted[i : i + _CHUNK]], halves[wanted[i : i + _CHUNK]]) for i in range(0, wanted.size, _CHUNK)]
    task = functools.partial(_cell_rows, model, dynamics, limits, settings)
    table = _uncertified(centres.shape[0], settings.pieces)
    if chunks:
        table[wanted] = np.concatenate(map_tasks(executor, task, chunks, chunk_size=1))
    return NearOptimalCells(
        coefficients.source_sha256, tuple(model.axes.names), model.range_lo.copy(), model.range_size.copy(),
        grid, limits, dynamics, settings, table,
    )  # fmt: skip


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
