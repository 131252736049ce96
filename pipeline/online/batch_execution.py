"""Execution bounds of many answers at once, read off the region map (NumPy only, no arm needed).

For a :class:`pipeline.online.batch.GeneratedBatch` generated with the map, each answer's leaf
gives the bounds proven for every obstacle of the leaf (:mod:`pipeline.certify.execution_bounds`):
with the paper timing its angle range and its speed, acceleration and torque bounds; with the
rest-to-rest timing (c, r), the duration T' = T / c + r of the answer's own T, and that timing's
bounds. The bounds hold for the arm the map was built with (``ExecutionBatch.limits``); the
answers for another arm are certified per query (:func:`pipeline.generate_certified`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import InvalidParameterError
from pipeline.model.limits import ArmLimits
from pipeline.motion.near_optimal import NearOptimal
from pipeline.motion.rest_to_rest import ShortestRestToRest
from pipeline.motion.timing import PAPER_TIMING, PaperTiming
from pipeline.offline.coefficients import Coefficients
from pipeline.online.batch import GeneratedBatch
from pipeline.online.generator import ATTACHED, _Attached, check_region_map

__all__ = ["ExecutionBatch", "execution_batch"]


@dataclass(frozen=True, eq=False)
class ExecutionBatch:
    """The map's execution bounds of n answers (NaN where an answer has none: an error, outside
    the fitted range, or a leaf without a rest-to-rest timing).

    Attributes:
        timing_name: "paper" or "rest-to-rest".
        limits: The limits of the arm the map was built with.
        duration_s: T' [s], (n,).
        speed_scale, ramp_s: The rest-to-rest timing's c and r [s], (n,) (1 and inf for the paper timing).
        angle_range_rad: (n, 2, 2) per joint (lo, hi) [rad].
        speed_bound_rad_s, acceleration_bound_rad_s2, torque_bound_n_m: (n, 2) bounds of |dq|
            [rad/s], |ddq| [rad/s^2], |tau| [N m].
        within_limits: (n,) True where every bound keeps ``limits`` (the answer is certified to
            execute; its clearance and endpoints are the batch's own bounds).
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


def _checked_inputs(coefficients: Coefficients, batch, timing, region_map):
    """The map's execution bounds, after every check of :func:`execution_batch`'s arguments."""
    if region_map is ATTACHED:
        region_map = coefficients.region_map
    if region_map is None:
        raise InvalidParameterError("region_map", None, "a region map (python -m pipeline.build writes one)")
    check_region_map(region_map, coefficients)
    if region_map.execution is None:
        raise InvalidParameterError(
            "region_map", "without execution bounds", "a map with them (python -m pipeline.certify_range adds them)"
        )
    if not isinstance(batch, GeneratedBatch) or batch.leaf is None:
        raise InvalidParameterError("batch", type(batch).__name__, "a GeneratedBatch made with the region map")
    if isinstance(timing, NearOptimal):
        raise InvalidParameterError(
            "timing",
            timing.name,
            "PAPER_TIMING or REST_TO_REST: the map holds no near-optimal profile; "
            "generate_certified(..., timing=NEAR_OPTIMAL) certifies it per query",
        )
    if not isinstance(timing, PaperTiming | ShortestRestToRest):
        raise InvalidParameterError("timing", type(timing).__name__, "PAPER_TIMING or REST_TO_REST")
    return region_map.execution


def execution_batch(
    coefficients: Coefficients,
    batch: GeneratedBatch,
    timing: PaperTiming | ShortestRestToRest = PAPER_TIMING,
    *,
    region_map: RegionMap | _Attached = ATTACHED,
) -> ExecutionBatch:
    """The execution bounds of ``batch``'s answers from ``region_map``'s leaves (module docstring).

    Args:
        coefficients: The coefficients of the batch.
        batch: From :func:`pipeline.generate_batch` with the same map.
        timing: ``PAPER_TIMING`` or ``REST_TO_REST``.
        region_map: The map (default: the one attached to the coefficients).

    Raises:
        InvalidParameterError: no map, a map without execution bounds, a batch generated without
            the map, or an unknown timing.
        RegionMapMismatchError: the map certifies other coefficients.
    """
    bounds = _checked_inputs(coefficients, batch, timing, region_map)
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
    position = np.asarray(limits.position_rad)
    keeps = (
        inside
        & np.isfinite(duration)
        & np.all(angles[:, :, 0] >= position[:, 0], 1)
        & np.all(angles[:, :, 1] <= position[:, 1], 1)
        & np.all(speed <= np.asarray(limits.velocity_rad_s), 1)
        & np.all(acceleration <= np.asarray(limits.acceleration_rad_s2), 1)
        & np.all(torque <= np.asarray(limits.effort_n_m), 1)
    )
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
