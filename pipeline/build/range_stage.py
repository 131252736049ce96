"""The build's second stage: the certifiable regression's rounds (if they apply) and the range
certificate of the final coefficients, in memory.

The coefficients are certified as they read back from their file text, so that the map links
to the sha256 of exactly the bytes the build writes (:func:`pipeline.certify.region_map.RegionMap.belongs_to`).
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, replace

from pipeline.build.config import BuildConfig
from pipeline.certify.cell_timings import near_optimal_cells
from pipeline.certify.certifiable_regression import (
    REFIT_ENDPOINT_HEADROOM,
    REFIT_MIN_CELLS,
    REFIT_POINTS_PER_ROUND,
    CertifiableFitConfig,
    refit_for_clearance,
)
from pipeline.certify.map_files import region_map_files
from pipeline.certify.map_for_coefficients import default_config, with_execution_bounds
from pipeline.certify.near_optimal_cells import cells_files
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import RegionMap
from pipeline.io.jsonio import dumps
from pipeline.io.progress import ProgressCallback
from pipeline.model.arm import PlanarArm
from pipeline.model.dynamics import identify_dynamics
from pipeline.model.limits import ArmLimits
from pipeline.offline.coefficients import Coefficients, coefficients_from_json
from pipeline.offline.doe import DoeData
from pipeline.offline.endpoint_regression import EndpointConstraint

__all__ = ["REFIT_STAGE", "CertifiedCoefficients", "as_written", "certify_coefficients"]

#: Progress stage names of the certifiable regression's rounds and of the final map.
REFIT_STAGE = "certifiable regression"


@dataclass(frozen=True, eq=False)
class CertifiedCoefficients:
    """The final coefficients with their range certificate, not yet written.

    Attributes:
        coefficients: As they read back from ``text`` (source: their file's path; sha256: of ``text``).
        text: The content of coefficients.json.
        region_map: Their range certificate; ``map_files`` its files by name (the header
            region_map.json and the leaf table region_map.npy: :mod:`pipeline.certify.map_files`;
            near_optimal_cells.json and .npy: :mod:`pipeline.certify.near_optimal_cells`).
        refit_report: The certifiable regression's rounds (None if it did not run).
        timing: The wall times [s] of its stages (``stages_s``: ``clearance_refit``, the refit's
            rounds but their last map, if they ran; ``range_certificate``, the final map;
            ``execution_bounds``, the map's bounds of the arm's motion; ``near_optimal_cells``, the
            certified near-optimal timing of each cell) and
            ``clearance_refit_rounds`` (if the refit ran).
    """

    coefficients: Coefficients
    text: str
    region_map: RegionMap
    map_files: dict[str, bytes]
    refit_report: dict | None
    timing: dict


def as_written(coefficients: Coefficients, source: str) -> tuple[Coefficients, str]:
    """``coefficients`` as they read back from their file text, and the text (``source``: the path
    they will be written to; their sha256: of the text)."""
    text = dumps(coefficients.to_json())
    digest = hashlib.sha256(text.encode("utf-8")).hexdigest()
    return coefficients_from_json(json.loads(text), source, digest), text


def _refit_endpoint(config: BuildConfig, coefficients: Coefficients) -> EndpointConstraint:
    """The refit's endpoint constraint: the first fit's grids over the coefficients' variables, with
    the refit's headroom of their number (:data:`REFIT_ENDPOINT_HEADROOM`; the largest beyond it)."""
    k = coefficients.variables.k
    headroom = REFIT_ENDPOINT_HEADROOM.get(k, max(REFIT_ENDPOINT_HEADROOM.values()))
    constraint = EndpointConstraint(tolerance_m=config.regression.endpoint_tolerance_m, headroom=headroom)
    return replace(constraint.for_variables(coefficients.variables), headroom=headroom)


def _refit_config(
    config: BuildConfig, coefficients: Coefficients, map_config: RangeCertificateConfig
) -> CertifiableFitConfig:
    """The certifiable regression's settings: its rounds but the last only pick constraint points
    (coarser cells, no extra depth, strips, cuts at the infeasibility contour or merging, the
    mean-value endpoint form, so that the coefficients do not depend on the map's endpoint form);
    the last round's certificate is the map's."""
    return CertifiableFitConfig(
        certificate=replace(
            map_config,
            min_cell=max(map_config.min_cell, REFIT_MIN_CELLS[coefficients.variables.k]),
            extra_depth=0,
            strip_split=0,
            infeasibility_cuts=0,
            clearance_cuts=0,
            merge_spread_m=0.0,
            second_order=False,
        ),
        final_certificate=map_config,
        endpoint=_refit_endpoint(config, coefficients),
        max_rounds=config.regression.clearance_rounds,
        points_per_round=REFIT_POINTS_PER_ROUND[coefficients.variables.k],
    )


def certify_coefficients(
    config: BuildConfig,
    doe: DoeData,
    coefficients: Coefficients,
    text: str,
    arm: PlanarArm,
    progress: ProgressCallback | None = None,
) -> CertifiedCoefficients:
    """Run the certifiable regression's rounds if ``config.certifiable_refit``, then certify the
    final coefficients over their fitted range, with the execution bounds of ``arm`` (its URDF
    limits and the build's acceleration limits) in every leaf.

    Args:
        config: The build's configuration.
        doe: The DOE the coefficients were regressed from.
        coefficients: The regression, as read back from ``text``.
        text: Its file content.
        arm: The arm the coefficients were fitted for.
        progress: Gets the stages of the refit's rounds (prefixed "certifiable regression round k: ";
            the last round's certificate is the final map) or of the map.
    """
    pinned = coefficients.family.pins_endpoints
    tolerance_m = config.regression.endpoint_tolerance_m
    map_config = default_config(
        coefficients,
        endpoint_tolerance_m=None if tolerance_m is None or pinned else tolerance_m,
        jobs=config.execution.workers,
        executor=config.execution.executor,
    )
    seconds: dict[str, float] = {}
    timing: dict = {"stages_s": seconds}
    report = None
    if config.certifiable_refit:
        refit = _refit_config(config, coefficients, map_config)
        started = time.perf_counter()
        stages = (
            None if progress is None else (lambda stage, done, total: progress(f"{REFIT_STAGE} {stage}", done, total))
        )
        coefficients, text, region_map, report = refit_for_clearance(
            coefficients, doe, refit, coefficients.source, stages
        )
        seconds["clearance_refit"] = time.perf_counter() - started - region_map.seconds
        timing["clearance_refit_rounds"] = report["rounds"]
        seconds["range_certificate"] = region_map.seconds
    else:
        started = time.perf_counter()
        region_map = certify_range(coefficients, map_config, progress=progress)
        seconds["range_certificate"] = time.perf_counter() - started
    started = time.perf_counter()
    limits = ArmLimits.from_arm(arm, config.acceleration_limits_rad_s2)
    dynamics = identify_dynamics(arm)
    region_map = with_execution_bounds(region_map, coefficients, dynamics, limits, map_config.run_on)
    seconds["execution_bounds"] = time.perf_counter() - started
    files = region_map_files(region_map)
    if config.range_map.near_optimal_cells != 0:
        started = time.perf_counter()
        cells = near_optimal_cells(
            coefficients,
            dynamics,
            limits.with_servo_defaults(),
            config.range_map.near_optimal_cells,
            executor=map_config.run_on,
        )
        seconds["near_optimal_cells"] = time.perf_counter() - started
        files = {**files, **cells_files(cells)}
        region_map = replace(region_map, near_optimal_cells=cells)
    return CertifiedCoefficients(coefficients, text, region_map, files, report, timing)
