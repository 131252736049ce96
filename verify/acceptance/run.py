"""Running a sweep: measure every case (in this process or in worker processes, same results
either way), then summarise and record where the numbers came from.

:func:`run_sweep` judges one coefficients set on n seeded cases: each trajectory is generated as
an online user would (:func:`pipeline.online.generator.generate`) and measured by
:func:`verify.acceptance.metrics.measure_cases`, :data:`MEASURE_BATCH` cases at a time.
"""

from __future__ import annotations

import datetime
import functools
import math
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from pipeline import load_coefficients
from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.geometry.link_reach import LinkReach
from pipeline.io.jsonio import json_safe
from pipeline.io.parallel import process_map
from pipeline.io.progress import progress_enabled
from pipeline.io.provenance import package_versions, sha256_file
from pipeline.model.arm import PlanarArm, load_planar_arm
from pipeline.model.obstacle import Obstacle
from pipeline.motion.families import PAPER_SOURCE
from pipeline.offline.coefficients import Coefficients
from pipeline.online.arm_check import arm_for
from pipeline.online.execution import dynamics_of
from pipeline.validation import check_non_negative, check_positive_int

from .cases import SweepRange, case_study_sizes, sample_cases
from .metrics import MeasureSettings, SweepCase, check_arm_matches, measure_cases
from .range_check import RangeCheck, check_range
from .results import CaseResult
from .summary import SweepSummary, summarize

DEFAULT_CASES = 1000
DEFAULT_SEED = 0


def source_label(source: str) -> str:
    """Short name of a coefficients source: the paper's name, or the file's stem."""
    return PAPER_SOURCE if source == PAPER_SOURCE else Path(source).stem


