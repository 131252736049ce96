"""What a build does: :class:`BuildConfig`, validated on construction with errors naming the
command-line option, and its sections, one frozen dataclass per concept:

* :class:`DesignSettings` (``design``): the design of experiments (levels, ranges, varied
  variables, design kind);
* :class:`OptimiserSettings` (``optimiser``): the PSO per experiment and its objective;
* :class:`RegressionSettings` (``regression``): the regression's endpoint tolerance, the
  convergence thresholds and the certifiable regression's rounds;
* :class:`RangeMapSettings` (``range_map``): the range certificate and its near-optimal cells;
* :class:`ExecutionSettings` (``execution``): where the work runs (local processes or Dask).

Every setting has a name (:data:`pipeline.build.options.OPTIONS`) by which
:meth:`BuildConfig.from_settings` and :meth:`BuildConfig.with_settings` place it in its section,
so that ``BuildConfig.from_settings(jobs=1, clearance_rounds=0)`` and
``BuildConfig(execution=ExecutionSettings(jobs=1), regression=RegressionSettings(clearance_rounds=0))``
are the same configuration.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from pipeline.build.options import (
    OPTIONS,
    SCENE_OPTIONS,
    SETTINGS,
    VARY_NAMES,
    scene_from_options,
    vary_item,
    vary_name,
)
from pipeline.certify.certifiable_regression import DEFAULT_CLEARANCE_ROUNDS, REFIT_VARIABLES
from pipeline.certify.range_model import axes_refusal
from pipeline.exceptions import InvalidParameterError, PipelineError
from pipeline.io.executor import (
    DEFAULT_WORKER_TIMEOUT_S,
    DaskScheduler,
    Executor,
    LocalPool,
    check_scheduler_address,
)
from pipeline.model.arm import DEFAULT_URDF
from pipeline.model.scene import Scene
from pipeline.motion.families import PAPER, TrajectoryFamily, family_from_name
from pipeline.offline.convergence import ConvergenceCriteria
from pipeline.offline.designs import DESIGN_KINDS, Factor, FullFactorial, ScaledDesign, design_class
from pipeline.offline.doe import Design
from pipeline.offline.endpoint_regression import EndpointConstraint
from pipeline.offline.experiment import SolverConfig
from pipeline.offline.fitness import FitnessConfig
from pipeline.offline.pso import PsoConfig
from pipeline.offline.variables import SIZE, Variables

__all__ = [
    "OPTIONS",
    "SCENE_OPTIONS",
    "SECTIONS",
    "VARY_NAMES",
    "BuildConfig",
    "DesignSettings",
    "ExecutionSettings",
    "OptimiserSettings",
    "RangeMapSettings",
    "RegressionSettings",
    "scene_from_options",
    "vary_item",
    "vary_name",
]

_PSO, _FITNESS, _CRITERIA = PsoConfig(), FitnessConfig(), ConvergenceCriteria()

# Names the sub-configurations use in their own errors -> the setting.
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


def _named(build: Callable[[], Any]) -> Any:
    """``build()``, with a sub-configuration's error renamed to the command-line option."""
    try:
        return build()
    except InvalidParameterError as exc:
        name = _SUB_NAMES.get(exc.name, exc.name)
        raise InvalidParameterError(OPTIONS.get(name, name), exc.value, exc.expected) from None


def _is_count(value: object) -> bool:
    """True for an integer >= 0 (a bool is not one)."""
    return not isinstance(value, bool) and isinstance(value, int | np.integer) and value >= 0


def _check_switches(settings: object, *names: str) -> None:
    """Each of ``names`` (settings of ``settings``' section) is True or False."""
    option_of = {option.attribute: option.flag for option in SETTINGS.values()}
    for name in names:
        if not isinstance(getattr(settings, name), bool):
            raise InvalidParameterError(option_of[name], getattr(settings, name), "True or False")


