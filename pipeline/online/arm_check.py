"""One arm check for the online layer: coefficients are only used with the arm they were fitted for."""

from __future__ import annotations

import math

from pipeline.exceptions import ArmMismatchError
from pipeline.model.arm import PlanarArm
from pipeline.offline.coefficients import Coefficients

#: Largest difference [m] between the coefficients' and the arm's link lengths or radii.
ARM_TOLERANCE_M = 1e-9


def check_arm_matches(coefficients: Coefficients, arm: PlanarArm, tolerance_m: float = ARM_TOLERANCE_M) -> None:
    """Refuse an arm whose link lengths or radii differ from those the coefficients were fitted for.

    Args:
        coefficients: The coefficients (their ``link_lengths_m`` and ``link_radii_m`` [m]).
        arm: The arm (read from its URDF).
        tolerance_m: Largest accepted difference [m].

    Raises:
        ArmMismatchError: a length or a radius differs by more than ``tolerance_m`` (a NaN radius,
            a link that is not a capsule, always differs); the message names both arms.
    """
    pairs = zip(
        (*coefficients.link_lengths_m, *coefficients.link_radii_m),
        (*arm.link_lengths_m, *arm.link_radii_m),
        strict=True,
    )
    if all(math.isfinite(float(b)) and abs(float(a) - float(b)) <= tolerance_m for a, b in pairs):
        return
    raise ArmMismatchError(
        tuple(float(v) for v in coefficients.link_lengths_m),
        tuple(float(v) for v in coefficients.link_radii_m),
        tuple(float(v) for v in arm.link_lengths_m),
        tuple(float(v) for v in arm.link_radii_m),
        arm.urdf_path,
    )
