"""Design of experiments: the paper's full factorial over (L, W), or a design over k scene
variables (:mod:`pipeline.offline.designs`), solved point by point.

The paper's design is K x K levels (K = 3 in the paper), ordered as Table 1: W descending by
rows, L descending within a row (Test 1 = (L_max, W_max)). A run of a design that varies more
than L and W (e.g. the obstacle's centre x) is solved in the scene of its values
(:meth:`pipeline.offline.variables.Variables.scene_for`); doe.json then names the variables
(``"variables"``) and gives each experiment's values beside L and W. A DOE over (L, W) alone
writes neither, so its file is the paper design's, byte for byte. Each experiment gets its own
random stream spawned from one seed, so the results do not depend on where they are solved
(``jobs`` worker processes, or a Dask cluster: :mod:`pipeline.io.executor`) or on the order in
which they finish.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.exceptions import DataFileError, InvalidParameterError, PipelineError
from pipeline.io.executor import Executor, LocalPool, as_executor, map_tasks
from pipeline.io.jsonio import read_json
from pipeline.io.parallel import item_seeds
from pipeline.model.arm import PlanarArm, load_planar_arm
from pipeline.model.scene import Scene
from pipeline.motion.families import PAPER, TrajectoryFamily, family_from_name
from pipeline.motion.trajectory import PARAMETER_NAMES, canonicalize
from pipeline.offline.designs import Factor, FullFactorial, ScaledDesign
from pipeline.offline.experiment import ExperimentResult, SolverConfig, solve_experiment
from pipeline.offline.variables import DEFAULT_VARIABLES, SIZE, Variables, variables_in
from pipeline.validation import check_positive, check_positive_int

FORMAT = "twolink-doe/1"
PAPER_L_RANGE_M = (0.20, 0.30)
PAPER_W_RANGE_M = (0.08, 0.12)


@dataclass(frozen=True)
class Design:
    """A K x K full-factorial design over (L, W).

    Attributes:
        levels: K, levels per factor (>= 3 for a quadratic fit).
        length_range_m: (L_min, L_max) [m].
        width_range_m: (W_min, W_max) [m].
    """

    levels: int = 3
    length_range_m: tuple[float, float] = PAPER_L_RANGE_M
    width_range_m: tuple[float, float] = PAPER_W_RANGE_M

    def __post_init__(self) -> None:
        check_positive_int("levels", self.levels, minimum=3)
        for name, (lo, hi) in (("L range", self.length_range_m), ("W range", self.width_range_m)):
            check_positive(f"{name} min", lo)
            check_positive(f"{name} max", hi)
            if not lo < hi:
                raise InvalidParameterError(name, (lo, hi), "min < max")

    def points(self) -> list[tuple[float, float]]:
        """(L, W) [m] of every experiment in Table 1 order."""
        lengths = np.linspace(self.length_range_m[1], self.length_range_m[0], self.levels)
        widths = np.linspace(self.width_range_m[1], self.width_range_m[0], self.levels)
        return [(round(float(L), 12), round(float(W), 12)) for W in widths for L in lengths]

    @property
    def variables(self) -> Variables:
        """(L, W)."""
        return DEFAULT_VARIABLES

    def runs(self) -> list[dict[str, float]]:
        """Each run's values by name."""
        return [{"L": L, "W": W} for L, W in self.points()]

    def full_factorial(self) -> FullFactorial:
        """The same design as a :class:`pipeline.offline.designs.FullFactorial` (same points, same JSON)."""
        factors = (Factor("L", self.length_range_m), Factor("W", self.width_range_m))
        return FullFactorial(factors, self.levels)

    def to_json(self) -> dict:
        return {
            "levels": self.levels,
            "L_range": list(self.length_range_m),
            "W_range": list(self.width_range_m),
            "order": "Table 1: W descending by rows, L descending within a row",
        }


#: One experiment's task: L, W, the other variables' values by name, its random stream.
_Task = tuple[float, float, dict[str, float], np.random.SeedSequence]


def run_scene(design: Design | ScaledDesign, scene: Scene, values: dict[str, float]) -> Scene:
    """The scene of the run with ``values`` (name -> value, L and W among them): ``scene`` with
    the fields of the other variables replaced (``scene`` itself for (L, W))."""
    return design.variables.scene_for(scene, {k: v for k, v in values.items() if k not in SIZE})


def _solve(arm: PlanarArm, scene: Scene, config: SolverConfig, task: _Task) -> ExperimentResult:
    length_m, width_m, extra, seed_sequence = task
    moved = DEFAULT_VARIABLES.scene_for(scene, extra)  # scene_for reads the names of ``extra`` only
    return solve_experiment(arm, length_m, width_m, moved, config, np.random.default_rng(seed_sequence))


