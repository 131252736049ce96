"""What a build does: :class:`BuildConfig` (validated on construction, errors naming the
command-line option) and :func:`scene_from_options` (the scene from defaults, a scene file and
single options).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from pipeline.certify.certifiable_regression import DEFAULT_CLEARANCE_ROUNDS, REFIT_VARIABLES
from pipeline.certify.range_model import axes_refusal
from pipeline.exceptions import DataFileError, InvalidParameterError, PipelineError
from pipeline.io.executor import (
    DEFAULT_WORKER_TIMEOUT_S,
    DaskScheduler,
    Executor,
    LocalPool,
    check_scheduler_address,
)
from pipeline.model.arm import DEFAULT_URDF
from pipeline.model.scene import Scene, read_scene_file
from pipeline.motion.families import PAPER, TrajectoryFamily, family_from_name
from pipeline.offline.convergence import ConvergenceCriteria
from pipeline.offline.designs import DESIGN_KINDS, Factor, FullFactorial, ScaledDesign, design_class
from pipeline.offline.doe import Design
from pipeline.offline.endpoint_regression import EndpointConstraint
from pipeline.offline.experiment import SolverConfig
from pipeline.offline.fitness import FitnessConfig
from pipeline.offline.pso import PsoConfig
from pipeline.offline.variables import NAMES, SIZE, Variables, check_name

__all__ = ["OPTIONS", "SCENE_OPTIONS", "BuildConfig", "scene_from_options"]

_PSO, _FITNESS, _CRITERIA = PsoConfig(), FitnessConfig(), ConvergenceCriteria()

#: Command-line option of each :class:`BuildConfig` field, named in error messages.
OPTIONS: Mapping[str, str] = MappingProxyType(
    {
        "out_folder": "--out",
        "seed": "--seed",
        "levels": "--levels",
        "length_range_m": "--L-range",
        "width_range_m": "--W-range",
        "vary": "--vary",
        "design_kind": "--design",
        "family": "--family",
        "jobs": "--jobs",
        "scheduler": "--scheduler",
        "worker_timeout_s": "--worker-timeout",
        "urdf_path": "--urdf",
        "scene": "--scene",
        "swarm_size": "--swarm-size",
        "iterations": "--iterations",
        "restarts": "--restarts",
        "polish": "--no-polish",
        "n_points": "--n-points",
        "endpoint_weight": "--endpoint-weight",
        "penalty_weight": "--penalty-weight",
        "margin_buffer_m": "--margin-buffer",
        "endpoint_tolerance_m": "--endpoint-tolerance",
        "doe_endpoint_error_max_m": "--max-doe-endpoint-error",
        "allow_unconverged": "--allow-unconverged",
        "acceleration_limits_rad_s2": "--acceleration-limit",
        "range_map": "--no-range-map",
        "clearance_rounds": "--clearance-rounds",
        "near_optimal_cells": "--near-optimal-cells",
    }
)
#: Command-line option of each scene field that has one; the others are set by ``--scene FILE``.
SCENE_OPTIONS: Mapping[str, str] = MappingProxyType(
    {
        "top_y_m": "--top-y",
        "start_y_m": "--start-y",
        "speed_m_s": "--speed",
        "margin_m": "--margin",
        "corner_radius_m": "--corner-radius",
    }
)
# Names the sub-configurations use in their own errors -> the BuildConfig field.
_SUB_NAMES = MappingProxyType(
    {
        "L range": "length_range_m",
        "L range min": "length_range_m",
        "L range max": "length_range_m",
        "W range": "width_range_m",
        "W range min": "width_range_m",
        "W range max": "width_range_m",
        "tolerance_m": "endpoint_tolerance_m",
        "endpoint_error_max_m": "doe_endpoint_error_max_m",
        "design": "design_kind",
    }
)
#: The variables ``--vary`` takes (L and W have --L-range and --W-range).
VARY_NAMES: tuple[str, ...] = tuple(name for name in NAMES if name not in SIZE)
# Other spellings of the variables -> the name (the scene fields they set, other cases).
_ALIASES = MappingProxyType({"X": "x", "D": "d", "centre_x_m": "x", "center_x_m": "x", "top_y_m": "d"})


def _renamed(exc: InvalidParameterError, option: str) -> InvalidParameterError:
    return InvalidParameterError(option, exc.value, exc.expected)


@dataclass(frozen=True)
class BuildConfig:
    """Everything a build needs; validated on construction (errors name the command-line option).

    Attributes:
        out_folder: Where doe.json, coefficients.json, region_map.json and build_timing.json go
            (and arm.urdf for an arm other than the shipped one); created when they are
            written, not before.
        seed: Master random seed (integer >= 0); the same seed gives byte-identical doe.json,
            coefficients.json and region_map.json whatever ``jobs``.
        levels: K, levels per factor of the full-factorial design (K^k runs, >= 3); the
            response-surface designs have 3 levels (``levels`` must be 3 with them).
        length_range_m, width_range_m: (min, max) of L and W [m].
        vary: The scene variables varied beside L and W (:mod:`pipeline.offline.variables`: x,
            the obstacle's centre x, or d, its far edge y), as
            :class:`pipeline.offline.designs.Factor` objects or (name, min, max) [m]; () for the
            paper's (L, W). With any, the coefficients vary them too; the range certificate
            covers them (d only with y1 = d, ``start_y_m`` None; otherwise the build writes no
            region map), the certifiable regression's rounds only (L, W, x).
        design_kind: The design: a :class:`pipeline.offline.designs.ScaledDesign` subclass
            (:class:`~pipeline.offline.designs.FullFactorial`, the default,
            :class:`~pipeline.offline.designs.BoxBehnken`,
            :class:`~pipeline.offline.designs.CentralComposite`) or its command-line name.
        family: Trajectory family (object, or its name as on the command line).
        jobs: Worker processes (>= 1), or 0 for every CPU (the default); does not change the result.
        scheduler: Address of a Dask scheduler (``host:port`` or ``tcp://host:port``) whose
            workers run the DOE and the range map in place of the ``jobs`` local processes (see
            :mod:`pipeline.io.executor`); None: the local processes. Does not change the result.
        worker_timeout_s: With ``scheduler``: how long to wait for its first worker before any
            work [s]; none by then is refused (``NoDaskWorkersError``).
        urdf_path: URDF of the arm (None: the paper's arm shipped with the package).
        scene: The scene (obstacle placement, path, speed, margin); see :func:`scene_from_options`.
        swarm_size, iterations, restarts: PSO settings (:class:`pipeline.offline.pso.PsoConfig`).
        polish: Polish every PSO restart with least_squares.
        n_points, endpoint_weight, penalty_weight, margin_buffer_m: Objective settings
            (:class:`pipeline.offline.fitness.FitnessConfig`; margin buffer [m]).
        endpoint_tolerance_m: Endpoint tolerance of the regression [m] (paper family), or None
            for the plain least-squares fit (the paper's Eq. 9). Ignored by a family that pins
            the endpoints.
        doe_endpoint_error_max_m: Largest endpoint error of a DOE optimum for the build to
            count as converged [m] (:mod:`pipeline.offline.convergence`).
        allow_unconverged: Write the files (marked) even if the build did not converge.
        acceleration_limits_rad_s2: The arm's joint acceleration limits [rad/s^2] (URDF carries
            none), recorded in the coefficients; later certificates hold answers to them. None: none.
        range_map: Certify the coefficients over their fitted range and write region_map.json.
        near_optimal_cells: Cells per axis of the map's near-optimal timings
            (:mod:`pipeline.certify.near_optimal_cells`); None: 64 over (L, W), 16 over three axes,
            8 over four; 0: none.
        clearance_rounds: Rounds of the certifiable regression before the map (paper family
            with the endpoint constraint; 0: none).
    """

    out_folder: Path = Path("results")
    seed: int = 0
    levels: int = 3
    length_range_m: tuple[float, float] = (0.20, 0.30)
    width_range_m: tuple[float, float] = (0.08, 0.12)
    vary: tuple[Factor | tuple[str, float, float], ...] = ()
    design_kind: type[ScaledDesign] | str = FullFactorial
    family: TrajectoryFamily | str = PAPER
    jobs: int = 0
    scheduler: str | None = None
    worker_timeout_s: float = DEFAULT_WORKER_TIMEOUT_S
    urdf_path: Path = DEFAULT_URDF
    scene: Scene = field(default_factory=Scene)
    swarm_size: int = _PSO.swarm_size
    iterations: int = _PSO.iterations
    restarts: int = _PSO.restarts
    polish: bool = True
    n_points: int = _FITNESS.n_points
    endpoint_weight: float = _FITNESS.endpoint_weight
    penalty_weight: float = _FITNESS.penalty_weight
    margin_buffer_m: float = _FITNESS.margin_buffer_m
    endpoint_tolerance_m: float | None = EndpointConstraint.tolerance_m
    doe_endpoint_error_max_m: float = _CRITERIA.endpoint_error_max_m
    allow_unconverged: bool = False
    acceleration_limits_rad_s2: tuple[float, float] | None = None
    range_map: bool = True
    clearance_rounds: int = DEFAULT_CLEARANCE_ROUNDS
    near_optimal_cells: int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.out_folder, str | os.PathLike):
            raise InvalidParameterError(OPTIONS["out_folder"], self.out_folder, "a folder path")
        object.__setattr__(self, "out_folder", Path(self.out_folder))
        if self.urdf_path is None:
            object.__setattr__(self, "urdf_path", DEFAULT_URDF)
        if not isinstance(self.urdf_path, str | os.PathLike):
            raise InvalidParameterError(OPTIONS["urdf_path"], self.urdf_path, "a URDF file path")
        object.__setattr__(self, "urdf_path", Path(self.urdf_path))
        if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer) or self.seed < 0:
            raise InvalidParameterError(OPTIONS["seed"], self.seed, "an integer >= 0")
        if isinstance(self.jobs, bool) or not isinstance(self.jobs, int | np.integer) or self.jobs < 0:
            raise InvalidParameterError(OPTIONS["jobs"], self.jobs, "an integer >= 0 (0 = every CPU)")
        if self.scheduler is not None:
            check_scheduler_address(OPTIONS["scheduler"], self.scheduler)
        timeout = self.worker_timeout_s
        if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not 0.0 < timeout < math.inf:
            raise InvalidParameterError(OPTIONS["worker_timeout_s"], self.worker_timeout_s, "a finite time > 0 [s]")
        if (
            isinstance(self.clearance_rounds, bool)
            or not isinstance(self.clearance_rounds, int | np.integer)
            or self.clearance_rounds < 0
        ):
            raise InvalidParameterError(OPTIONS["clearance_rounds"], self.clearance_rounds, "an integer >= 0")
        cells = self.near_optimal_cells
        if cells is not None and (isinstance(cells, bool) or not isinstance(cells, int | np.integer) or cells < 0):
            raise InvalidParameterError(OPTIONS["near_optimal_cells"], cells, "an integer >= 0 (0: none)")
        if isinstance(self.family, str):
            try:
                object.__setattr__(self, "family", family_from_name(self.family))
            except PipelineError:
                raise InvalidParameterError(OPTIONS["family"], self.family, "a trajectory family name") from None
        if not isinstance(self.family, TrajectoryFamily):
            raise InvalidParameterError(OPTIONS["family"], self.family, "a TrajectoryFamily or its name")
        if not isinstance(self.scene, Scene):
            raise InvalidParameterError(OPTIONS["scene"], self.scene, "a pipeline.model.scene.Scene")
        if self.scene.centre_x_m != 0.0:
            raise InvalidParameterError(
                "centre_x_m",
                self.scene.centre_x_m,
                "0: the build's range certificate and the online generator place the obstacle at x = 0",
            )
        if self.acceleration_limits_rad_s2 is not None:
            try:
                limits = tuple(float(v) for v in self.acceleration_limits_rad_s2)
            except (TypeError, ValueError):
                limits = ()
            if len(limits) != 2 or not all(v > 0.0 for v in limits):
                raise InvalidParameterError(
                    OPTIONS["acceleration_limits_rad_s2"],
                    self.acceleration_limits_rad_s2,
                    "two positive limits [rad/s^2]",
                )
            object.__setattr__(self, "acceleration_limits_rad_s2", limits)
        for name in ("polish", "allow_unconverged", "range_map"):
            if not isinstance(getattr(self, name), bool):
                raise InvalidParameterError(OPTIONS[name], getattr(self, name), "True or False")
        self._check_vary()
        self._check_design_kind()
        # Build every sub-configuration once, so that a bad value fails here.
        self.design()
        self.solver()
        self.endpoint_constraint()
        self.criteria()

    @property
    def workers(self) -> int:
        """Worker processes: ``jobs``, or every CPU for 0."""
        return int(self.jobs) if self.jobs > 0 else (os.cpu_count() or 1)

    @property
    def executor(self) -> Executor:
        """Where the DOE and the range map run: the Dask scheduler, or ``workers`` local processes."""
        if self.scheduler is None:
            return LocalPool(self.workers)
        return DaskScheduler(self.scheduler, worker_timeout_s=float(self.worker_timeout_s))

    def _check_vary(self) -> None:
        """``vary`` as Factors: known names other than L and W, each once, min < max."""
        option = OPTIONS["vary"]
        if not isinstance(self.vary, tuple | list):
            raise InvalidParameterError(option, self.vary, "a sequence of (name, min, max)")
        factors = []
        for item in self.vary:
            if not isinstance(item, Factor):
                if not isinstance(item, tuple | list) or len(item) != 3:
                    raise InvalidParameterError(option, item, "NAME MIN MAX")
                name = vary_name(item[0])
                try:
                    item = Factor(name, (item[1], item[2]))
                except InvalidParameterError as exc:
                    raise InvalidParameterError(f"{option} {name}", exc.value, exc.expected) from None
            if item.name in SIZE:
                flag = OPTIONS["length_range_m" if item.name == "L" else "width_range_m"]
                raise InvalidParameterError(option, item.name, f"x or d ({item.name}'s range is {flag})")
            if item.name in (f.name for f in factors):
                raise InvalidParameterError(option, item.name, "each name once")
            factors.append(item)
        object.__setattr__(self, "vary", tuple(factors))

    def _check_design_kind(self) -> None:
        option = OPTIONS["design_kind"]
        kind = self.design_kind
        if isinstance(kind, str):
            try:
                kind = design_class(kind)
            except InvalidParameterError as exc:
                raise InvalidParameterError(option, kind, exc.expected) from None
        if not (isinstance(kind, type) and kind in DESIGN_KINDS.values()):
            raise InvalidParameterError(option, self.design_kind, f"one of {', '.join(DESIGN_KINDS)} or its class")
        object.__setattr__(self, "design_kind", kind)
        if kind is not FullFactorial and self.levels != 3:
            raise InvalidParameterError(OPTIONS["levels"], self.levels, f"3 with --design {kind.kind} (3 levels)")

    @property
    def variables(self) -> Variables:
        """The scene variables the DOE and the coefficients vary: (L, W) and ``vary``'s."""
        return Variables((*SIZE, *(f.name for f in self.vary)))

    @property
    def certifiable_axes(self) -> bool:
        """True if the range certificate covers the coefficients' variables in the build's scene
        (:func:`pipeline.certify.range_model.axes_refusal`: L, W, x and d, d only with y1 = d)."""
        return axes_refusal(self.variables, self.scene) is None

    @property
    def certifiable_refit(self) -> bool:
        """True if the build runs the certifiable regression's rounds before the map (a range
        map over certifiable axes among the regression's
        :data:`~pipeline.certify.certifiable_regression.REFIT_VARIABLES`, rounds > 0, the endpoint
        constraint, the paper family); over other axes (d) the coefficients are certified as
        regressed."""
        return bool(
            self.range_map
            and self.certifiable_axes
            and all(name in REFIT_VARIABLES for name in self.variables.names)
            and self.clearance_rounds > 0
            and self.endpoint_tolerance_m is not None
            and self.family == PAPER
        )

    @staticmethod
    def _named(build: Callable):
        """``build()``, with a sub-configuration's error renamed to the command-line option."""
        try:
            return build()
        except InvalidParameterError as exc:
            name = _SUB_NAMES.get(exc.name, exc.name)
            raise _renamed(exc, OPTIONS.get(name, name)) from None

    def design(self) -> ScaledDesign:
        """The design: over (L, W) and ``vary``'s variables, of kind ``design_kind`` (the
        default: the paper's K x K full factorial over (L, W))."""
        for name in ("length_range_m", "width_range_m"):
            value = getattr(self, name)
            if not isinstance(value, tuple | list) or len(value) != 2:
                raise InvalidParameterError(OPTIONS[name], value, "(min, max) [m]")
            object.__setattr__(self, name, tuple(value))
        size = self._named(lambda: Design(self.levels, tuple(self.length_range_m), tuple(self.width_range_m)))
        factors = (*size.full_factorial().factors, *self.vary)
        if self.design_kind is FullFactorial:
            return FullFactorial(factors, self.levels)
        return self._named(lambda: self.design_kind(factors))

    def solver(self) -> SolverConfig:
        """PSO, polish and objective settings of every experiment."""
        pso = self._named(
            lambda: PsoConfig(swarm_size=self.swarm_size, iterations=self.iterations, restarts=self.restarts)
        )
        fitness = self._named(
            lambda: FitnessConfig(
                n_points=self.n_points,
                endpoint_weight=self.endpoint_weight,
                penalty_weight=self.penalty_weight,
                margin_buffer_m=self.margin_buffer_m,
            )
        )
        return SolverConfig(family=self.family, fitness=fitness, pso=pso, polish=self.polish)

    def endpoint_constraint(self) -> EndpointConstraint | None:
        """The regression's endpoint constraint, or None (plain fit, or a family exact by construction)."""
        if self.endpoint_tolerance_m is None:
            return None
        constraint = self._named(lambda: EndpointConstraint(tolerance_m=self.endpoint_tolerance_m))
        return None if self.family.pins_endpoints else constraint

    def criteria(self) -> ConvergenceCriteria:
        """The thresholds the results must meet."""
        return self._named(lambda: ConvergenceCriteria(endpoint_error_max_m=self.doe_endpoint_error_max_m))


def vary_name(name: object) -> str:
    """A ``--vary`` name, or a one-line error naming the valid ones and the closest."""
    if name in SIZE:
        flag = OPTIONS["length_range_m" if name == "L" else "width_range_m"]
        raise InvalidParameterError(OPTIONS["vary"], name, f"one of {', '.join(VARY_NAMES)} ({name}'s range is {flag})")
    if isinstance(name, str) and name not in VARY_NAMES and name in _ALIASES:
        raise InvalidParameterError(
            OPTIONS["vary"], name, f"one of {', '.join(VARY_NAMES)} (did you mean {_ALIASES[name]!r}?)"
        )
    return check_name(name, VARY_NAMES, OPTIONS["vary"])


def scene_from_options(scene_file: str | Path | None = None, **options: float | None) -> Scene:
    """The scene of a build: the defaults, then the keys of ``scene_file`` (TOML or JSON, keys
    as :data:`pipeline.model.scene.SCENE_FIELDS`), then the ``options`` that are not None
    (scene field name -> value, e.g. ``top_y_m=0.54``). Errors name the option or the file's key.

    Raises:
        DataFileError: the scene file is unreadable or has an unknown key or a non-number.
        InvalidParameterError: a value is out of its domain.
    """
    values: dict[str, float | None] = {}
    origin: dict[str, str] = {}
    if scene_file is not None:
        try:
            values.update(read_scene_file(scene_file))
        except DataFileError as exc:
            raise DataFileError(f"--scene {exc.path}", exc.reason) from None
        origin.update({key: f"--scene {scene_file}: {key}" for key in values})
    for key, value in options.items():
        if key not in SCENE_OPTIONS:
            raise InvalidParameterError("scene option", key, f"one of {', '.join(SCENE_OPTIONS)}")
        if value is not None:
            values[key], origin[key] = value, SCENE_OPTIONS[key]
    try:
        return Scene(**values)
    except InvalidParameterError as exc:
        raise _renamed(exc, origin.get(exc.name, exc.name)) from None
