"""The benchmark's settings and results: what is timed, with which defaults, and how it came out."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.validation import check_non_negative, check_positive, check_positive_int

from .ompl_planner import OMPL_DEFAULT_RESOLUTION

FORMAT = "twolink-bench/1"
DEFAULT_BUILD_TIMING = "results/build_timing.json"
#: Coefficients over (L, W, x) of row (a*) over (L, W, x), used if the file exists (beside ``results/``).
DEFAULT_COEFFICIENTS_X = "results-x/coefficients.json"
#: The command that makes them.
MAKE_COEFFICIENTS_X = "python -m pipeline.build --vary x -0.03 0.03 --out results-x"
DEFAULT_N = 50
DEFAULT_SEED = 0
#: Interleaved timed passes of the per-query rows (a), (a*) and (a*) over (L, W, x) [passes].
DEFAULT_REPEATS = 1000
#: Timed passes of the batched rows (a'), (a*') and (r*') [passes].
DEFAULT_BATCH_REPEATS = 200
#: Obstacles per call of the batched rows (a') and (a*') [obstacles]: the bench's obstacles, cycled.
DEFAULT_BATCH_SIZE = 1000
DEFAULT_SLOW_REPEATS = 3
DEFAULT_PSO_CASES = 3
DEFAULT_OMPL_TIME_S = 1.0
#: TOPP-RA's gridpoints in the row beside (n*) [gridpoints] (verify.benchmark.near_optimal).
DEFAULT_TOPPRA_GRIDPOINTS = 100

#: Warm-up calls of the cheap methods before timing.
WARMUP_CALLS = 20


@dataclass(frozen=True)
class MethodResult:
    """Timings and answer quality of one method.

    Attributes:
        key: Short key: "a", "a_batch", "a_range", "a_range_batch", "r_range", "r_range_batch", "b",
            "n_opt", "toppra", "c", "d", "d_cert", and over (L, W, x) "a_range_x", "d_x", "d_x_cert".
        label: Row label of the table.
        obstacles: Distinct obstacles queried.
        times_s: Every timed run, as time per query [s].
        queries: Queries whose answers are counted (obstacles x runs).
        answered: Queries that returned an answer (a trajectory or a path).
        certified: Answers certified collision-free (certified clearance > 0).
        keeps_margin: Answers whose certified clearance is >= the margin.
        note: What exactly was timed.
        extra: Method-specific numbers (repairs, planner failures, Coal queries, ...).
    """

    key: str
    label: str
    obstacles: int
    times_s: tuple[float, ...]
    queries: int
    answered: int
    certified: int
    keeps_margin: int
    note: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def median_s(self) -> float:
        """Median time per query [s]."""
        return float(np.median(self.times_s))

    @property
    def answered_fraction(self) -> float:
        """Fraction of the queries answered."""
        return self.answered / self.queries if self.queries else float("nan")

    @property
    def certified_fraction(self) -> float:
        """Fraction of the answers certified collision-free."""
        return self.certified / self.answered if self.answered else float("nan")

    @property
    def keeps_margin_fraction(self) -> float:
        """Fraction of the answers whose certified clearance keeps the margin."""
        return self.keeps_margin / self.answered if self.answered else float("nan")

    def to_json(self, reference_a_s: float, reference_b_s: float | None) -> dict[str, Any]:
        """Plain-JSON form, with the ratios of the median to (a) and (b)."""
        return {
            "key": self.key,
            "label": self.label,
            "obstacles": self.obstacles,
            "timed_runs": len(self.times_s),
            "median_s": self.median_s,
            "min_s": float(np.min(self.times_s)),
            "max_s": float(np.max(self.times_s)),
            "ratio_to_a": self.median_s / reference_a_s,
            "ratio_to_b": None if reference_b_s is None else self.median_s / reference_b_s,
            "queries": self.queries,
            "answered": self.answered,
            "answered_fraction": self.answered_fraction,
            "certified_collision_free": self.certified,
            "certified_fraction": self.certified_fraction,
            "keeps_margin": self.keeps_margin,
            "keeps_margin_fraction": self.keeps_margin_fraction,
            "note": self.note,
            "extra": self.extra,
        }


@dataclass(frozen=True)
class BenchSettings:
    """What the benchmark runs.

    Attributes:
        n: Random obstacles [cases].
        seed: Seed of the obstacle sampler, the PSO and OMPL.
        repeats: Interleaved timed passes over all obstacles of the per-query rows (a), (a*) and
            (a*) over (L, W, x) (:mod:`verify.benchmark.per_query`).
        batch_repeats: Timed passes of the batched rows (a'), (a*') and (r*').
        batch_size: Obstacles per call of the batched rows (a') and (a*'): the n obstacles cycled to
            this many (at least n), so that a call's fixed cost is spread as a batch user's is.
        slow_repeats: Timed passes over all obstacles for (r*), (b), (n*), TOPP-RA and (d).
        pso_cases: Obstacles (the first ones) on which (c) re-runs the PSO; 0 skips (c).
        pso_swarm_size, pso_iterations, pso_restarts: PSO settings of (c) and --run-build; None: the
            coefficients' build settings if recorded (provenance), else PsoConfig's defaults.
        polish: least_squares polish in (c); None: as the build did (default True).
        ompl_time_s: RRT-Connect time budget per query [s].
        ompl_margin_m: Validity margin of (d): a state is valid iff both links' clearance is >= this [m];
            None: the coefficients' scene margin (the fair comparison: the margin (b) is held to).
        ompl_simplify: Simplify the RRT-Connect path (timed as part of (d)).
        ompl_resolution: OMPL's validity checking resolution [fraction of the joint-space extent].
        run_ompl: Run (d) if ompl is installed.
        build_timing: build_timing.json to report (None: skip).
        run_build_levels: If set, also run a reduced build with this many levels per factor.
        urdf: URDF of the arm (None: the project's).
        region_map: Region map of the coefficients for (a*) (None: the one beside them, else
            certified in-process).
        coefficients_x: Coefficients over (L, W, x), with their region map beside them, for the row
            (a*) over (L, W, x) and OMPL on the same moved obstacles (None: ``DEFAULT_COEFFICIENTS_X``
            if it exists, else the rows are left out).
        run_x: Run the rows over (L, W, x) (False: left out, even with ``coefficients_x``).
        run_near_optimal: Run (n*) and TOPP-RA on its paths (:mod:`verify.benchmark.near_optimal`).
        toppra_gridpoints: TOPP-RA's gridpoints in that row [gridpoints] (>= 2).
    """

    n: int = DEFAULT_N
    seed: int = DEFAULT_SEED
    repeats: int = DEFAULT_REPEATS
    batch_repeats: int = DEFAULT_BATCH_REPEATS
    batch_size: int = DEFAULT_BATCH_SIZE
    slow_repeats: int = DEFAULT_SLOW_REPEATS
    pso_cases: int = DEFAULT_PSO_CASES
    pso_swarm_size: int | None = None
    pso_iterations: int | None = None
    pso_restarts: int | None = None
    polish: bool | None = None
    ompl_time_s: float = DEFAULT_OMPL_TIME_S
    ompl_margin_m: float | None = None
    ompl_simplify: bool = True
    ompl_resolution: float = OMPL_DEFAULT_RESOLUTION
    run_ompl: bool = True
    build_timing: Path | None = Path(DEFAULT_BUILD_TIMING)
    run_build_levels: int | None = None
    urdf: Path | None = None
    region_map: Path | None = None
    coefficients_x: Path | None = None
    run_x: bool = True
    run_near_optimal: bool = True
    toppra_gridpoints: int = DEFAULT_TOPPRA_GRIDPOINTS

    def __post_init__(self) -> None:
        check_positive_int("--n", self.n)
        check_positive_int("--seed", self.seed, minimum=0)
        check_positive_int("--repeats", self.repeats)
        check_positive_int("--batch-repeats", self.batch_repeats)
        check_positive_int("--batch-size", self.batch_size)
        check_positive_int("--slow-repeats", self.slow_repeats)
        check_positive_int("--toppra-gridpoints", self.toppra_gridpoints, minimum=2)
        check_positive_int("--pso-cases", self.pso_cases, minimum=0)
        if self.pso_cases > self.n:
            raise InvalidParameterError("--pso-cases", self.pso_cases, f"at most --n = {self.n}")
        for name, value, minimum in (
            ("--pso-swarm-size", self.pso_swarm_size, 2),
            ("--pso-iterations", self.pso_iterations, 1),
            ("--pso-restarts", self.pso_restarts, 1),
        ):
            if value is not None:
                check_positive_int(name, value, minimum=minimum)
        check_positive("--ompl-time", self.ompl_time_s)
        if self.ompl_margin_m is not None:
            check_non_negative("--ompl-margin", self.ompl_margin_m)
        check_positive("--ompl-resolution", self.ompl_resolution)
        if self.run_build_levels is not None:
            check_positive_int("--run-build", self.run_build_levels, minimum=3)
        if self.region_map is not None and not Path(self.region_map).is_file():
            raise InvalidParameterError("--region-map", str(self.region_map), "an existing region map file")
        if self.coefficients_x is not None and not Path(self.coefficients_x).is_file():
            raise InvalidParameterError(
                "--coefficients-x", str(self.coefficients_x), f"an existing coefficients file ({MAKE_COEFFICIENTS_X})"
            )


@dataclass(frozen=True)
class BenchReport:
    """Everything one benchmark run measured.

    Attributes:
        coefficients: Source, family and hash of the coefficients.
        settings: The settings as plain JSON.
        cases_m: The obstacles (L, W) [m], shape (n, 2).
        margin_m: The scene's safety margin [m].
        methods: One :class:`MethodResult` per method run.
        skipped: Method key -> why it was skipped.
        sweep: Sweep rates (None if not run).
        build: Build timing (None if none was found or run).
        range_map: Where (a*)'s region map came from (:meth:`BenchRegionMap.to_json`; None if (a*) did not run).
        machine: Python, platform, CPU count, package versions.
        command: The command line.
        elapsed_s: Wall time of the whole benchmark [s].
        over_x: The coefficients over (L, W, x), their map and obstacles of the row (a*) over (L, W, x)
            (None if it did not run).
        near_optimal: (n*) against TOPP-RA on the same paths and limits: duration ratios and sampled
            excesses (:meth:`verify.benchmark.near_optimal.NearOptimalRows.summary`; None if (n*) did not run).
    """

    coefficients: dict[str, Any]
    settings: dict[str, Any]
    cases_m: np.ndarray
    margin_m: float
    methods: tuple[MethodResult, ...]
    skipped: dict[str, str]
    sweep: dict[str, Any] | None
    build: dict[str, Any] | None
    range_map: dict[str, Any] | None
    machine: dict[str, Any]
    command: str
    elapsed_s: float
    over_x: dict[str, Any] | None = None
    near_optimal: dict[str, Any] | None = None

    def method(self, key: str) -> MethodResult | None:
        """The result of method ``key``, or None if it was not run."""
        return next((m for m in self.methods if m.key == key), None)

    def ratios(self) -> dict[str, float | None]:
        """(d) / (a), (d) / (a*), (d) / (b), (b) / (a*), over (L, W, x) OMPL on the moved obstacles
        over (a*) on them, and (n*) over TOPP-RA on its paths: medians per query measured in this run
        (None where a method did not run)."""

        def ratio(numerator: str, denominator: str) -> float | None:
            top, bottom = self.method(numerator), self.method(denominator)
            return None if top is None or bottom is None else top.median_s / bottom.median_s

        return {
            "d_over_a": ratio("d", "a"),
            "d_over_a_range": ratio("d", "a_range"),
            "d_over_b": ratio("d", "b"),
            "b_over_a_range": ratio("b", "a_range"),
            "d_x_over_a_range_x": ratio("d_x", "a_range_x"),
            "n_opt_over_toppra": ratio("n_opt", "toppra"),
        }

    def a_range_summary(self) -> dict[str, Any] | None:
        """The (a*) row's headline figures (None if it did not run): median per query and batched
        time per obstacle [us], the fractions of in-range queries answered with a certified clearance
        (> 0) and with one >= the margin, and the ratio (d) / (a*)."""
        row, batch = self.method("a_range"), self.method("a_range_batch")
        if row is None:
            return None
        in_range = row.extra["in_range_queries"]
        return {
            "median_us": row.median_s * 1e6,
            "batched_us_per_obstacle": None if batch is None else batch.median_s * 1e6,
            "certified_fraction": row.certified / in_range if in_range else None,
            "margin_fraction": row.keeps_margin / in_range if in_range else None,
            "ratio_to_d": self.ratios()["d_over_a_range"],
            "in_range_queries": in_range,
            "same_parameters_as_a": row.extra["same_parameters_as_a"],
            "region_map": self.range_map,
        }

    def a_range_x_summary(self) -> dict[str, Any] | None:
        """The headline figures of (a*) over (L, W, x) (None if it did not run): median per query [us],
        the fractions of in-range queries with a certified clearance > 0 and >= the margin, the ratio
        of OMPL on the same moved obstacles to it, and where its coefficients and map came from."""
        row = self.method("a_range_x")
        if row is None:
            return None
        in_range = row.extra["in_range_queries"]
        return {
            "median_us": row.median_s * 1e6,
            "certified_fraction": row.certified / in_range if in_range else None,
            "margin_fraction": row.keeps_margin / in_range if in_range else None,
            "ratio_to_d_x": self.ratios()["d_x_over_a_range_x"],
            "in_range_queries": in_range,
            "over_x": self.over_x,
        }

    def to_json(self) -> dict[str, Any]:
        """The --json document."""
        a = self.method("a")
        b = self.method("b")
        reference_a = a.median_s if a else float("nan")
        reference_b = b.median_s if b else None
        return {
            "format": FORMAT,
            "command": self.command,
            "note": "ratios measured in one run on this machine, not absolute claims",
            "coefficients": self.coefficients,
            "settings": self.settings,
            "margin_m": self.margin_m,
            "cases": [[float(length), float(width)] for length, width in self.cases_m],
            "methods": [m.to_json(reference_a, reference_b) for m in self.methods],
            "a_range": self.a_range_summary(),
            "a_range_x": self.a_range_x_summary(),
            "near_optimal": self.near_optimal,
            "ratios": self.ratios(),
            "skipped": dict(self.skipped),
            "sweep": self.sweep,
            "build": self.build,
            "machine": self.machine,
            "elapsed_s": self.elapsed_s,
        }
