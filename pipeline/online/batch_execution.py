"""Execution bounds of many answers at once, read off the region map (NumPy only, no arm needed).

For a :class:`pipeline.online.batch.GeneratedBatch` generated with the map, each answer's leaf
gives the bounds proven for every obstacle of the leaf (:mod:`pipeline.certify.execution_bounds`):
with the paper timing its angle range and its speed, acceleration and torque bounds; with the
rest-to-rest timing (c, r), the duration T' = T / c + r of the answer's own T, and that timing's
bounds; with the near-optimal timing, T' and the bounds of the map's near-optimal cell holding
the obstacle (:mod:`pipeline.certify.near_optimal_cells`), jerk included. The bounds hold for the
arm the map was built with (``ExecutionBatch.limits``); the answers for another arm are certified
per query (:func:`pipeline.generate_certified`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import InvalidParameterError
from pipeline.model.limits import ArmLimits
from pipeline.motion.near_optimal import NEAR_OPTIMAL, NearOptimal
from pipeline.motion.rest_to_rest import ShortestRestToRest
from pipeline.motion.timing import PAPER_TIMING, PaperTiming
from pipeline.offline.coefficients import Coefficients
from pipeline.online.batch import GeneratedBatch
from pipeline.online.generator import ATTACHED, _Attached, check_region_map

if TYPE_CHECKING:
    from pipeline.certify.near_optimal_cells import NearOptimalCells

__all__ = ["ExecutionBatch", "execution_batch"]


@dataclass(frozen=True, eq=False)
class ExecutionBatch:
    """The map's execution bounds of n answers (NaN where an answer has none: an error, outside
    the fitted range, or a leaf without a rest-to-rest timing).

    Attributes:
        timing_name: "paper", "rest-to-rest" or "near-optimal".
        limits: The limits of the arm the map was built with.
        duration_s: T' [s], (n,).
        speed_scale, ramp_s: The rest-to-rest timing's c and r [s], (n,) (1 and inf for the paper
            timing, NaN for the near-optimal one).
        angle_range_rad: (n, 2, 2) per joint (lo, hi) [rad].
        speed_bound_rad_s, acceleration_bound_rad_s2, torque_bound_n_m: (n, 2) bounds of |dq|
            [rad/s], |ddq| [rad/s^2], |tau| [N m].
        within_limits: (n,) True where every bound keeps ``limits`` (the answer is certified to
            execute; its clearance and endpoints are the batch's own bounds).
        jerk_bound_rad_s3: (n, 2) bounds of |jerk| [rad/s^3] for the near-optimal timing; None
            for the others (their jerk is not bounded).
    """

    timing_name: str
    limits: ArmLimits
    duration_s: np.ndarray
    speed_scale: np.ndarray
    ramp_s: np.ndarray
    angle_range_rad: np.ndarray
    speed_bound_rad_s: np.ndarray
    acceleration_bound_rad_s2: np.ndarray
    torque_bound_n_m: np.ndarray
    within_limits: np.ndarray
    jerk_bound_rad_s3: np.ndarray | None = None


def _checked_inputs(coefficients: Coefficients, batch, timing, region_map):
    """The map's execution bounds, after every check of :func:`execution_batch`'s arguments."""
    if region_map is ATTACHED:
        region_map = coefficients.region_map
    if region_map is None:
        raise InvalidParameterError("region_map", None, "a region map (python -m pipeline.build writes one)")
    check_region_map(region_map, coefficients)
    if region_map.execution is None and not isinstance(timing, NearOptimal):
        raise InvalidParameterError(
            "region_map", "without execution bounds", "a map with them (python -m pipeline.certify_range adds them)"
        )
    if not isinstance(batch, GeneratedBatch) or batch.leaf is None:
        raise InvalidParameterError("batch", type(batch).__name__, "a GeneratedBatch made with the region map")
    if isinstance(timing, NearOptimal):
        if region_map.near_optimal_cells is None or timing != NEAR_OPTIMAL:
            raise InvalidParameterError(
                "timing",
                timing.name,
                "PAPER_TIMING or REST_TO_REST: this map holds no near-optimal cells for these settings "
                "(python -m pipeline.build writes them); generate_certified(..., timing=NEAR_OPTIMAL) "
                "certifies it per query",
            )
    elif not isinstance(timing, PaperTiming | ShortestRestToRest):
        raise InvalidParameterError("timing", type(timing).__name__, "PAPER_TIMING, REST_TO_REST or NEAR_OPTIMAL")
    return region_map


def execution_batch(
    coefficients: Coefficients,
    batch: GeneratedBatch,
    timing: PaperTiming | ShortestRestToRest | NearOptimal = PAPER_TIMING,
    *,
    region_map: RegionMap | _Attached = ATTACHED,
) -> ExecutionBatch:
    """The execution bounds of ``batch``'s answers from ``region_map``'s leaves (module docstring).

    Args:
        coefficients: The coefficients of the batch.
        batch: From :func:`pipeline.generate_batch` with the same map.
        timing: ``PAPER_TIMING``, ``REST_TO_REST`` or ``NEAR_OPTIMAL`` (from the map's near-optimal
            cells, :mod:`pipeline.certify.near_optimal_cells`: T' and the bounds of each answer's
            cell, made for the limits with the servo defaults, ``ExecutionBatch.limits``).
        region_map: The map (default: the one attached to the coefficients).

    Raises:
        InvalidParameterError: no map, a map without execution bounds, a batch generated without
            the map, or an unknown timing.
        RegionMapMismatchError: the map certifies other coefficients.
    """
    region_map = _checked_inputs(coefficients, batch, timing, region_map)
    if isinstance(timing, NearOptimal):
        return _near_optimal_batch(region_map.near_optimal_cells, batch)
    bounds = region_map.execution
    leaf = batch.leaf
    inside = leaf >= 0
    k = np.where(inside, leaf, 0)
    n = leaf.size
    T = batch.durations_s
    if isinstance(timing, PaperTiming):
        scale, ramp, duration = np.ones(n), np.full(n, np.inf), T.copy()
        speed, acceleration, torque = (
            bounds.paper_speed_rad_s[k],
            bounds.paper_acceleration_rad_s2[k],
            bounds.paper_torque_n_m[k],
        )
    else:
        scale, ramp = bounds.columns["speed_scale"][k], bounds.columns["ramp_s"][k]
        duration = T / scale + ramp
        speed, acceleration, torque = (b[k] for b in bounds.rest_to_rest)
    angles = bounds.angle_range_rad[k]
    limits = bounds.limits
    keeps = inside & np.isfinite(duration) & _keeps(limits, angles, speed, acceleration, torque)
    missing = ~inside[:, None]
    return ExecutionBatch(
        PAPER_TIMING.name if isinstance(timing, PaperTiming) else timing.name,
        limits,
        np.where(inside, duration, np.nan),
        np.where(inside, scale, np.nan),
        np.where(inside, ramp, np.nan),
        np.where(missing[:, :, None], np.nan, angles),
        np.where(missing, np.nan, speed),
        np.where(missing, np.nan, acceleration),
        np.where(missing, np.nan, torque),
        keeps,
    )


def _keeps(limits: ArmLimits, angles, speed, acceleration, torque, jerk=None) -> np.ndarray:
    """(n,) True where every bound keeps ``limits``."""
    position = np.asarray(limits.position_rad)
    keeps = (
        np.all(angles[:, :, 0] >= position[:, 0], 1)
        & np.all(angles[:, :, 1] <= position[:, 1], 1)
        & np.all(speed <= np.asarray(limits.velocity_rad_s), 1)
        & np.all(acceleration <= np.asarray(limits.acceleration_rad_s2), 1)
        & np.all(torque <= np.asarray(limits.effort_n_m), 1)
    )
    return keeps if jerk is None else keeps & np.all(jerk <= np.asarray(limits.jerk_rad_s3), 1)


def _near_optimal_batch(cells: NearOptimalCells, batch: GeneratedBatch) -> ExecutionBatch:
    """The near-optimal T' and bounds of the cell of each answer of ``batch`` (NaN outside a
    certified cell or where the answer has none)."""
    points = np.column_stack([batch.lengths_m, batch.widths_m, *(batch.variables[name] for name in cells.axes[2:])])
    cell = np.where(batch.leaf >= 0, cells.cells_of(points), -1)
    rows = cells.table[np.maximum(cell, 0)]
    duration = np.where(cell >= 0, rows["duration_s"], np.nan)
    inside = np.isfinite(duration)
    b = np.where(inside[:, None], rows["bounds"], np.nan)
    angles = np.stack([np.stack([-b[:, 2], b[:, 0]], 1), np.stack([-b[:, 3], b[:, 1]], 1)], 1)
    speed, acceleration, torque, jerk = b[:, 4:6], b[:, 6:8], b[:, 8:10], b[:, 10:12]
    n = cell.size
    return ExecutionBatch(
        NEAR_OPTIMAL.name,
        cells.limits,
        duration,
        np.full(n, np.nan),
        np.full(n, np.nan),
        angles,
        speed,
        acceleration,
        torque,
        inside & _keeps(cells.limits, angles, speed, acceleration, torque, jerk),
        jerk,
    )