def _solve_in_worker(urdf_path: str, scene: Scene, config: SolverConfig, task: _Task) -> ExperimentResult:
    """One experiment in a worker process (the arm is reloaded there: milliseconds, against
    seconds of PSO)."""
    return _solve(load_planar_arm(urdf_path), scene, config, task)


def run_doe(
    arm: PlanarArm,
    design: Design | ScaledDesign,
    scene: Scene,
    config: SolverConfig,
    seed: int,
    jobs: int | Executor = 1,
    progress: Callable[[ExperimentResult], None] | None = None,
) -> list[ExperimentResult]:
    """Solve every experiment of ``design``; results in design order, the same wherever they run.

    Args:
        arm: The arm (its URDF is reloaded in each worker when the experiments run elsewhere).
        design: The runs: the (L, W) grid, or a design over k variables (each run solved in
            ``scene`` with its variables' fields replaced, :func:`run_scene`).
        scene: Scene settings (the base scene of the runs).
        config: Solver settings.
        seed: Master seed; experiment i uses the i-th spawned child stream
            (:func:`pipeline.io.parallel.item_seeds`).
        jobs: Where to solve them (:func:`pipeline.io.executor.map_tasks`): a number of local
            processes (1 = in this process), a :class:`pipeline.io.executor.LocalPool` or a
            :class:`pipeline.io.executor.DaskScheduler`; one experiment per worker call.
        progress: Called with each result as it completes.
    """
    executor = as_executor(jobs)
    runs = design.runs()
    tasks = [
        (values["L"], values["W"], {k: v for k, v in values.items() if k not in SIZE}, stream)
        for values, stream in zip(runs, item_seeds(seed, len(runs)), strict=True)
    ]
    if executor == LocalPool(1):
        function = functools.partial(_solve, arm, scene, config)
    else:
        function = functools.partial(_solve_in_worker, str(arm.urdf_path), scene, config)

    def report(_index: int, result: ExperimentResult) -> None:
        if progress:
            progress(result)

    return map_tasks(executor, function, tasks, report, chunk_size=1)


@dataclass(frozen=True)
class DoeData:
    """Experiments read from a DOE file (ours or the paper's Table 2).

    Attributes:
        family: Trajectory family of the parameters.
        lengths_m, widths_m: (L, W) of each experiment [m].
        parameters: (n, 8) parameters in PARAMETER_NAMES order (canonical for the paper family).
        free: (n, k) the family's free parameters in FREE_PARAMETERS order.
        scene: Scene of the experiments (the base scene, for a DOE over more variables than (L, W)).
        link_lengths_m, link_radii_m, elbow: Arm data needed by the generator.
        document: The whole parsed file.
        source: File path.
        variables: The scene variables the DOE varies (default (L, W)).
        extra_m: (n, k - 2) each experiment's values of ``variables.extra`` [m]; None for (L, W).
    """

    family: TrajectoryFamily
    lengths_m: np.ndarray
    widths_m: np.ndarray
    parameters: np.ndarray
    free: np.ndarray
    scene: Scene
    link_lengths_m: tuple[float, float]
    link_radii_m: tuple[float, float]
    elbow: int
    document: dict
    source: str
    variables: Variables = DEFAULT_VARIABLES
    extra_m: np.ndarray | None = None

    @property
    def points(self) -> np.ndarray:
        """Each experiment's variable values (n, k), columns in ``variables``' order."""
        columns = [self.lengths_m, self.widths_m]
        if self.extra_m is not None:
            columns.extend(self.extra_m.T)
        return np.column_stack(columns)

    def free_parameters(self) -> dict[str, np.ndarray]:
        """Homogenised (Eq. 8) free parameters of the family, name -> (n,)."""
        free = self.family.canonical_free(self.free)
        return {name: free[:, i] for i, name in enumerate(self.family.free_parameter_names)}


def _number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def load_doe(path: str | Path) -> DoeData:
    """Read and validate a DOE file.

    Raises:
        DataFileError: missing, unreadable, not JSON, or malformed.
    """
    return doe_from_json(read_json(path), str(path))


