"""The benchmark's rows over the obstacle's pose: coefficients that also vary its centre x, or
its centre x and far edge d.

**(a*) over (L, W, x)** (or (L, W, x, d)) times ``generate(coefficients, L, W, x=x, region_map=m)``
(``d=d`` too) one query at a time, side by side with (a) and (a*)
(:mod:`verify.benchmark.per_query`), on random values uniform in the coefficients' fitted box
(seeded; its (L, W) columns are drawn as the bench's (L, W) obstacles are), with the map that the
build wrote beside them: the answer carries the certified clearance and endpoint bounds of the
leaf holding the query. **(d) over (L, W, x)** and **(d+)** run OMPL's RRT-Connect
(:mod:`verify.benchmark.ompl_planner`) on the same moved obstacles: each query plans around
``Obstacle.in_scene(L, W, scene)`` in the answer's moved scene (its ``obstacle``, centred at x,
its far edge at d), from the IK of that scene's P1 to that of P5.

The coefficients come from ``--coefficients-x FILE``, else ``results-x/coefficients.json`` if it
exists; else the rows are left out, with the command that makes them.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pipeline import load_coefficients
from pipeline.certify.region_map import DEFAULT_MAP_NAME
from pipeline.exceptions import DataFileError
from pipeline.model.arm import PlanarArm
from pipeline.model.scene import Scene
from pipeline.offline.coefficients import Coefficients
from pipeline.online.loading import map_path_beside
from verify.acceptance.metrics import check_arm_matches

from . import ompl_planner as planner
from .methods import bench_ompl, range_counts
from .per_query import PerQueryRow
from .results import DEFAULT_COEFFICIENTS_X, MAKE_COEFFICIENTS_X, BenchSettings, MethodResult

#: The variable sets the rows take (the coefficients' own).
AXES_TAKEN = (("L", "W", "x"), ("L", "W", "x", "d"))
#: Key of the row, also of its entry in the report's ``skipped``.
KEY = "a_range_x"


def row_name(coefficients: Coefficients) -> str:
    """How the table names the row of ``coefficients``: "(a*) over (L, W, x)" or "(a*) over (L, W, x, d)"."""
    return f"(a*) over ({', '.join(coefficients.variables.names)})"


def coefficients_x_path(settings: BenchSettings) -> Path | None:
    """The coefficients file of the rows: ``settings.coefficients_x``, else ``DEFAULT_COEFFICIENTS_X``
    if it exists, else None."""
    if settings.coefficients_x is not None:
        return Path(settings.coefficients_x)
    default = Path(DEFAULT_COEFFICIENTS_X)
    return default if default.is_file() else None


def missing_reason(settings: BenchSettings) -> str:
    """Why the rows are left out (``coefficients_x_path`` gave None, or ``--no-x``), with the remedy."""
    if not settings.run_x:
        return "--no-x"
    return f"no {DEFAULT_COEFFICIENTS_X} and no --coefficients-x (make it with: {MAKE_COEFFICIENTS_X})"


def load_coefficients_x(path: Path, arm: PlanarArm) -> Coefficients:
    """The coefficients over (L, W, x) at ``path`` with the region map beside them, for ``arm``.

    Raises:
        DataFileError: the file is missing or malformed, its coefficients do not vary (L, W, x),
            or no map beside it certifies them.
        InvalidParameterError: they were fitted for another arm.
    """
    coefficients = load_coefficients(path)
    if tuple(coefficients.variables.names) not in AXES_TAKEN:
        taken = " or ".join(f"({', '.join(axes)})" for axes in AXES_TAKEN)
        raise DataFileError(
            path,
            f"--coefficients-x must vary {taken}, these vary {', '.join(coefficients.variables.names)} "
            f"({MAKE_COEFFICIENTS_X})",
        )
    if coefficients.region_map is None:
        beside = map_path_beside(coefficients) or Path(DEFAULT_MAP_NAME)
        raise DataFileError(
            path, f"no {beside} certifying these coefficients (python -m pipeline.certify_range {path} makes it)"
        )
    check_arm_matches(coefficients, arm)
    return coefficients


def sample_cases_x(coefficients: Coefficients, n: int, seed: int) -> np.ndarray:
    """n obstacles [m], uniform in the coefficients' fitted box, shape (n, k): a column per
    variable, L and W drawn first as :func:`verify.acceptance.cases.sample_cases` draws them (the
    same (L, W) for the same fitted (L, W) range), then x (and d), from
    ``numpy.random.default_rng(seed)``."""
    rng = np.random.default_rng(seed)
    columns = [rng.uniform(*coefficients.fitted_range_m[name], n) for name in coefficients.variables.names]
    return np.stack(columns, -1)


def moved_scene(coefficients: Coefficients, case: np.ndarray, answer: Any) -> Scene:
    """The scene of the obstacle ``case`` (the coefficients' variables [m]): the answer's (its
    obstacle moved), or the coefficients' scene moved where the generator refused (None)."""
    if answer is not None:
        return answer.scene
    extra = coefficients.variables.extra
    return coefficients.variables.scene_for(coefficients.scene, dict(zip(extra, map(float, case[2:]), strict=True)))


def x_methods(
    timed: PerQueryRow,
    arm: PlanarArm,
    settings: BenchSettings,
    *,
    log: Callable[[str], None] = lambda _: None,
    skipped: dict[str, str],
    ompl_margin_m: float | None = None,
) -> tuple[list[MethodResult], dict[str, Any]]:
    """(a*) over (L, W, x) from its ``timed`` row, then OMPL (d) and (d+) on the same moved obstacles if it runs.

    Args:
        timed: The row of (a*) over (L, W, x), timed side by side with (a) and (a*)
            (:mod:`verify.benchmark.per_query`): coefficients over (L, W, x) with their region map
            attached (:func:`load_coefficients_x`) on :func:`sample_cases_x`'s obstacles.
        ompl_margin_m: Validity margin of OMPL [m] (None: the coefficients' scene margin).
        skipped: Why OMPL's rows over (L, W, x) were left out goes here (key "d_x").

    Returns:
        (the rows, the report's ``over_x``: coefficients, map and obstacles).
    """
    methods = [_generator_row(timed, settings)]
    if not settings.run_ompl:
        skipped["d_x"] = "--no-ompl"
    elif not planner.ompl_available():
        skipped["d_x"] = "ompl is not installed (pip install ompl, or the project's 'bench' extra)"
    else:
        log(f"timing (d) OMPL RRT-Connect on the same moved obstacles ({settings.ompl_time_s} s budget per query) ...")
        try:
            methods.extend(_ompl_rows(timed, arm, settings, ompl_margin_m))
        except ImportError as exc:
            skipped["d_x"] = f"ompl could not be imported ({exc})"
    return methods, _over_x_report(timed)


def _generator_row(timed: PerQueryRow, settings: BenchSettings) -> MethodResult:
    """The row (a*) over (L, W, x): the generator with the region map, each call timed [s], and how many
    in-range queries it answered with a certified clearance > 0 and >= the margin."""
    coefficients, cases, answers = timed.coefficients, timed.cases, timed.answers
    counts = range_counts(answers, coefficients.scene.margin_m)
    answered = [a for a in answers if a is not None]
    names = ", ".join(coefficients.variables.names)
    keywords = ", ".join(f"{name}={name}" for name in coefficients.variables.extra)
    return MethodResult(
        key=KEY,
        label=f"{row_name(coefficients)}: generator + map",
        obstacles=len(cases),
        times_s=tuple(timed.times_s),
        queries=len(cases),
        answered=len(answered),
        certified=counts.certified,
        keeps_margin=counts.keeps_margin,
        note=f"generate(coefficients_x, L, W, {keywords}, region_map=m), each call timed, on random ({names}) in the "
        f"fitted box; passes: {settings.repeats}, interleaved with (a)'s and (a*)'s; {counts.certified} of "
        f"{counts.in_range} in-range queries answered with a certified clearance > 0, {counts.keeps_margin} >= "
        "the margin",
        extra={"in_range_queries": counts.in_range, "certified_clearance_min_m": counts.clearance_min_m},
    )


def _ompl_rows(
    timed: PerQueryRow, arm: PlanarArm, settings: BenchSettings, ompl_margin_m: float | None
) -> list[MethodResult]:
    """(d) and (d+) over (L, W, x): OMPL RRT-Connect, then our certificate of its path, on the row's
    moved obstacles, valid at ``ompl_margin_m`` [m] (None: the scene margin).

    Raises:
        ImportError: ompl could not be imported.
    """
    coefficients, cases, answers = timed.coefficients, timed.cases, timed.answers
    margin = coefficients.scene.margin_m
    validity = margin if ompl_margin_m is None else ompl_margin_m
    scenes = [moved_scene(coefficients, case, answer) for case, answer in zip(cases, answers, strict=True)]
    simplify = " + simplify" if settings.ompl_simplify else ""
    names = ", ".join(coefficients.variables.names)
    return bench_ompl(
        coefficients,
        cases,
        arm,
        settings,
        validity,
        margin,
        scenes=scenes,
        rows=(
            ("d_x", f"(d) over ({names}): OMPL RRT-Connect{simplify}"),
            ("d_x_cert", f"(d+) over ({names}): + our certificate"),
        ),
    )


def _over_x_report(timed: PerQueryRow) -> dict[str, Any]:
    """The report's ``over_x``: the coefficients over (L, W, x), their region map and the obstacles
    (cases [m], and the centre x [m] of each answered one)."""
    coefficients, cases = timed.coefficients, timed.cases
    answered = [a for a in timed.answers if a is not None]
    summary = timed.region_map.summary()
    return {
        "source": coefficients.source,
        "sha256": coefficients.source_sha256,
        "fitted_range_m": {k: list(v) for k, v in coefficients.fitted_range_m.items()},
        "region_map": {
            "path": None if map_path_beside(coefficients) is None else str(map_path_beside(coefficients)),
            "cells": summary["cells"],
            "certified_collision_free_fraction": summary["certified_collision_free_fraction"],
            "clearance_bound_min_m": summary["clearance_bound_min_m"],
        },
        "cases_m": [[float(v) for v in case] for case in cases],
        "obstacle_centre_x_m": [float(a.obstacle.centre_x_m) for a in answered],
        "obstacle_top_y_m": [float(a.obstacle.top_y_m) for a in answered],
    }


def timed_load(path: Path, arm: PlanarArm, log: Callable[[str], None]) -> Coefficients:
    """:func:`load_coefficients_x`, logged with its wall time (a fine map over (L, W, x) is tens of MB)."""
    log(f"loading the coefficients over the obstacle's pose and their region map: {path} ...")
    started = time.perf_counter()
    coefficients = load_coefficients_x(path, arm)
    log(f"  loaded in {time.perf_counter() - started:.1f} s")
    return coefficients
