"""What the verify command lines (``verify.sweep``, ``verify.online_sweep``, ``verify.bench``,
``verify.view``) share beyond :mod:`pipeline.cli`: the coefficients loaded with or without the
region map beside them, and the arm recorded with them, with errors named after the option.
"""

from __future__ import annotations

import dataclasses
import sys
import warnings
from pathlib import Path

from pipeline.cli import arm_for_cli, load_coefficients_for_cli
from pipeline.exceptions import ArmMismatchError, DataFileError, InvalidParameterError, RegionMapMismatchWarning
from pipeline.model.arm import PlanarArm
from pipeline.motion.families import PAPER_SOURCE
from pipeline.offline.coefficients import Coefficients
from pipeline.online.loading import load_coefficients, region_map_beside


def load_coefficients_for_verify(
    prog: str, source: str, *, beside: bool = True, malformed_hint: str | None = None
) -> Coefficients:
    """:func:`pipeline.cli.load_coefficients_for_cli`, with the region map beside the file only if
    ``beside``.

    With ``beside``, the map the build wrote beside the coefficients is attached
    (``coefficients.region_map``) if it certifies them; one of other coefficients is not
    attached, and the warning that says so is printed as one line, ``prog: warning: ...``, on
    stderr. Without, the file beside them is not read (the command names its own map, or none).

    Args:
        prog: The command, for the warning.
        source: Coefficients file, or the paper's name.
        beside: Attach the map beside the file.
        malformed_hint: Appended to the error for a malformed map beside the file (how to go on
            without it, e.g. "--no-region-map skips it").

    Raises:
        DataFileError: the coefficients file is missing or malformed, or (``beside``) the map
            beside it is.
    """
    if source != PAPER_SOURCE and not Path(source).is_file():
        load_coefficients_for_cli(source)  # raises DataFileError, with the build's hint
    coefficients = load_coefficients(source, region_map=None)
    if not beside:
        return coefficients
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RegionMapMismatchWarning)
        try:
            region_map = region_map_beside(coefficients)
        except DataFileError as exc:  # found, not asked for: say how to go on without it
            if malformed_hint is None:
                raise
            raise DataFileError(exc.path, f"{exc.reason}; {malformed_hint}") from None
    for warning in caught:
        print(f"{prog}: warning: {' '.join(str(warning.message).split())}", file=sys.stderr, flush=True)
    return coefficients if region_map is None else dataclasses.replace(coefficients, region_map=region_map)


def arm_for_verify(coefficients: Coefficients, urdf: str | Path | None) -> PlanarArm:
    """:func:`pipeline.cli.arm_for_cli`: the arm recorded with ``coefficients``, or the ``--urdf``
    given, checked against them.

    Raises:
        InvalidParameterError: the ``--urdf`` arm is not the one the coefficients were fitted
            for (named ``--urdf``, with both arms' link lengths and radii).
        DataFileError: the recorded arm's URDF is missing or changed.
        RobotModelError: the URDF cannot be loaded.
    """
    try:
        return arm_for_cli(coefficients, urdf)
    except ArmMismatchError as exc:
        raise InvalidParameterError(
            "--urdf", str(exc.arm_source), f"the arm the coefficients were fitted for ({exc})"
        ) from None