@dataclass(frozen=True)
class DesignSettings:
    """The design of experiments; validated on construction.

    Attributes:
        levels: K, levels per factor of the full-factorial design (K^k runs, >= 3); the
            response-surface designs have 3 levels (``levels`` must be 3 with them).
        length_range_m, width_range_m: (min, max) of L and W [m].
        vary: The scene variables varied beside L and W (:mod:`pipeline.offline.variables`: x,
            the obstacle's centre x, or d, its far edge y), as
            :class:`pipeline.offline.designs.Factor` objects or (name, min, max) [m]; () for the
            paper's (L, W). With any, the coefficients vary them too; the range certificate
            covers them (d only with y1 = d, the scene's ``start_y_m`` None; otherwise the build
            writes no region map), the certifiable regression's rounds only (L, W, x).
        kind: The design: a :class:`pipeline.offline.designs.ScaledDesign` subclass
            (:class:`~pipeline.offline.designs.FullFactorial`, the default,
            :class:`~pipeline.offline.designs.BoxBehnken`,
            :class:`~pipeline.offline.designs.CentralComposite`) or its command-line name.
    """

    levels: int = 3
    length_range_m: tuple[float, float] = (0.20, 0.30)
    width_range_m: tuple[float, float] = (0.08, 0.12)
    vary: tuple[Factor | tuple[str, float, float], ...] = ()
    kind: type[ScaledDesign] | str = FullFactorial

    def __post_init__(self) -> None:
        self._check_vary()
        self._check_kind()
        for name in ("length_range_m", "width_range_m"):
            value = getattr(self, name)
            if not isinstance(value, tuple | list) or len(value) != 2:
                raise InvalidParameterError(OPTIONS[name], value, "(min, max) [m]")
            object.__setattr__(self, name, tuple(value))
        self.scaled_design()  # a bad level or range fails here

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

    def _check_kind(self) -> None:
        option = OPTIONS["design_kind"]
        kind = self.kind
        if isinstance(kind, str):
            try:
                kind = design_class(kind)
            except InvalidParameterError as exc:
                raise InvalidParameterError(option, kind, exc.expected) from None
        if not (isinstance(kind, type) and kind in DESIGN_KINDS.values()):
            raise InvalidParameterError(option, self.kind, f"one of {', '.join(DESIGN_KINDS)} or its class")
        object.__setattr__(self, "kind", kind)
        if kind is not FullFactorial and self.levels != 3:
            raise InvalidParameterError(OPTIONS["levels"], self.levels, f"3 with --design {kind.kind} (3 levels)")

    @property
    def variables(self) -> Variables:
        """The scene variables the DOE and the coefficients vary: (L, W) and ``vary``'s."""
        return Variables((*SIZE, *(f.name for f in self.vary)))

    def scaled_design(self) -> ScaledDesign:
        """The design: over (L, W) and ``vary``'s variables, of kind ``kind`` (the default: the
        paper's K x K full factorial over (L, W))."""
        size = _named(lambda: Design(self.levels, tuple(self.length_range_m), tuple(self.width_range_m)))
        factors = (*size.full_factorial().factors, *self.vary)
        if self.kind is FullFactorial:
            return FullFactorial(factors, self.levels)
        return _named(lambda: self.kind(factors))


@dataclass(frozen=True)
class OptimiserSettings:
    """The PSO per experiment, its polish and its objective; validated on construction.

    Attributes:
        swarm_size, iterations, restarts: PSO settings [count] (:class:`pipeline.offline.pso.PsoConfig`).
        polish: Polish every PSO restart with least_squares.
        n_points: Path points n of Eq. 5 [count].
        endpoint_weight: Weight of the first and last path points in Eq. 5 [-].
        penalty_weight: Clearance penalty weight [1/m^2 relative to Eq. 5's m^2].
        margin_buffer_m: Extra clearance the optimiser aims for beyond the margin [m]
            (:class:`pipeline.offline.fitness.FitnessConfig`).
    """

    swarm_size: int = _PSO.swarm_size
    iterations: int = _PSO.iterations
    restarts: int = _PSO.restarts
    polish: bool = True
    n_points: int = _FITNESS.n_points
    endpoint_weight: float = _FITNESS.endpoint_weight
    penalty_weight: float = _FITNESS.penalty_weight
    margin_buffer_m: float = _FITNESS.margin_buffer_m

    def __post_init__(self) -> None:
        _check_switches(self, "polish")
        self.pso()
        self.fitness()

    def pso(self) -> PsoConfig:
        """The swarm's settings."""
        return _named(lambda: PsoConfig(swarm_size=self.swarm_size, iterations=self.iterations, restarts=self.restarts))

    def fitness(self) -> FitnessConfig:
        """The objective's settings."""
        return _named(
            lambda: FitnessConfig(
                n_points=self.n_points,
                endpoint_weight=self.endpoint_weight,
                penalty_weight=self.penalty_weight,
                margin_buffer_m=self.margin_buffer_m,
            )
        )


