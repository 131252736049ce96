"""The whole build as one call: :func:`run_build` (:class:`pipeline.build.config.BuildConfig`) ->
:class:`BuildResult`. ``python -m pipeline.build`` parses its options into a ``BuildConfig``,
calls this and prints the result.

DOE and regression (:mod:`pipeline.build.doe_fit`) -> certifiable regression and range map
(:mod:`pipeline.build.range_stage`) -> the files, written as one set at the end
(:func:`pipeline.io.file_set.write_file_set`): ``doe.json``, ``coefficients.json``,
``region_map.json`` (linked to the coefficients by their sha256), ``build_timing.json``, and
``arm.urdf`` for an arm other than the shipped one. A build stopped at any point (an error,
Ctrl-C, a termination signal a command turned into an exception) leaves its output folder as it
found it. The first three are deterministic for a seed (no timestamps) whatever the number of
worker processes; the timing varies run to run (``build_timing.json``: the total wall time and
each stage's, which add up to it).

The output folder's parent must exist (a mistyped parent is refused, not created). While the
build runs it holds the folder's lock (:mod:`pipeline.io.folder_lock`): a second build into the
same folder is refused before any work.

Where the certifiable regression runs, its coefficients are the ones written, and the sampled
check that the regressed trajectories do not collide (:mod:`pipeline.offline.convergence`) runs
on them, after it: the first fit may cross an obstacle where an end pose is close to it, and the
refit's clearance constraints move it off.

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
from types import MappingProxyType

from pipeline.build.config import OPTIONS, BuildConfig
from pipeline.build.doe_fit import DoeFit, fit_doe, grid_collisions
from pipeline.build.range_stage import as_written, certify_coefficients
from pipeline.certify.map_files import table_name
from pipeline.certify.near_optimal_cells import cells_file_names
from pipeline.certify.range_model import axes_refusal
from pipeline.certify.region_map import DEFAULT_MAP_NAME, RegionMap
from pipeline.exceptions import BuildNotConvergedError
from pipeline.io.executor import check_executor
from pipeline.io.file_set import Content, WrittenFile, write_file_set
from pipeline.io.folder_lock import build_lock
from pipeline.io.jsonio import dumps
from pipeline.io.output_paths import check_output_folder
from pipeline.io.progress import ProgressCallback
from pipeline.model.arm import ARM_FILE_NAME, load_planar_arm
from pipeline.offline.coefficients import Coefficients
from pipeline.offline.convergence import ConvergenceProblem
from pipeline.offline.experiment import ExperimentResult

__all__ = ["COEFFICIENTS_NAME", "DOE_NAME", "STAGE_NAMES", "TIMING_NAME", "BuildResult", "run_build", "stage_summary"]

#: File names of the build's output set.
DOE_NAME, COEFFICIENTS_NAME, TIMING_NAME = "doe.json", "coefficients.json", "build_timing.json"
#: The stages of build_timing.json's ``stages_s``, in build order, with their names in words.
STAGE_NAMES = MappingProxyType(
    {
        "checks": "checks",
        "doe": "DOE",
        "regression": "regression",
        "clearance_refit": "certifiable regression",
        "range_certificate": "range certificate",
        "execution_bounds": "execution bounds",
        "near_optimal_cells": "near-optimal cells",
        "writing": "writing",
        "other": "other",
    }
)
#: The stage that holds what the others leave of the total.
OTHER_STAGE = "other"


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
        timing: The build_timing.json document: ``total_s``, the wall time [s] from the start of
            :func:`run_build` to the files staged on disk (only their renames into place, a few
            milliseconds, come after), and ``stages_s``, the wall time [s] of each stage
            (:data:`STAGE_NAMES`, those that ran; ``other`` the rest), which add up to it.
        region_map: The range certificate of the coefficients (None without one: ``range_map``
            off, or the build did not converge).
        refit_report: The certifiable regression's rounds (None if they did not run).
        written: The files written, each with whether it replaced a file (empty if nothing was written).
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
    written: tuple[WrittenFile, ...] = ()

    @property
    def converged(self) -> bool:
        """True if every DOE optimum and the regression met the thresholds."""
        return not self.problems

    @property
    def range_map_skipped(self) -> str | None:
        """Why the build wrote no region map though ``range_map`` asked for one, or None."""
        if not self.config.range_map.enabled or self.region_map is not None:
            return None
        refusal = axes_refusal(self.config.variables, self.config.scene)
        if refusal is not None:
            names = ", ".join(self.config.variables.names)
            return f"the range certificate takes {refusal}, and these coefficients vary {names}"
        return "the build did not converge"


def _unwritten(
    config: BuildConfig,
    fit: DoeFit,
    timing: dict,
    coefficients: Coefficients | None = None,
    problems: tuple[ConvergenceProblem, ...] | None = None,
) -> BuildResult:
    """The result of a build that writes nothing: ``fit``'s, or the ``coefficients`` and
    ``problems`` it came to after the certifiable regression."""
    return BuildResult(
        config,
        fit.experiments,
        fit.doe_document,
        fit.paper_rows,
        fit.coefficients if coefficients is None else coefficients,
        fit.problems if problems is None else problems,
        timing,
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
        InfeasibleSceneError: bad configuration, output folder (one whose parent does not exist
            included) or URDF, an obstacle the arm cannot pass or whose end pose collides (all
            before any work; nothing written or created).
        OutputLockedError: another build is writing ``config.out_folder`` (before any work).
        BuildNotConvergedError: the results missed the thresholds and ``allow_unconverged``
            is False (nothing written; ``exc.result`` holds the unwritten result).
        SchedulerUnreachableError: ``scheduler`` cannot be reached (before any work; nothing written).
        WorkerPoolError: the worker processes stopped (e.g. a script without a ``__main__`` guard).
    """
    started = time.perf_counter()
    check_output_folder(config.out_folder, OPTIONS["out_folder"], new_parents=False)
    with build_lock(config.out_folder):
        return _locked_build(config, progress, started)


