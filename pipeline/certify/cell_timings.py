"""Certifying the near-optimal timing of every cell of a grid over the fitted range (the build's
step; the cells, their files and their lookups: :mod:`pipeline.certify.near_optimal_cells`).

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

Each cell is enclosed 1e-9 of its side wider than it is (:data:`_FACE_SLACK`), so that a point the
lookup's floating-point arithmetic assigns to it lies in the box enclosed. A cell whose timing is
not certified within the attempts holds NaN.
"""

from __future__ import annotations

import functools
from types import MappingProxyType

import numpy as np

from pipeline.certify.execution_range import LeafJets, leaf_jets
from pipeline.certify.near_optimal_cells import NearOptimalCells, uncertified_rows
from pipeline.certify.range_model import RangeModel
from pipeline.exceptions import InvalidParameterError, TimingRefusedError
from pipeline.io.executor import Executor, map_tasks
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.near_optimal import NearOptimalSettings, near_optimal_box_timing
from pipeline.motion.path_box import PathBox, normalised_mean_value
from pipeline.offline.coefficients import Coefficients

__all__ = ["CELL_SETTINGS", "DEFAULT_CELLS_PER_AXIS", "near_optimal_cells"]

#: Cells per axis by the number of axes (the table's size grows as its power).
DEFAULT_CELLS_PER_AXIS = MappingProxyType({2: 64, 3: 16, 4: 8})
#: How each cell's timing is built by default.
CELL_SETTINGS = NearOptimalSettings()
_CHUNK = 128
#: Each cell's box is enclosed this much wider (relative) than its side: a point the lookup's
#: rounded arithmetic puts in the cell lies within the box enclosed.
_FACE_SLACK = 1e-9


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
    rows = uncertified_rows(centres.shape[0], settings.pieces)
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
    """The certified near-optimal timing of every cell of the grid
    (:mod:`pipeline.certify.near_optimal_cells`: the grid and the table).

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
    table = uncertified_rows(centres.shape[0], settings.pieces)
    if chunks:
        table[wanted] = np.concatenate(map_tasks(executor, task, chunks, chunk_size=1))
    return NearOptimalCells(
        coefficients.source_sha256, tuple(model.axes.names), model.range_lo.copy(), model.range_size.copy(),
        grid, limits, dynamics, settings, table,
    )  # fmt: skip