@dataclass(frozen=True)
class RegressionSettings:
    """The regression, the convergence thresholds and the certifiable regression's rounds;
    validated on construction.

    Attributes:
        endpoint_tolerance_m: Endpoint tolerance of the regression [m] (paper family), or None
            for the plain least-squares fit (the paper's Eq. 9). Ignored by a family that pins
            the endpoints.
        doe_endpoint_error_max_m: Largest endpoint error of a DOE optimum for the build to
            count as converged [m] (:mod:`pipeline.offline.convergence`).
        allow_unconverged: Write the files (marked) even if the build did not converge.
        clearance_rounds: Rounds of the certifiable regression before the map [count] (paper
            family with the endpoint constraint; 0: none).
    """

    endpoint_tolerance_m: float | None = EndpointConstraint.tolerance_m
    doe_endpoint_error_max_m: float = _CRITERIA.endpoint_error_max_m
    allow_unconverged: bool = False
    clearance_rounds: int = DEFAULT_CLEARANCE_ROUNDS

    def __post_init__(self) -> None:
        if not _is_count(self.clearance_rounds):
            raise InvalidParameterError(OPTIONS["clearance_rounds"], self.clearance_rounds, "an integer >= 0")
        _check_switches(self, "allow_unconverged")
        self.constraint()
        self.criteria()

    def constraint(self) -> EndpointConstraint | None:
        """The regression's endpoint constraint, or None (plain fit) whatever the family."""
        if self.endpoint_tolerance_m is None:
            return None
        return _named(lambda: EndpointConstraint(tolerance_m=self.endpoint_tolerance_m))

    def criteria(self) -> ConvergenceCriteria:
        """The thresholds the results must meet."""
        return _named(lambda: ConvergenceCriteria(endpoint_error_max_m=self.doe_endpoint_error_max_m))


@dataclass(frozen=True)
class RangeMapSettings:
    """The range certificate; validated on construction.

    Attributes:
        enabled: Certify the coefficients over their fitted range and write region_map.json.
        near_optimal_cells: Cells per axis of the map's near-optimal timings [count]
            (:mod:`pipeline.certify.cell_timings`); None: 64 over (L, W), 16 over three axes,
            8 over four; 0: none.
    """

    enabled: bool = True
    near_optimal_cells: int | None = None

    def __post_init__(self) -> None:
        _check_switches(self, "enabled")
        cells = self.near_optimal_cells
        if cells is not None and not _is_count(cells):
            raise InvalidParameterError(OPTIONS["near_optimal_cells"], cells, "an integer >= 0 (0: none)")


@dataclass(frozen=True)
class ExecutionSettings:
    """Where the DOE and the range map run; none of it changes the files. Validated on construction.

    Attributes:
        jobs: Worker processes [count] (>= 1), or 0 for every CPU (the default).
        scheduler: Address of a Dask scheduler (``host:port`` or ``tcp://host:port``) whose
            workers run the DOE and the range map in place of the ``jobs`` local processes (see
            :mod:`pipeline.io.executor`); None: the local processes.
        worker_timeout_s: With ``scheduler``: how long to wait for its first worker before any
            work [s]; none by then is refused (``NoDaskWorkersError``).
    """

    jobs: int = 0
    scheduler: str | None = None
    worker_timeout_s: float = DEFAULT_WORKER_TIMEOUT_S

    def __post_init__(self) -> None:
        if not _is_count(self.jobs):
            raise InvalidParameterError(OPTIONS["jobs"], self.jobs, "an integer >= 0 (0 = every CPU)")
        if self.scheduler is not None:
            check_scheduler_address(OPTIONS["scheduler"], self.scheduler)
        timeout = self.worker_timeout_s
        if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not 0.0 < timeout < math.inf:
            raise InvalidParameterError(OPTIONS["worker_timeout_s"], timeout, "a finite time > 0 [s]")

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