def doe_from_json(document: dict, path: str) -> DoeData:
    """Validate a parsed DOE document (``path`` names it in error messages).

    Raises:
        DataFileError: malformed.
    """
    if document.get("format") != FORMAT:
        raise DataFileError(path, f"format is {document.get('format')!r}, expected {FORMAT!r}")
    try:
        family = family_from_name(document.get("family", PAPER.name))
    except PipelineError as exc:
        raise DataFileError(path, str(exc)) from None
    all_free = family.free_parameter_names == PARAMETER_NAMES
    variables = _doe_variables(document, path)
    experiments = document.get("experiments")
    if not isinstance(experiments, list) or not experiments:
        raise DataFileError(path, "'experiments' must be a non-empty list")
    lengths, widths, rows, free_rows, extra_rows = [], [], [], [], []
    for i, experiment in enumerate(experiments):
        if not isinstance(experiment, dict):
            raise DataFileError(path, f"experiment {i} is not an object")
        L, W, params = experiment.get("L"), experiment.get("W"), experiment.get("parameters")
        if not (_number(L) and _number(W) and L > 0 and W > 0):
            raise DataFileError(path, f"experiment {i}: L = {L!r}, W = {W!r}; expected positive numbers")
        if not isinstance(params, dict) or not all(_number(params.get(n)) for n in PARAMETER_NAMES):
            raise DataFileError(path, f"experiment {i}: 'parameters' needs finite {', '.join(PARAMETER_NAMES)}")
        extra = [experiment.get(name) for name in variables.extra]
        if not all(map(_number, extra)):
            raise DataFileError(path, f"experiment {i}: needs finite values of {', '.join(variables.extra)}")
        extra_rows.append([float(v) for v in extra])
        lengths.append(float(L))
        widths.append(float(W))
        rows.append([float(params[n]) for n in PARAMETER_NAMES])
        free_names = family.free_parameter_names
        if all_free:
            free_rows.append(rows[-1])
        else:
            free = experiment.get("free_parameters")
            if not isinstance(free, dict) or not all(_number(free.get(n)) for n in free_names):
                raise DataFileError(path, f"experiment {i}: 'free_parameters' needs finite {', '.join(free_names)}")
            free_rows.append([float(free[n]) for n in free_names])
    scene_doc = document.get("scene", {})
    if not isinstance(scene_doc, dict):
        raise DataFileError(path, "'scene' must be an object")
    try:
        scene = Scene.from_dict(scene_doc)
    except Exception as exc:
        raise DataFileError(path, f"scene: {exc}") from None
    lengths_link = tuple(scene_doc.get("link_lengths_m", (0.30, 0.35)))
    radii_link = tuple(scene_doc.get("link_radii_m", (0.005, 0.005)))
    if len(lengths_link) != 2 or len(radii_link) != 2 or not all(map(_number, lengths_link + radii_link)):
        raise DataFileError(path, "scene.link_lengths_m and scene.link_radii_m must be two numbers each")
    return DoeData(
        family=family,
        lengths_m=np.array(lengths),
        widths_m=np.array(widths),
        parameters=canonicalize(np.array(rows)) if all_free else np.array(rows),
        free=np.array(free_rows),
        scene=scene,
        link_lengths_m=(float(lengths_link[0]), float(lengths_link[1])),
        link_radii_m=(float(radii_link[0]), float(radii_link[1])),
        elbow=int(scene_doc.get("elbow", 1)),
        document=document,
        source=str(path),
        variables=variables,
        extra_m=np.array(extra_rows).reshape(len(rows), -1) if variables.extra else None,
    )


def _doe_variables(document: dict, path: str) -> Variables:
    """The DOE file's ``variables`` (absent: (L, W)); L and W must be among them."""
    variables = variables_in(document, path)
    if variables.names[:2] != SIZE:
        raise DataFileError(path, f"variables are {document['variables']!r}; L and W must be among them")
    return variables


def doe_document(
    results: Sequence[ExperimentResult],
    design: Design | ScaledDesign,
    scene: Scene,
    arm: PlanarArm,
    config: SolverConfig,
    provenance: dict,
    elbow: int,
) -> dict:
    """The doe.json document (deterministic: no wall times); for a design over more than (L, W),
    with ``"variables"`` and each experiment's values of them after its L and W."""
    variables = design.variables
    experiments = []
    for i, (result, values) in enumerate(zip(results, design.runs(), strict=True)):
        record = result.to_json()
        size = {"L": record.pop("L"), "W": record.pop("W")}
        extra = {name: values[name] for name in variables.extra}
        experiments.append({"test": i + 1, **size, **extra, **record})
    head = {"format": FORMAT, "family": config.family.name}
    if not variables.is_size_only:
        head["variables"] = list(variables.names)
    return {
        **head,
        "design": design.to_json(),
        "scene": {
            **scene.to_dict(),
            "link_lengths_m": list(arm.link_lengths_m),
            "link_radii_m": list(arm.link_radii_m),
            "elbow": elbow,
        },
        "experiments": experiments,
        "provenance": provenance,
    }
