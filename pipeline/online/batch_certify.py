"""Certify many generated trajectories at once: the adaptive certificate (Coal) of each answer of a
:class:`pipeline.online.batch.GeneratedBatch`, returned as arrays (for sweeps)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL, ClearanceRoute
from pipeline.geometry.motion_certificate import DEFAULT_TOLERANCE_M
from pipeline.geometry.sinusoid_certificate import certify_trajectory
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.offline.coefficients import Coefficients
from pipeline.online.arm_check import check_arm_matches
from pipeline.online.batch import GeneratedBatch
from pipeline.online.query_state import state_of


@dataclass(frozen=True, eq=False)
class CertifiedBatch:
    """The adaptive certificate of n trajectories (NaN / 0 where the batch had no answer).

    Attributes:
        certified_clearance_m: Rigorous lower bounds over [0, T] [m], shape (n,).
        sampled_clearance_m: Minimum over the initial samples [m], shape (n,).
        evaluations: Clearance evaluations (configurations) per trajectory, shape (n,).
        decide_above_m: The decide-mode threshold used [m], or None (tolerance mode).
    """

    certified_clearance_m: np.ndarray
    sampled_clearance_m: np.ndarray
    evaluations: np.ndarray
    decide_above_m: float | None


def certify_batch(
    coefficients: Coefficients,
    batch: GeneratedBatch,
    arm: PlanarArm | None = None,
    *,
    route: ClearanceRoute = COAL,
    decide_above_m: float | None = None,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
) -> CertifiedBatch:
    """Certify every answer of ``batch`` (the adaptive route of
    :func:`pipeline.geometry.sinusoid_certificate.certify`), after one arm check.

    Args:
        coefficients: The coefficients of the batch (their scene, moved by the batch's values of
            the extra variables such as x, places the obstacles).
        batch: From :func:`generate_batch`.
        arm: The arm the coefficients were fitted for (None: the arm recorded with them, :func:`arm_for`).
        route: Clearance route (Coal, canonical).
        decide_above_m: Only decide whether each clearance exceeds this [m] (fastest). A bound above
            it also certifies the case collision-free; a case at or below it (where refinement
            stopped at the first sample below the threshold) is certified again deciding 0, so that
            ``certified_clearance_m > 0`` always answers "collision-free?" and ``> decide_above_m``
            "keeps the margin?". None: tolerance mode (bounds within ``tolerance_m`` of the sampled
            minimum; several times slower).
        tolerance_m: Tolerance of the bound [m].

    Raises:
        InvalidParameterError: ``batch`` is not a :class:`GeneratedBatch` (e.g. arrays of L and W:
            generate them first with :func:`pipeline.generate_batch`).
        ArmMismatchError: the arm differs from the coefficients'.
    """
    if not isinstance(batch, GeneratedBatch):
        raise InvalidParameterError(
            "batch", type(batch).__name__, "a GeneratedBatch from pipeline.generate_batch(coefficients, L, W)"
        )
    if arm is None:
        arm = state_of(coefficients).arm
    check_arm_matches(coefficients, arm)
    n = batch.lengths_m.size
    certified, sampled, evaluations = np.full(n, np.nan), np.full(n, np.nan), np.zeros(n, dtype=int)
    scene = coefficients.scene
    for i in range(n):
        if batch.error[i] is not None:
            continue
        values = {name: float(v[i]) for name, v in batch.variables.items()}
        moved = coefficients.variables.scene_for(scene, values) if values else scene
        obstacle = Obstacle.in_scene(float(batch.lengths_m[i]), float(batch.widths_m[i]), moved)
        certificate = certify_trajectory(
            batch.trajectory(i), arm, obstacle, route=route, decide_above_m=decide_above_m, tolerance_m=tolerance_m
        )
        evaluations[i] = certificate.evaluations
        if decide_above_m is not None and decide_above_m > 0.0 and certificate.certified_clearance_m <= decide_above_m:
            certificate = certify_trajectory(
                batch.trajectory(i), arm, obstacle, route=route, decide_above_m=0.0, tolerance_m=tolerance_m
            )
            evaluations[i] += certificate.evaluations
        certified[i] = certificate.certified_clearance_m
        sampled[i] = certificate.sampled_clearance_m
    return CertifiedBatch(certified, sampled, evaluations, decide_above_m)