#: The sections of a :class:`BuildConfig`: attribute -> class.
SECTIONS: Mapping[str, type] = MappingProxyType(
    {
        "design": DesignSettings,
        "optimiser": OptimiserSettings,
        "regression": RegressionSettings,
        "range_map": RangeMapSettings,
        "execution": ExecutionSettings,
    }
)


def _by_section(settings: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """Settings by name -> (those of BuildConfig itself, those of each section by field name).

    Raises:
        InvalidParameterError: a name that is no setting.
    """
    own: dict[str, Any] = {}
    sections: dict[str, dict[str, Any]] = {name: {} for name in SECTIONS}
    for name, value in settings.items():
        option = SETTINGS.get(name)
        if option is None:
            raise InvalidParameterError("setting", name, f"one of {', '.join(SETTINGS)}")
        (sections[option.section] if option.section else own)[option.attribute] = value
    return own, sections


@dataclass(frozen=True)
class BuildConfig:
    """Everything a build needs; validated on construction (errors name the command-line option).

    Attributes:
        out_folder: Where doe.json, coefficients.json, region_map.json and build_timing.json go
            (and arm.urdf for an arm other than the shipped one); created when they are
            written, not before.
        seed: Master random seed (integer >= 0); the same seed gives byte-identical doe.json,
            coefficients.json and region_map.json whatever the execution.
        family: Trajectory family (object, or its name as on the command line).
        urdf_path: URDF of the arm (None: the paper's arm shipped with the package).
        scene: The scene (obstacle placement, path, speed, margin); see :func:`scene_from_options`.
        acceleration_limits_rad_s2: The arm's joint acceleration limits [rad/s^2] (URDF carries
            none), recorded in the coefficients; later certificates hold answers to them. None: none.
        design: The design of experiments (:class:`DesignSettings`).
        optimiser: The PSO and its objective (:class:`OptimiserSettings`).
        regression: The regression and the convergence thresholds (:class:`RegressionSettings`).
        range_map: The range certificate (:class:`RangeMapSettings`).
        execution: Where the work runs (:class:`ExecutionSettings`).
    """

    out_folder: Path = Path("results")
    seed: int = 0
    family: TrajectoryFamily | str = PAPER
    urdf_path: Path = DEFAULT_URDF
    scene: Scene = field(default_factory=Scene)
    acceleration_limits_rad_s2: tuple[float, float] | None = None
    design: DesignSettings = field(default_factory=DesignSettings)
    optimiser: OptimiserSettings = field(default_factory=OptimiserSettings)
    regression: RegressionSettings = field(default_factory=RegressionSettings)
    range_map: RangeMapSettings = field(default_factory=RangeMapSettings)
    execution: ExecutionSettings = field(default_factory=ExecutionSettings)

    def __post_init__(self) -> None:
        for name, section in SECTIONS.items():
            if not isinstance(getattr(self, name), section):
                raise InvalidParameterError(name, getattr(self, name), f"a {section.__name__}")
        self._check_paths()
        if not _is_count(self.seed):
            raise InvalidParameterError(OPTIONS["seed"], self.seed, "an integer >= 0")
        if isinstance(self.family, str):
            try:
                object.__setattr__(self, "family", family_from_name(self.family))
            except PipelineError:
                raise InvalidParameterError(OPTIONS["family"], self.family, "a trajectory family name") from None
        if not isinstance(self.family, TrajectoryFamily):
            raise InvalidParameterError(OPTIONS["family"], self.family, "a TrajectoryFamily or its name")
        self._check_scene()
        self._check_acceleration_limits()

    def _check_paths(self) -> None:
        if not isinstance(self.out_folder, str | os.PathLike):
            raise InvalidParameterError(OPTIONS["out_folder"], self.out_folder, "a folder path")
        object.__setattr__(self, "out_folder", Path(self.out_folder))
        if self.urdf_path is None:
            object.__setattr__(self, "urdf_path", DEFAULT_URDF)
        if not isinstance(self.urdf_path, str | os.PathLike):
            raise InvalidParameterError(OPTIONS["urdf_path"], self.urdf_path, "a URDF file path")
        object.__setattr__(self, "urdf_path", Path(self.urdf_path))

    def _check_scene(self) -> None:
        if not isinstance(self.scene, Scene):
            raise InvalidParameterError(OPTIONS["scene"], self.scene, "a pipeline.model.scene.Scene")
        if self.scene.centre_x_m != 0.0:
            raise InvalidParameterError(
                "centre_x_m",
                self.scene.centre_x_m,
                "0: the build's range certificate and the online generator place the obstacle at x = 0",
            )

    def _check_acceleration_limits(self) -> None:
        if self.acceleration_limits_rad_s2 is None:
            return
        try:
            limits = tuple(float(v) for v in self.acceleration_limits_rad_s2)
        except (TypeError, ValueError):
            limits = ()
        if len(limits) != 2 or not all(v > 0.0 for v in limits):
            raise InvalidParameterError(
                OPTIONS["acceleration_limits_rad_s2"], self.acceleration_limits_rad_s2, "two positive limits [rad/s^2]"
            )
        object.__setattr__(self, "acceleration_limits_rad_s2", limits)

    @classmethod
    def from_settings(cls, **settings: Any) -> BuildConfig:
        """The configuration of settings by name (:data:`pipeline.build.options.OPTIONS`'s keys,
        e.g. ``jobs=1``, ``clearance_rounds=0``), each placed in its section; the others default.

        Raises:
            InvalidParameterError: an unknown setting, or a bad value (naming its option).
        """
        own, sections = _by_section(settings)
        return cls(**own, **{name: SECTIONS[name](**values) for name, values in sections.items()})

    def with_settings(self, **settings: Any) -> BuildConfig:
        """This configuration with settings by name replaced (as :meth:`from_settings` takes them).

        Raises:
            InvalidParameterError: an unknown setting, or a bad value (naming its option).
        """
        own, sections = _by_section(settings)
        changed = {name: replace(getattr(self, name), **values) for name, values in sections.items() if values}
        return replace(self, **own, **changed)

    def settings(self) -> Mapping[str, Any]:
        """Every setting by name (the inverse of :meth:`from_settings`)."""
        return MappingProxyType(
            {
                name: getattr(getattr(self, option.section) if option.section else self, option.attribute)
                for name, option in SETTINGS.items()
            }
        )

    @property
    def variables(self) -> Variables:
        """The scene variables the DOE and the coefficients vary: (L, W) and ``design.vary``'s."""
        return self.design.variables

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
        constraint, the paper family: L, W, x and d, as the certificate's axes)."""
        return bool(
            self.range_map.enabled
            and self.certifiable_axes
            and all(name in REFIT_VARIABLES for name in self.variables.names)
            and self.regression.clearance_rounds > 0
            and self.regression.endpoint_tolerance_m is not None
            and self.family == PAPER
        )

    def solver(self) -> SolverConfig:
        """PSO, polish and objective settings of every experiment."""
        optimiser = self.optimiser
        return SolverConfig(
            family=self.family, fitness=optimiser.fitness(), pso=optimiser.pso(), polish=optimiser.polish
        )

    def endpoint_constraint(self) -> EndpointConstraint | None:
        """The regression's endpoint constraint, or None (plain fit, or a family exact by construction)."""
        constraint = self.regression.constraint()
        return None if constraint is None or self.family.pins_endpoints else constraint
