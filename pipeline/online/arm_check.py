"""The arm of a coefficients file, and the check that coefficients are used with the arm they were
fitted for.

The build records the arm's URDF in the coefficients' provenance (``urdf``: its file name,
``urdf_sha256``: the sha256 of its bytes). The paper's arm is shipped with the package; any other
URDF is copied beside ``coefficients.json`` (as ``arm.urdf``) by the build, so the arm travels with
the coefficients: :func:`arm_for` finds it there and checks it by its sha256. An arm given
explicitly (``--urdf``) overrides it after :func:`check_arm_matches`.
"""

from __future__ import annotations

import math
from pathlib import Path

from pipeline.exceptions import ArmMismatchError, DataFileError, InvalidParameterError
from pipeline.io.provenance import sha256_file
from pipeline.model.arm import ARM_FILE_NAME, DEFAULT_URDF, PlanarArm, load_planar_arm
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
    if not isinstance(arm, PlanarArm):
        raise InvalidParameterError("arm", type(arm).__name__, "a PlanarArm from pipeline.load_planar_arm(), or None")
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


def recorded_urdf(coefficients: Coefficients) -> Path:
    """The URDF the coefficients were fitted with: the shipped arm's, or the copy beside the file.

    Coefficients without a record (the paper's Eq. 9, a plain regression of a DOE file) assume
    the shipped arm.

    Raises:
        DataFileError: the recorded URDF is neither the shipped one nor beside the coefficients
            with the recorded sha256.
    """
    provenance = coefficients.provenance
    digest = provenance.get("urdf_sha256")
    if not digest or digest == sha256_file(DEFAULT_URDF):
        return DEFAULT_URDF
    name = str(provenance.get("urdf") or ARM_FILE_NAME)
    beside = Path(coefficients.source).with_name(Path(name).name) if coefficients.source else None
    if beside is not None and beside.is_file() and sha256_file(beside) == digest:
        return beside
    raise DataFileError(
        coefficients.source,
        f"fitted for the arm {name} (sha256 {digest[:12]}), which is not beside it"
        + ("" if beside is None or not beside.is_file() else " (the file there has another sha256)")
        + ": pass its URDF (--urdf FILE, or arm=load_planar_arm(FILE))",
    )


def arm_for(coefficients: Coefficients, urdf: str | Path | None = None) -> PlanarArm:
    """The arm to use with ``coefficients``: :func:`recorded_urdf`'s, or ``urdf`` if given
    (checked with :func:`check_arm_matches`), loaded from its URDF on each call (the queries of one
    coefficients object share one: ``pipeline.online.query_state.QueryState.arm``).

    Raises:
        DataFileError: no ``urdf`` given and the recorded URDF is missing or changed.
        RobotModelError: the URDF cannot be loaded.
        ArmMismatchError: the arm of ``urdf`` differs from the coefficients'.
    """
    if urdf is not None:
        arm = load_planar_arm(urdf)
        check_arm_matches(coefficients, arm)
        return arm
    arm = load_planar_arm(recorded_urdf(coefficients))
    check_arm_matches(coefficients, arm)
    return arm