def _locked_build(config: BuildConfig, progress: ProgressCallback | None, started: float) -> BuildResult:
    """:func:`run_build` once the output folder is locked; ``started``: its start [s, perf_counter]."""
    check_executor(config.execution.executor)
    arm = load_planar_arm(config.urdf_path)
    fit = fit_doe(config, arm, progress)
    timing = {"total_s": 0.0, **fit.timing, "stages_s": dict(fit.timing["stages_s"])}
    if fit.problems and not config.regression.allow_unconverged:
        _close_timing(timing, started)
        raise BuildNotConvergedError(fit.problems, _unwritten(config, fit, timing))

    coefficients, text = as_written(fit.coefficients, str(config.out_folder / COEFFICIENTS_NAME))
    certified = None
    if config.range_map.enabled and not fit.problems and config.certifiable_axes:
        certified = certify_coefficients(config, fit.doe, coefficients, text, arm, progress)
        coefficients, text = certified.coefficients, certified.text
        timing["stages_s"].update(certified.timing["stages_s"])
        timing.update({k: v for k, v in certified.timing.items() if k != "stages_s"})
    collisions = _written_collisions(fit, coefficients, timing)
    problems = fit.problems + collisions
    if collisions:  # the certifiable regression's coefficients collide
        if not config.regression.allow_unconverged:
            _close_timing(timing, started)
            raise BuildNotConvergedError(problems, _unwritten(config, fit, timing, coefficients, problems))
        coefficients, text = as_written(coefficients.marked_unconverged(problems), coefficients.source)
        certified = None
    writing = time.perf_counter()

    def timing_text() -> str:  # called once the other files are staged: the writing is timed too
        timing["stages_s"]["writing"] = time.perf_counter() - writing
        _close_timing(timing, started)
        return dumps(timing)

    files: dict[str, Content] = {
        DOE_NAME: fit.doe_text,
        COEFFICIENTS_NAME: text,
        # A map of earlier coefficients must not stay beside these.
        **dict.fromkeys((table_name(DEFAULT_MAP_NAME), DEFAULT_MAP_NAME, *cells_file_names())),
        **({} if certified is None else certified.map_files),
        TIMING_NAME: timing_text,
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
        problems,
        timing,
        None if certified is None else certified.region_map,
        None if certified is None else certified.refit_report,
        written,
    )


def _written_collisions(fit: DoeFit, coefficients: Coefficients, timing: dict) -> tuple[ConvergenceProblem, ...]:
    """The sampled collision check that waited for the certifiable regression (``fit.collision_grid``),
    on the coefficients it gave; its time is added to the ``checks`` stage."""
    if not fit.collision_grid:
        return ()
    started = time.perf_counter()
    problems = tuple(grid_collisions(coefficients, fit.collision_grid))
    timing["stages_s"]["checks"] += time.perf_counter() - started
    return problems


def _close_timing(timing: dict, started: float) -> None:
    """Set ``timing["total_s"]``, the wall time since ``started`` [s], and the stage ``other``:
    what the named stages leave of it, so that the stages add up to the total."""
    timing["total_s"] = time.perf_counter() - started
    stages = timing["stages_s"]
    stages.pop(OTHER_STAGE, None)
    stages[OTHER_STAGE] = max(0.0, timing["total_s"] - sum(stages.values()))


def stage_summary(timing: dict) -> str:
    """The stages of a build_timing.json document in words, in build order: ``DOE 22.1 s,
    regression 0.2 s, ...`` (names as :data:`STAGE_NAMES`; any other stage under its key)."""
    stages = timing.get("stages_s") or {}
    order = [name for name in STAGE_NAMES if name in stages] + [name for name in stages if name not in STAGE_NAMES]
    return ", ".join(f"{STAGE_NAMES.get(name, name)} {float(stages[name]):.1f} s" for name in order)
