"""Loading coefficients for the online step, with their range certificate attached.

:func:`load_coefficients` reads a coefficients file (:func:`pipeline.offline.coefficients.read_coefficients`)
and attaches the region map that certifies it, so that every in-range answer of
:func:`pipeline.online.generator.generate` carries its certified bounds by default. A map is
attached only if its link, the sha256 of the coefficients file it was made from, matches the
file's bytes: a map of other coefficients is never used. NumPy only: no Pinocchio, no Coal.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import replace
from pathlib import Path

from pipeline.certify.map_files import load_region_map, region_map_of
from pipeline.certify.region_map import DEFAULT_MAP_NAME, RegionMap
from pipeline.exceptions import InvalidParameterError, RegionMapMismatchError, RegionMapMismatchWarning
from pipeline.io.jsonio import read_json
from pipeline.motion.families import PAPER_SOURCE
from pipeline.offline.coefficients import Coefficients, read_coefficients

__all__ = ["BESIDE", "load_coefficients", "map_path_beside", "region_map_beside"]


class _Beside:
    """The type of :data:`BESIDE`."""

    def __repr__(self) -> str:
        return "BESIDE"


#: ``region_map=BESIDE`` (the default): the map written beside the coefficients file by the build.
BESIDE = _Beside()


def map_path_beside(coefficients: Coefficients) -> Path | None:
    """Where the build writes the region map of ``coefficients`` (``region_map.json`` beside the
    file), or None for coefficients that do not come from a file (the paper's Eq. 9)."""
    if not coefficients.source or coefficients.source == PAPER_SOURCE:
        return None
    return Path(coefficients.source).with_name(DEFAULT_MAP_NAME)


def region_map_beside(coefficients: Coefficients) -> RegionMap | None:
    """The region map beside the coefficients file if it certifies exactly these coefficients.

    None if there is no map there. A map of other coefficients (an older build's) is not
    returned: a :class:`RegionMapMismatchWarning` says so.

    Raises:
        DataFileError: the map file is unreadable or malformed.
    """
    path = map_path_beside(coefficients)
    if path is None or not path.is_file():
        return None
    document = read_json(path)
    link = document.get("coefficients") if isinstance(document, dict) else None
    if isinstance(link, dict) and link.get("sha256") != coefficients.source_sha256:
        region_map = None  # another build's: its leaves are not read
    else:
        region_map = region_map_of(document, path)
    if region_map is None or not region_map.belongs_to(coefficients):
        digest = link.get("sha256", "") if isinstance(link, dict) else ""
        warnings.warn(
            f"{path} certifies coefficients sha256 {str(digest)[:12]}, not "
            f"{coefficients.source} (sha256 {coefficients.source_sha256[:12]}): not attached; "
            "python -m pipeline.certify_range makes the map of these",
            RegionMapMismatchWarning,
            stacklevel=3,
        )
        return None
    return _with_cells_beside(region_map, path, coefficients)


def _with_cells_beside(region_map: RegionMap, map_path: Path, coefficients: Coefficients) -> RegionMap:
    """``region_map`` with the near-optimal cells written beside it, if they were made from these
    coefficients (:mod:`pipeline.certify.near_optimal_cells`, imported only where they are: it
    needs Numba). The map was just read and is not shared yet: the cells are set on it in place,
    without checking its leaves again."""
    from pipeline.certify.near_optimal_cells import CELLS_NAME, load_near_optimal_cells

    path = map_path.with_name(CELLS_NAME)
    if not path.is_file():
        return region_map
    cells = load_near_optimal_cells(path)
    if cells.coefficients_sha256 == coefficients.source_sha256:
        object.__setattr__(region_map, "near_optimal_cells", cells)
    return region_map


def load_coefficients(
    source: str | os.PathLike, *, region_map: RegionMap | str | os.PathLike | _Beside | None = BESIDE
) -> Coefficients:
    """Load a coefficients file (or the paper's Eq. 9 for ``"paper"``) with its range certificate.

    Args:
        source: Path of a ``coefficients.json``, or ``"paper"``.
        region_map: :data:`BESIDE` (default): the ``region_map.json`` beside the file, if it
            certifies these coefficients; a path or a :class:`RegionMap`: that map, which must
            certify them; None: no map (answers carry no certified bounds).

    Returns:
        The coefficients; ``coefficients.region_map`` is the attached map or None.

    Warns:
        RegionMapMismatchWarning: the map beside the file certifies other coefficients (not attached).
        UnconvergedCoefficientsWarning: the file was written by a build that did not converge.

    Raises:
        InvalidParameterError: ``source`` or ``region_map`` is not one of the types above.
        DataFileError: a file is missing, unreadable or malformed.
        RegionMapMismatchError: the map named by ``region_map`` certifies other coefficients.
    """
    coefficients = read_coefficients(source)
    if region_map is BESIDE:
        attached = region_map_beside(coefficients)
    elif region_map is None:
        attached = None
    elif isinstance(region_map, RegionMap):
        attached = region_map
    elif isinstance(region_map, str | os.PathLike) and not isinstance(region_map, bytes):
        attached = load_region_map(region_map)
    else:
        raise InvalidParameterError("region_map", region_map, "BESIDE, a region map file path, a RegionMap, or None")
    if attached is not None and not attached.belongs_to(coefficients):
        raise RegionMapMismatchError(attached.coefficients_sha256, coefficients.source_sha256)
    return coefficients if attached is None else replace(coefficients, region_map=attached)