def resolve_jobs(jobs: int) -> int:
    """Number of worker processes: ``jobs``, or every usable CPU if 0."""
    check_positive_int("jobs", jobs, minimum=0)
    if jobs == 0:
        try:
            return len(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - not Linux
            return os.cpu_count() or 1
    return jobs


@dataclass(frozen=True)
class _WorkerContext:
    """What a worker process needs to measure cases (picklable); it loads the rest once."""

    source: str
    sha256: str
    urdf_path: str
    settings: MeasureSettings


def load_unchanged(source: str, sha256: str) -> Coefficients:
    """The coefficients at ``source`` if their sha256 is still ``sha256`` (what a worker process
    loads for the sweep that started it), without a region map (a worker measures cases, it
    reads no bounds).

    Raises:
        DataFileError: the file changed since the sweep read it.
    """
    coefficients = load_coefficients(source, region_map=None)
    if coefficients.source_sha256 != sha256:
        raise DataFileError(source, "changed while the sweep was running (sha256 differs)")
    return coefficients


@functools.lru_cache(maxsize=4)
def _loaded(source: str, sha256: str, urdf_path: str) -> tuple[Coefficients, PlanarArm, LinkReach]:
    arm = load_planar_arm(urdf_path)  # the main process's arm, already checked against the coefficients
    return load_unchanged(source, sha256), arm, LinkReach.from_arm(arm)


def arm_for_sweep(coefficients: Coefficients, urdf_path: str | Path | None = None) -> PlanarArm:
    """The arm to measure ``coefficients`` with: the one recorded with them
    (:func:`pipeline.online.arm_check.arm_for`), or the URDF ``urdf_path`` if given, which must
    match them.

    Raises:
        InvalidParameterError: the arm of ``urdf_path`` is not the coefficients' (named ``--urdf``).
        DataFileError: the recorded arm's URDF is missing or changed.
    """
    if urdf_path is None:
        return arm_for(coefficients)
    arm = load_planar_arm(urdf_path)
    check_arm_matches(coefficients, arm)
    return arm


#: Most cases per chunk of work sent to a worker process (progress is reported per chunk).
MAX_CHUNK_CASES = 16
#: Cases measured together (:func:`verify.acceptance.metrics.measure_cases`: their sampled checks
#: vectorised over them): consecutive blocks of the cases, the same whatever the number of worker
#: processes (so the results do not depend on it), each one unit of work and of progress.
MEASURE_BATCH = 16


def chunk_size(n_cases: int, jobs: int) -> int:
    """Cases per chunk for ``jobs`` worker processes: about 64 chunks per process, at most
    :data:`MAX_CHUNK_CASES` cases each (so that the progress bar advances smoothly; the results
    do not depend on it)."""
    return max(1, min(MAX_CHUNK_CASES, math.ceil(n_cases / (64 * jobs))))


def _measure_in_worker(context: _WorkerContext, batch: list[SweepCase]) -> list[CaseResult]:
    coefficients, arm, reach = _loaded(context.source, context.sha256, context.urdf_path)
    return measure_cases(coefficients, batch, arm, context.settings, reach=reach)


def case_columns(coefficients: Coefficients) -> tuple[str, ...]:
    """The columns of a cases array for ``coefficients``: L, W, then their extra variables."""
    return coefficients.variables.names


def run_cases(
    source: str,
    cases_m: np.ndarray,
    settings: MeasureSettings,
    *,
    jobs: int = 1,
    urdf_path: str | None = None,
    progress: bool = False,
    label: str = "",
    coefficients: Coefficients | None = None,
    arm: PlanarArm | None = None,
    region_map: RegionMap | None = None,
) -> tuple[CaseResult, ...]:
    """Measure every case of ``cases_m`` (shape (n, k) [m]: L, W, then the coefficients' extra
    variables, :func:`case_columns`); results in case order.

    The cases are measured in consecutive blocks of :data:`MEASURE_BATCH`
    (:func:`verify.acceptance.metrics.measure_cases`), the same blocks whatever ``jobs``, so the
    results do not depend on it (:func:`pipeline.io.parallel.process_map`). ``jobs`` > 1 uses
    that many worker processes; each loads the coefficients and the arm (from its URDF file)
    itself and checks the coefficients' hash.

    The region map the cases will be checked against (``region_map``, else the one attached to
    ``coefficients``), if it belongs to them and bounds the torques of this arm, gives each case
    its leaf's torque bound (:func:`torque_ceilings`): the sampled torques are refined where they
    come near it.

    Args:
        source: Coefficients file, or the paper's name.
        cases_m: Cases, shape (n, k) [m] (k = 2 for (L, W) coefficients).
        settings: Measurement settings.
        jobs: Worker processes (0: every CPU; 1: in this process).
        urdf_path: URDF of the arm (default: the one recorded with the coefficients; ignored if
            ``arm`` is given).
        progress: Show a tqdm progress bar on stderr (only if it is a terminal).
        label: Progress-bar label.
        coefficients, arm: Already loaded objects (optional); ``arm`` must be the coefficients'.
        region_map: The region map the cases will be checked against (default: the one attached
            to ``coefficients``, if any).
    """
    jobs = resolve_jobs(jobs)
    coefficients = coefficients if coefficients is not None else load_coefficients(source, region_map=None)
    columns = case_columns(coefficients)
    cases = _cases_array(cases_m, columns)
    arm = arm if arm is not None else arm_for_sweep(coefficients, urdf_path)
    extra = columns[2:]
    ceilings = torque_ceilings(region_map or coefficients.region_map, coefficients, arm, cases)
    indexed = [
        SweepCase(
            i,
            float(row[0]),
            float(row[1]),
            tuple(zip(extra, (float(v) for v in row[2:]), strict=True)),
            None if ceilings is None or not np.all(np.isfinite(ceilings[i])) else _pair(ceilings[i]),
        )
        for i, row in enumerate(cases)
    ]
    batches = [indexed[k : k + MEASURE_BATCH] for k in range(0, len(indexed), MEASURE_BATCH)]
    if jobs == 1:
        reach = LinkReach.from_arm(arm)

        def function(batch: list[SweepCase]) -> list[CaseResult]:
            return measure_cases(coefficients, batch, arm, settings, reach=reach)

    else:
        context = _WorkerContext(source, coefficients.source_sha256, str(arm.urdf_path), settings)
        function = functools.partial(_measure_in_worker, context)
    shown = progress_enabled(progress)
    with tqdm(total=len(indexed), desc=label or "cases", unit="case", file=sys.stderr, disable=not shown) as bar:
        measured = process_map(
            function,
            batches,
            jobs=jobs,
            chunk_size=1,
            on_done=lambda done: bar.update(sum(len(batch) for batch in done)),
        )
    results = [result for batch in measured for result in batch]
    return tuple(results)


def _pair(values: Any) -> tuple[float, float]:
    a, b = (float(v) for v in values)
    return a, b


def torque_ceilings(
    region_map: RegionMap | None, coefficients: Coefficients, arm: PlanarArm, cases: np.ndarray
) -> np.ndarray | None:
    """Per case of ``cases`` ((n, k) [m], columns :func:`case_columns`), the paper timing's torque
    bound (n, 2) [N m] of the map's leaf holding it (inf outside the map), or None when there is
    no map, it belongs to other coefficients, has no execution bounds, bounds another arm's
    torques, or lacks one of its axes among the cases' columns (the cases are then checked
    against no torque bound of a map: :mod:`verify.acceptance.range_check`)."""
    if region_map is None or region_map.execution is None or not region_map.belongs_to(coefficients):
        return None
    if region_map.execution.dynamics != dynamics_of(arm):
        return None
    columns = case_columns(coefficients)
    if any(name not in columns for name in region_map.axes[2:]):
        return None
    extra = [cases[:, columns.index(name)] for name in region_map.axes[2:]]
    leaf = region_map.cells_at(cases[:, 0], cases[:, 1], *extra)["leaf"]
    out = np.full((cases.shape[0], 2), np.inf)
    inside = leaf >= 0
    out[inside] = region_map.execution.paper_torque_n_m[leaf[inside]]
    return out


def _cases_array(cases_m: np.ndarray, columns: Sequence[str]) -> np.ndarray:
    """``cases_m`` as an (n, k) float array, one column per variable of ``columns``.

    Raises:
        InvalidParameterError: the cases do not have one value per variable.
    """
    cases = np.asarray(cases_m, dtype=float)
    k = len(columns)
    if cases.ndim == 1 and cases.size % k == 0:
        cases = cases.reshape(-1, k)
    if cases.ndim != 2 or cases.shape[1] != k:
        raise InvalidParameterError(
            "cases", list(cases.shape), f"shape (n, {k}): one column per variable ({', '.join(columns)})"
        )
    return cases


@dataclass(frozen=True)
class SweepRun:
    """One coefficients set judged on one set of cases.

    Attributes:
        label: Short name (the paper's name, or the file's stem).
        source: The coefficients source as given.
        cases: One result per sampled case, in case order.
        case_studies: The four case studies (index 0..3, their own list).
        summary: :func:`verify.acceptance.summary.summarize` of ``cases``.
        provenance: Coefficients hash, seed, range, settings, package versions.
        sweep_range: The sampled range.
        fitted_range: The coefficients' fitted range.
        elapsed_s: Wall time of the sweep [s].
        jobs: Worker processes used.
        settings: How the cases were measured.
        range_check: The cases against the coefficients' region map (None: no map was given).
    """

    label: str
    source: str
    cases: tuple[CaseResult, ...]
    case_studies: tuple[CaseResult, ...]
    summary: SweepSummary
    provenance: dict[str, Any]
    sweep_range: SweepRange
    fitted_range: SweepRange
    elapsed_s: float
    jobs: int
    settings: MeasureSettings = field(default_factory=MeasureSettings)
    range_check: RangeCheck | None = None

    def __post_init__(self) -> None:
        check_non_negative("elapsed_s", self.elapsed_s)

    @property
    def passed(self) -> bool:
        """True if every case passed and no case contradicts the region map."""
        return self.summary.all_passed and (self.range_check is None or self.range_check.passed)

    @property
    def extrapolating(self) -> bool:
        """True if the sampled range leaves the fitted range."""
        return not self.fitted_range.contains(self.sweep_range)

    def to_json(self) -> dict[str, Any]:
        """{"cases": [...], "summary": {...}, "provenance": {...}, "case_studies": [...], "timing": {...},
        "region_map": {...} or None, "passed": bool}."""
        return json_safe(
            {
                "label": self.label,
                "cases": [c.to_json() for c in self.cases],
                "summary": self.summary.to_json(),
                "case_studies": [c.to_json() for c in self.case_studies],
                "provenance": self.provenance,
                "timing": {
                    "elapsed_s": self.elapsed_s,
                    "cases_per_s": len(self.cases) / self.elapsed_s if self.elapsed_s > 0 else None,
                    "jobs": self.jobs,
                },
                "region_map": None if self.range_check is None else self.range_check.to_json(),
                "passed": self.passed,
            }
        )


def run_sweep(
    source: str,
    *,
    n: int = DEFAULT_CASES,
    seed: int = DEFAULT_SEED,
    sweep_range: SweepRange | None = None,
    settings: MeasureSettings | None = None,
    jobs: int = 1,
    urdf_path: str | None = None,
    progress: bool = False,
    label: str | None = None,
    cases_m: np.ndarray | None = None,
    case_studies: bool = True,
    argv: Sequence[str] | None = None,
    coefficients: Coefficients | None = None,
    arm: PlanarArm | None = None,
    region_map: RegionMap | None = None,
    region_map_path: str | None = None,
) -> SweepRun:
    """Judge one coefficients set on n seeded cases (or the given ``cases_m``), sampled over
    every variable of the coefficients (L, W and, e.g., the obstacle's centre x), and, if a
    region map is given, cross-check the cases against it
    (:func:`verify.acceptance.range_check.check_range`: a contradiction fails the run).

    Args:
        source: Coefficients file or the paper's name.
        n: Number of cases (ignored if ``cases_m`` is given).
        seed: Seed of the case sampler.
        sweep_range: Sampled range, over the coefficients' variables; default their fitted range.
        settings: Measurement settings; default :class:`MeasureSettings`.
        jobs: Worker processes (0: every CPU).
        urdf_path: URDF of the arm; default the one recorded with the coefficients (it must
            match them; ignored if ``arm`` is given).
        progress: Show a progress bar on stderr (only if it is a terminal).
        label: Name of the run; default :func:`source_label`.
        cases_m: Explicit cases (n, k) [m] instead of sampling (``seed`` is then only recorded):
            L, W, then the coefficients' extra variables.
        case_studies: Also measure the four case studies.
        argv: Command line to record in the provenance.
        coefficients: ``source`` already loaded (optional).
        arm: The arm already loaded (optional; checked against the coefficients).
        region_map: The range certificate to check (optional; one of other coefficients is
            reported as not belonging and not checked).
        region_map_path: Its file, for the report.

    Raises:
        PipelineError: bad coefficients, range or settings, or coefficients fitted for another arm.
    """
    settings = settings or MeasureSettings()
    coefficients = coefficients if coefficients is not None else load_coefficients(source, region_map=None)
    fitted, chosen = _sweep_ranges(coefficients, sweep_range)
    variables = coefficients.variables
    cases = sample_cases(chosen, n, seed) if cases_m is None else _cases_array(cases_m, variables.names)
    arm = _sweep_arm(coefficients, arm, urdf_path, chosen)
    plan = _SweepPlan(source, label or source_label(source), coefficients, arm, settings, fitted, chosen)
    start = time.perf_counter()
    results = plan.measure(cases, jobs, progress, region_map)
    elapsed = time.perf_counter() - start
    studies = measure_case_studies(coefficients, arm, settings, fitted) if case_studies else ()
    provenance = plan.provenance(seed, len(results), cases_m is not None, sweep_range is None, argv)
    return plan.sweep_run(results, studies, provenance, (elapsed, jobs), (region_map, region_map_path))


def _sweep_ranges(coefficients: Coefficients, sweep_range: SweepRange | None) -> tuple[SweepRange, SweepRange]:
    """The coefficients' fitted range and the range to sample (``sweep_range``, default the fitted one).

    Raises:
        InvalidParameterError: a sweep range over other variables than the coefficients'.
    """
    variables = coefficients.variables
    fitted = SweepRange.from_fitted(coefficients.fitted_range_m, variables.names)
    chosen = sweep_range or fitted
    if chosen.names != variables.names:
        wanted = ", ".join(variables.names)
        raise InvalidParameterError("sweep range", list(chosen.names), f"a range over the variables {wanted}")
    return fitted, chosen


def _sweep_arm(
    coefficients: Coefficients, arm: PlanarArm | None, urdf_path: str | None, chosen: SweepRange
) -> PlanarArm:
    """The sweep's arm (``arm``, checked against the coefficients, or the one of ``urdf_path`` or of
    the coefficients' record); the obstacles at the low and the high corner of ``chosen`` built
    first, so that impossible sizes fail early.

    Raises:
        PipelineError: coefficients fitted for another arm, or an impossible obstacle.
    """
    if arm is None:
        arm = arm_for_sweep(coefficients, urdf_path)
    else:
        check_arm_matches(coefficients, arm)
    variables = coefficients.variables
    for corner in zip(*chosen.ranges_m, strict=True):  # the low and the high corner
        scene = variables.scene_for(coefficients.scene, dict(zip(variables.extra, corner[2:], strict=True)))
        Obstacle.in_scene(corner[0], corner[1], scene)  # fails early on impossible sizes
    return arm


@dataclass(frozen=True)
class _SweepPlan:
    """What one sweep judges, checked before any case is measured.

    Attributes:
        source: Coefficients file or the paper's name.
        label: Name of the run.
        coefficients: The coefficients.
        arm: The arm (checked against the coefficients).
        settings: Measurement settings.
        fitted: The coefficients' fitted range.
        chosen: The sampled range.
    """

    source: str
    label: str
    coefficients: Coefficients
    arm: PlanarArm
    settings: MeasureSettings
    fitted: SweepRange
    chosen: SweepRange

    def measure(
        self, cases: np.ndarray, jobs: int, progress: bool, region_map: RegionMap | None
    ) -> tuple[CaseResult, ...]:
        """:func:`run_cases` on ``cases`` (n, k) [m] with ``jobs`` worker processes."""
        return run_cases(
            self.source,
            cases,
            self.settings,
            jobs=jobs,
            progress=progress,
            label=self.label,
            coefficients=self.coefficients,
            arm=self.arm,
            region_map=region_map,
        )

    def provenance(
        self, seed: int, n_cases: int, cases_given: bool, range_is_fitted: bool, argv: Sequence[str] | None
    ) -> dict[str, Any]:
        """:func:`_provenance` with what only :func:`run_sweep` knows: whether the cases were given
        and the range is the fitted one, and the command line."""
        provenance = _provenance(
            self.source,
            self.coefficients,
            self.chosen,
            self.fitted,
            self.settings,
            seed=seed,
            n_cases=n_cases,
            arm=self.arm,
        )
        provenance.update(
            cases_given_explicitly=cases_given,
            range_is_fitted_range=range_is_fitted,
            command=list(argv) if argv is not None else None,
        )
        return provenance

    def sweep_run(
        self,
        results: tuple[CaseResult, ...],
        studies: tuple[CaseResult, ...],
        provenance: dict[str, Any],
        timing: tuple[float, int],
        region: tuple[RegionMap | None, str | None],
    ) -> SweepRun:
        """The :class:`SweepRun` of the measured ``results`` and case ``studies``.

        Args:
            timing: The measuring's wall time [s] and the ``jobs`` asked for.
            region: The region map to cross-check the cases against (or None) and its file.
        """
        elapsed, jobs = timing
        region_map, region_map_path = region
        return SweepRun(
            label=self.label,
            source=self.source,
            cases=results,
            case_studies=studies,
            summary=summarize(results, self.settings.thresholds),
            provenance=json_safe(provenance),
            sweep_range=self.chosen,
            fitted_range=self.fitted,
            elapsed_s=elapsed,
            jobs=resolve_jobs(jobs),
            settings=self.settings,
            range_check=(
                None
                if region_map is None
                else check_range(
                    region_map,
                    self.coefficients,
                    results,
                    self.settings,
                    path=region_map_path,
                    dynamics=dynamics_of(self.arm),
                )
            ),
        )


def measure_case_studies(
    coefficients: Coefficients, arm: PlanarArm, settings: MeasureSettings, fitted: SweepRange
) -> tuple[CaseResult, ...]:
    """The four case studies of :func:`verify.acceptance.cases.case_study_sizes`, measured (index
    0..3); each extra variable of ``fitted`` (e.g. the obstacle's centre x) at its range's midpoint."""
    reach = LinkReach.from_arm(arm)
    extra = tuple((name, 0.5 * (lo + hi)) for name, (lo, hi) in fitted.extra_m)
    cases = [SweepCase(i, length, width, extra) for i, (length, width) in enumerate(case_study_sizes(fitted))]
    return tuple(measure_cases(coefficients, cases, arm, settings, reach=reach))


def _provenance(
    source: str,
    coefficients: Coefficients,
    chosen: SweepRange,
    fitted: SweepRange,
    settings: MeasureSettings,
    *,
    seed: int,
    n_cases: int,
    arm: PlanarArm,
) -> dict[str, Any]:
    """Where a sweep's numbers came from: coefficients (hash, family, range), seed, range, settings,
    URDF (hash), scene, package versions and the time; the caller adds what only it knows."""
    urdf = Path(arm.urdf_path)
    return {
        "coefficients": {
            "source": source,
            "path": None if source == PAPER_SOURCE else str(Path(source).resolve()),
            "sha256": coefficients.source_sha256,
            "family": coefficients.family.name,
            "fitted_range_m": fitted.to_dict(),
            "provenance": coefficients.provenance,
        },
        "seed": seed,
        "cases_given_explicitly": None,
        "n_cases": n_cases,
        "range_m": chosen.to_dict(),
        "range_is_fitted_range": None,
        "extrapolating": not fitted.contains(chosen),
        "settings": settings.to_dict(),
        "urdf": {"path": str(urdf), "sha256": sha256_file(urdf)},
        "scene": coefficients.scene.to_dict(),
        "packages": package_versions(),
        "command": None,
        "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
