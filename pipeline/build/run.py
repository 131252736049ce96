"""The whole build as one call: :func:`run_build` (:class:`pipeline.build.config.BuildConfig`) ->
:class:`BuildResult`. ``python -m pipeline.build`` parses its options into a ``BuildConfig``,
calls this and prints the result.

DOE and regression (:mod:`pipeline.build.doe_fit`) -> certifiable regression and range map
(:mod:`pipeline.build.range_stage`) -> the files, written as one set at the end
(:func:`pipeline.io.file_set.write_file_set`): ``doe.json``, ``coefficients.json``,
``region_map.json`` (linked to the coefficients by their sha256), ``build_timing.json``, and
``arm.urdf`` for an arm other than the shipped one. A build stopped at any point (an error,
Ctrl-C) leaves its output folder as it found it. The first three are deterministic for a seed
(no timestamps) whatever the number of worker processes; the timing varies run to run.

A build whose results miss the convergence thresholds writes nothing and raises
:class:`pipeline.exceptions.BuildNotConvergedError`, unless ``allow_unconverged``: then the
DOE and coefficients are written, marked (``"converged": false`` and the reasons), without a
region map, and :func:`pipeline.load_coefficients` warns whenever such a file is loaded.

A build that varies a scene variable the range certificate does not cover in its scene
(``BuildConfig.vary``; it covers L, W, the obstacle's centre x and its far edge d, d only with
y1 = d: :func:`pipeline.certify.range_model.axes_refusal`) writes no region map either
(:attr:`BuildResult.range_map_skipped` says why a map is missing).

Worker processes (``jobs`` other than 1) start with ``spawn`` and re-import the main script: a
script that calls :func:`run_build` must do so under ``if __name__ == "__main__":``; without it
the pool breaks and the call raises :class:`pipeline.exceptions.WorkerPoolError` saying so. With
a ``scheduler``, the workers of that Dask cluster do the work instead
(:mod:`pipeline.io.executor`); the connection is checked before any work.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

from pipeline.build.config import OPTIONS, BuildConfig
from pipeline.build.doe_fit import DoeFit, fit_doe
from pipeline.build.range_stage import as_written, certify_coefficients
from pipeline.certify.range_model import axes_refusal
from pipeline.certify.region_map import DEFAULT_MAP_NAME, RegionMap
from pipeline.exceptions import BuildNotConvergedError
from pipeline.io.executor import check_executor
from pipeline.io.file_set import write_file_set
from pipeline.io.jsonio import dumps
from pipeline.io.output_paths import check_output_folder
from pipeline.io.progress import ProgressCallback
from pipeline.model.arm import ARM_FILE_NAME, load_planar_arm
from pipeline.offline.coefficients import Coefficients
from pipeline.offline.convergence import ConvergenceProblem
from pipeline.offline.experiment import ExperimentResult

__all__ = ["COEFFICIENTS_NAME", "DOE_NAME", "TIMING_NAME", "BuildResult", "run_build"]

#: File names of the build's output set.
DOE_NAME, COEFFICIENTS_NAME, TIMING_NAME = "doe.json", "coefficients.json", "build_timing.json"


@dataclass(frozen=True, eq=False)
class BuildResult:
    """What a build produced.

    Attributes:
        config: The configuration it ran.
        experiments: The DOE optima in Table 1 order.
        doe_document: The doe.json document.
        paper_rows: The paper's Table 2 scored on our fitness (None unless the design and scene are the paper's).
        coefficients: The final coefficients as written (after the certifiable regression, if it
            ran), with their region map attached (``coefficients.region_map``).
        problems: What missed the convergence thresholds (empty: converged).
        timing: The build_timing.json document.
        region_map: The range certificate of the coefficients (None without one: ``range_map``
            off, or the build did not converge).
        refit_report: The certifiable regression's rounds (None if they did not run).
        written: Paths written, each with whether it replaced a file (empty if nothing was written).
    """

    config: BuildConfig
    experiments: tuple[ExperimentResult, ...]
    doe_document: dict
    paper_rows: list[dict] | None
    coefficients: Coefficients
    problems: tuple[ConvergenceProblem, ...]
    timing: dict
    region_map: RegionMap | None = None
    refit_report: dict | None = None
    written: tuple[tuple[Path, bool], ...] = ()

    @property
    def converged(self) -> bool:
        """True if every DOE optimum and the regression met the thresholds."""
        return not self.problems

    @property
    def range_map_skipped(self) -> str | None:
        """Why the build wrote no region map though ``range_map`` asked for one, or None."""
        if not self.config.range_map or self.region_map is not None:
            return None
        refusal = axes_refusal(self.config.variables, self.config.scene)
        if refusal is not None:
            names = ", ".join(self.config.variables.names)
            return f"the range certificate takes {refusal}, and these coefficients vary {names}"
        return "the build did not converge"


def _unwritten(config: BuildConfig, fit: DoeFit, timing: dict) -> BuildResult:
    return BuildResult(
        config, fit.experiments, fit.doe_document, fit.paper_rows, fit.coefficients, fit.problems, timing
    )


def run_build(config: BuildConfig, progress: ProgressCallback | None = None) -> BuildResult:
    """Run the build: DOE, regression, certifiable regression, range map, then the files.

    Args:
        config: What to build.
        progress: ``progress(stage, done, total)`` as each stage advances
            (:class:`pipeline.io.progress.ProgressBars` draws it).

    Returns:
        The result, with the files written (``result.written``).

    Raises:
        InvalidParameterError, DataFileError, RobotModelError, UnreachableObstacleError,
        InfeasibleSceneError: bad configuration, output folder or URDF, an obstacle the arm
            cannot pass or whose end pose collides (all before any work; nothing written or created).
        BuildNotConvergedError: the results missed the thresholds and ``allow_unconverged``
            is False (nothing written; ``exc.result`` holds the unwritten result).
        SchedulerUnreachableError: ``scheduler`` cannot be reached (before any work; nothing written).
        WorkerPoolError: the worker processes stopped (e.g. a script without a ``__main__`` guard).
    """
    started = time.perf_counter()
    check_output_folder(config.out_folder, OPTIONS["out_folder"])
    check_executor(config.executor)
    arm = load_planar_arm(config.urdf_path)
    fit = fit_doe(config, arm, progress)
    timing = dict(fit.timing)
    timing["total_s"] = time.perf_counter() - started
    if fit.problems and not config.allow_unconverged:
        raise BuildNotConvergedError(fit.problems, _unwritten(config, fit, timing))

    coefficients, text = as_written(fit.coefficients, str(config.out_folder / COEFFICIENTS_NAME))
    certified = None
    if config.range_map and not fit.problems and config.certifiable_axes:
        certified = certify_coefficients(config, fit.doe, coefficients, text, arm, progress)
        coefficients, text = certified.coefficients, certified.text
        timing.update(certified.timing)
        timing["total_with_range_certificate_s"] = (
            timing["total_s"]
            + certified.timing["range_certificate_s"]
            + certified.timing.get("clearance_refit_s", 0.0)
            + certified.timing["execution_bounds_s"]
        )
    files: dict[str, str | bytes | None] = {
        DOE_NAME: fit.doe_text,
        COEFFICIENTS_NAME: text,
        # A map of earlier coefficients must not stay beside these.
        DEFAULT_MAP_NAME: None if certified is None else certified.map_text,
        TIMING_NAME: dumps(timing),
    }
    if coefficients.provenance.get("urdf") == ARM_FILE_NAME:
        files[ARM_FILE_NAME] = arm.urdf_path.read_bytes()
    written = write_file_set(config.out_folder, files)
    if certified is not None:
        coefficients = replace(coefficients, region_map=certified.region_map)
    return BuildResult(
        config,
        fit.experiments,
        fit.doe_document,
        fit.paper_rows,
        coefficients,
        fit.problems,
        timing,
        None if certified is None else certified.region_map,
        None if certified is None else certified.refit_report,
        written,
    )
