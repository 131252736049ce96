"""A regression the range certificate can certify: constraint generation between the
endpoint-constrained fit (``pipeline.offline.endpoint_regression``) and the range certificate.

Round k:

1. certify the current coefficients over the fitted range (``certify_range``; the last round
   with ``final_certificate``, whose cells may be finer);
2. for every leaf that misses the margin without being proven infeasible (status
   ``collision_free`` or ``undecided``), take its worst point: the variables' values v at its
   centre ((L, W), or with the obstacle's centre x and far edge d where they vary) and the s in [0, 1] where the
   clearance along that motion is lowest (dense sampling); for every leaf whose endpoint bound
   exceeds the tolerance, take its centre as an endpoint target;
3. refit the same quadratic model by SLSQP from the current fit: minimise the squared distance
   to the DOE optima subject to the endpoint errors <= the endpoint constraint's fit tolerance
   (tolerance (1 - headroom), as the build's regression) on its grid plus the new endpoint
   targets, and to clearance(L_i, W_i, s_i) >= margin + cushion at every point collected so far
   (analytic distance, d clearance / d theta by central differences, chained in closed form to
   the 48 coefficients; the clearance rows in cm, the scale of the endpoint slack). If SLSQP
   cannot meet a positive cushion it is asked for the margin itself;

until the map has no such leaf or ``max_rounds`` is reached, or a refit fails to converge (it is
tried again without the points whose end poses keep less than margin + each of
``RETRY_SLACKS_M``; if that fails too, the previous fit and its map are returned and the report
says so). Leaves whose end poses cannot keep margin + ``feasible_slack_m`` at the fit's
endpoint tolerance (:func:`end_pose_room_m`, sampled at the leaf's centre) are not constrained:
there the family cannot keep the margin at all with that tolerance, or only just. The fit
remains a closed-form quadratic in its variables; its certificate is the last map, so nothing here
needs trusting beyond ``certify_range``. Paper family only (all 8 parameters regressed).

The refit holds the endpoint errors to tolerance (1 - ``REFIT_ENDPOINT_HEADROOM[k]``) and
constrains every leaf whose end poses leave room for the margin (``feasible_slack_m`` = 0). Both
settings act on a band near W = 0.12 m, some 20-50 um of W wide, where the end poses' room reaches
the margin and the regression's clearance does not: narrower than the cells of the refit's own
maps, so they are chosen by that band itself (the last line of ``python scripts/margin_gap.py``:
the regression's sampled clearance against the sampled room, per L by bisection in W). Less
headroom narrows the band but lets the endpoint errors exceed the tolerance between the grid
points; a second round, whose map at ``REFIT_MIN_CELL`` asks for points its cells cannot place,
makes the final map worse. The measurements are in ``docs/results.md`` ("Settings of the
certifiable regression").
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType

import numpy as np

from pipeline.certify.end_pose_room import configuration_clearance, end_pose_room_m
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import STATUSES, RegionMap, source_name
from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.io.jsonio import dumps
from pipeline.io.progress import ProgressCallback
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import desired_path
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficient_basis import normalised_basis, solve_coefficients
from pipeline.offline.coefficients import Coefficients, coefficients_from_json
from pipeline.offline.doe import DoeData
from pipeline.offline.endpoint_regression import (
    EndpointConstraint,
    EndpointTargets,
    endpoint_errors_m,
    endpoint_slack,
    endpoint_slack_jacobian,
    endpoint_targets,
    merge_targets,
    targets_at,
)
from pipeline.offline.regression import coefficient_of_determination, design_matrix
from pipeline.validation import check_non_negative, check_positive_int

_SAMPLES_S = 401
_CHUNK_LEAVES = 256
_FD_STEP_RAD = 1e-6
#: Clearance constraints are given to SLSQP in centimetres, the size of the endpoint slack's terms.
_CLEARANCE_SCALE = 100.0
#: Default of ``CertifiableFitConfig.feasible_slack_m`` [m]: every leaf whose end poses leave the
#: margin is constrained. A positive slack leaves the leaves just above the infeasibility contour
#: unconstrained and widens the band where the end poses keep the margin and the regression does
#: not (``python scripts/margin_gap.py``, last line; figures in docs/results.md).
_DEFAULT_FEASIBLE_SLACK_M = 0.0
#: Headroom of the refit's endpoint constraint per number of variables (``python -m
#: pipeline.build``'s refit holds the endpoint errors to tolerance (1 - this) at its grid and
#: targets; the first fit keeps ``EndpointConstraint``'s). Over (L, W): each 0.01 of headroom costs
#: the end poses about 0.0145 mm of room in the strip near W = 0.12 m (0.72 mm of clearance per mm
#: of tolerance there), so less headroom lets the refit keep the margin closer to the
#: infeasibility contour; but the errors between the 21 x 21 grid points must stay within the
#: tolerance for the range certificate to prove it, which 0.005 does and 0.0025 does not. Over
#: (L, W, x) the first fit's (``K_ENDPOINT_HEADROOM``). Over (L, W, x, d), 0.2: the default
#: map still proves every endpoint within the tolerance on its cells of 1/32, and the margin
#: gains where the end poses' room lies between the margin at 1.3 mm and at 2 mm of tolerance
#: (0.35, the first fit's, cost the margin there); at 0.1 the endpoint bound exceeds the
#: tolerance on 1.20 % of the box (up to 2.195 mm) at those cells (docs/results.md).
REFIT_ENDPOINT_HEADROOM: Mapping[int, float] = MappingProxyType({2: 0.005, 3: 0.05, 4: 0.2})


#: If a refit does not converge, it is tried again without the points whose end poses keep less
#: than margin + each of these in turn (:func:`end_pose_room_m`) [m]; the last keeps about the
#: leaves whose infeasibility bound U is at least margin + 1 mm.
RETRY_SLACKS_M = (1e-4, 1e-3)
#: Rounds of the build's certifiable regression (``python -m pipeline.build --clearance-rounds``).
DEFAULT_CLEARANCE_ROUNDS = 1
#: Smallest cell of the maps of the build's refit rounds but the last (fraction of the side), per
#: number of variables; the last round, whose map the build writes, uses the build's (finer)
#: cells. The coarser cells keep the refit's points on the leaves that matter and the rounds fast.
REFIT_MIN_CELLS: Mapping[int, float] = MappingProxyType({2: 1.0 / 256, 3: 1.0 / 32, 4: 1.0 / 16})
#: Clearance points (and endpoint targets) each refit round adds, per number of variables
#: (``CertifiableFitConfig.points_per_round`` of the build's refit). Over (L, W, x) the band where
#: the regression's clearance crosses the margin is a surface across L and x, not a line along L:
#: 400 points spread over it leave the regression below the margin between them on 0.22 % of the
#: box where the end poses leave room for it, 1200 on 0.03 % (``python scripts/margin_band.py``),
#: for about 40 s more refit; over (L, W, x, d) 1200 points raise the map's margin from 95.1 % to
#: 95.5 % of the feasible volume, for about 80 s more refit; figures in docs/results.md.
REFIT_POINTS_PER_ROUND: Mapping[int, int] = MappingProxyType({2: 400, 3: 1200, 4: 1200})
#: The variables the certifiable regression covers: its constraint points move the obstacle by
#: x and d (:func:`_moved`; P1 and P5 with it, y1 = d), as the range certificate's axes do
#: (``pipeline.build.config.BuildConfig.certifiable_refit``).
REFIT_VARIABLES: tuple[str, ...] = ("L", "W", "x", "d")


@dataclass(frozen=True)
class CertifiableFitConfig:
    """Settings of :func:`fit_certifiable`.

    Attributes:
        certificate: Settings of each round's range certificate but the last.
        final_certificate: Settings of the last round's (the returned map's); None: ``certificate``.
        endpoint: The endpoint constraint (tolerance and grid) of the regression.
        max_rounds: Rounds of certify -> add constraints -> refit.
        cushion_m: Clearance asked above the margin at the constraint points [m] (the margin
            must hold between them too).
        points_per_round: Cap on new clearance constraint points and on new endpoint targets per round.
        feasible_slack_m: Leaves whose end poses within the fit's endpoint tolerance keep less
            than margin + this (:func:`end_pose_room_m`, sampled at the leaf's centre) are not
            constrained [m]: the family cannot keep the margin there, or only just.
    """

    certificate: RangeCertificateConfig = field(default_factory=RangeCertificateConfig)
    final_certificate: RangeCertificateConfig | None = None
    endpoint: EndpointConstraint = field(default_factory=EndpointConstraint)
    max_rounds: int = 4
    cushion_m: float = 0.0
    points_per_round: int = 400
    feasible_slack_m: float = _DEFAULT_FEASIBLE_SLACK_M

    def __post_init__(self) -> None:
        if not isinstance(self.certificate, RangeCertificateConfig):
            raise InvalidParameterError("certificate", self.certificate, "a RangeCertificateConfig")
        if not isinstance(self.final_certificate, RangeCertificateConfig | None):
            raise InvalidParameterError("final_certificate", self.final_certificate, "a RangeCertificateConfig or None")
        check_positive_int("max_rounds", self.max_rounds)
        check_non_negative("cushion_m", self.cushion_m)
        check_positive_int("points_per_round", self.points_per_round)
        check_non_negative("feasible_slack_m", self.feasible_slack_m)


@dataclass(frozen=True, eq=False)
class ClearancePoints:
    """Points (v, s) where the refit must keep the clearance, with their T: v the coefficients'
    variables (L, W and any of x, d), s the normalised time.

    Attributes:
        points: (n, k + 1): the k variables' values [m], then s [-].
        duration_s: T [s], (n,) (of the path at x = 0: the moved path is a translate).
    """

    points: np.ndarray
    duration_s: np.ndarray


def clearance_points(coefficients: Coefficients, points: np.ndarray) -> ClearancePoints:
    """:class:`ClearancePoints` of ``points`` (n, k + 1): the coefficients' variables [m], then s [-],
    each with its T."""
    points = np.asarray(points, dtype=float)
    variables = coefficients.variables
    scene = coefficients.scene
    if variables.is_size_only:
        durations = np.array([desired_path(Obstacle.in_scene(L, W, scene), scene).duration_s for L, W in points[:, :2]])
    else:
        durations = targets_at(points[:, :-1], variables, scene, coefficients.link_lengths_m).duration_s
    return ClearancePoints(points, durations)


def clearance_grid(coefficients: Coefficients, sizes_m: np.ndarray, s: np.ndarray) -> ClearancePoints:
    """Every obstacle of ``sizes_m`` (n, k: the coefficients' variables [m]) at every normalised
    time of ``s`` (m,): n * m points, obstacle-major (reshape values to (n, m)), T computed once
    per obstacle."""
    k = coefficients.variables.k
    sizes = np.asarray(sizes_m, dtype=float).reshape(-1, k)
    s = np.asarray(s, dtype=float).ravel()
    per_obstacle = clearance_points(coefficients, np.column_stack([sizes, np.zeros(len(sizes))]))
    points = np.column_stack([np.repeat(sizes, s.size, axis=0), np.tile(s, len(sizes))])
    return ClearancePoints(points, np.repeat(per_obstacle.duration_s, s.size))


def _theta(parameters: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles (n, 2) and d theta_j / d (A_j, w_j, phi_j, gamma_j) (n, 2, 4) at times t (n,)."""
    A, w, phi, gamma = (parameters[:, i::4] for i in range(4))
    u = w * t[:, None] + phi
    theta = A * np.sin(u) + gamma
    d = np.stack([np.sin(u), A * t[:, None] * np.cos(u), A * np.cos(u), np.ones_like(u)], -1)
    return theta, d


def _design(coefficients: Coefficients, values: np.ndarray) -> np.ndarray:
    """The quadratic basis of the coefficients' variables at ``values`` (n, k) [m]; for (L, W)
    :func:`design_matrix`."""
    if coefficients.variables.is_size_only:
        return design_matrix(values[:, 0], values[:, 1])
    return coefficients.variables.design(values)


def _moved(coefficients: Coefficients, values: np.ndarray) -> dict[str, np.ndarray]:
    """The obstacle's centre x and far edge y [m] per row of ``values`` (n, k) where the
    coefficients vary them (``centre_x_m``, ``top_y_m``: keywords of
    :func:`configuration_clearance` and :func:`end_pose_room_m`); absent, the scene's."""
    variables = coefficients.variables
    moved = {}
    for name, keyword in (("x", "centre_x_m"), ("d", "top_y_m")):
        if name in variables.names:
            moved[keyword] = values[:, variables.index(name)]
    return moved


def _room(coefficients: Coefficients, values: np.ndarray, tolerance_m: float) -> np.ndarray:
    """:func:`end_pose_room_m` [m] of the obstacles at ``values`` (n, k) at ``tolerance_m`` [m]."""
    return end_pose_room_m(coefficients, values[:, 0], values[:, 1], tolerance_m, **_moved(coefficients, values))


def _point_clearance(theta: np.ndarray, values: np.ndarray, coefficients: Coefficients) -> np.ndarray:
    """Clearance [m] of ``theta`` (n, 2) against the obstacles at ``values`` (n, k)."""
    return configuration_clearance(theta, values, coefficients, **_moved(coefficients, values))


def clearance_at(b: np.ndarray, data: ClearancePoints, coefficients: Coefficients) -> np.ndarray:
    """Clearance [m] of the fit with coefficient matrix ``b`` (basis size x 8, row-major) at the points."""
    values = data.points[:, :-1]
    X = _design(coefficients, values)
    theta, _ = _theta(X @ np.reshape(b, (X.shape[1], 8)), data.points[:, -1] * data.duration_s)
    return _point_clearance(theta, values, coefficients)


def clearance_jacobian(b: np.ndarray, data: ClearancePoints, coefficients: Coefficients) -> np.ndarray:
    """d :func:`clearance_at` / d b, (n, 8 m): central differences in theta, closed form beyond."""
    values = data.points[:, :-1]
    X = _design(coefficients, values)
    m = X.shape[1]
    theta, d_theta = _theta(X @ np.reshape(b, (m, 8)), data.points[:, -1] * data.duration_s)
    grad = np.empty_like(theta)
    for j in (0, 1):
        step = np.zeros(2)
        step[j] = _FD_STEP_RAD
        up = _point_clearance(theta + step, values, coefficients)
        down = _point_clearance(theta - step, values, coefficients)
        grad[:, j] = (up - down) / (2 * _FD_STEP_RAD)
    d_p = (grad[:, :, None] * d_theta).reshape(len(theta), 8)  # joint-major = PARAMETER_NAMES order
    return np.einsum("np,nk->nkp", d_p, X).reshape(len(theta), 8 * m)


def worst_points(
    coefficients: Coefficients,
    region_map: RegionMap,
    limit: int,
    feasible_slack_m: float = _DEFAULT_FEASIBLE_SLACK_M,
    tolerance_m: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Clearance points (v, s) of the leaves that miss the margin without being infeasible
    and whose end poses leave room for it (:func:`end_pose_room_m` at ``tolerance_m``, default
    the map's endpoint tolerance, at least margin + ``feasible_slack_m`` at the leaf's centre;
    at most ``limit``, spread evenly over those leaves in lexicographic order of their centres:
    the lowest ``limit`` crowd into one corner and leave the rest of the strip to later rounds),
    and the centres v of leaves whose endpoint bound exceeds the tolerance, largest bound first
    (at most ``limit``); v the coefficients' variables."""
    centres = region_map.leaf_centres_m()
    failing = np.flatnonzero(
        (region_map.status == STATUSES.index("collision_free")) | (region_map.status == STATUSES.index("undecided"))
    )
    # Leaves whose end poses cannot keep the margin (sampled) are left out: the constraint
    # would be infeasible there.
    tolerance = region_map.endpoint_tolerance_m if tolerance_m is None else tolerance_m
    room = _room(coefficients, centres[failing], tolerance)
    failing = failing[room >= region_map.margin_m + feasible_slack_m]
    order = np.lexsort(centres[failing].T[::-1])
    chosen = failing[order[np.unique(np.linspace(0, order.size - 1, min(limit, order.size)).round().astype(np.int64))]]
    s = np.linspace(0.0, 1.0, _SAMPLES_S)
    data = clearance_points(coefficients, np.column_stack([centres[chosen], np.zeros(len(chosen))]))
    params = _design(coefficients, centres[chosen]) @ _matrix(coefficients)  # (n, 8)
    where = np.empty(len(chosen), dtype=np.int64)
    for chunk in range(0, len(chosen), _CHUNK_LEAVES):  # vectorised over leaves x samples
        rows = slice(chunk, chunk + _CHUNK_LEAVES)
        count = params[rows].shape[0]
        theta, _ = _theta(np.repeat(params[rows], _SAMPLES_S, 0), (data.duration_s[rows, None] * s).ravel())
        clearance = _point_clearance(theta, np.repeat(centres[chosen][rows], _SAMPLES_S, 0), coefficients)
        where[rows] = np.argmin(clearance.reshape(count, _SAMPLES_S), axis=1)
    worst = np.column_stack([centres[chosen], s[where]])
    loose = np.flatnonzero(region_map.endpoint_bound_m > region_map.endpoint_tolerance_m)
    loose = loose[np.argsort(-region_map.endpoint_bound_m[loose], kind="stable")][:limit]
    return worst, centres[loose]


def _merge_targets(grid: EndpointTargets, extra: EndpointTargets | None) -> EndpointTargets:
    return grid if extra is None else merge_targets(grid, extra)


def _targets_at(coefficients: Coefficients, centres: np.ndarray) -> EndpointTargets:
    """P1, P5 and T at ``centres`` (n, k) of the coefficients' variables."""
    scene = coefficients.scene
    if not coefficients.variables.is_size_only:
        return targets_at(centres, coefficients.variables, scene, coefficients.link_lengths_m)
    paths = [desired_path(Obstacle.in_scene(L, W, scene), scene) for L, W in centres]
    return EndpointTargets(
        centres[:, 0].copy(),
        centres[:, 1].copy(),
        np.array([p.points_m[0] for p in paths]),
        np.array([p.points_m[-1] for p in paths]),
        np.array([p.duration_s for p in paths]),
        tuple(coefficients.link_lengths_m),
    )


def _solve_refit(
    objective,
    b0: np.ndarray,
    X_grid: np.ndarray,
    targets: EndpointTargets,
    clearance: ClearancePoints,
    start: Coefficients,
    floor_m: float,
    config: CertifiableFitConfig,
) -> tuple[np.ndarray, bool]:
    """One SLSQP solve: least squares subject to the endpoint slack at ``targets`` (the
    endpoint constraint's fit tolerance) and clearance >= ``floor_m`` at the points; over k > 2
    variables in normalised variables (:mod:`pipeline.offline.coefficient_basis`)."""
    tolerance_m = config.endpoint.fit_tolerance_m
    constraints = [
        (
            lambda b: endpoint_slack(b, X_grid, targets, tolerance_m),
            lambda b: endpoint_slack_jacobian(b, X_grid, targets, tolerance_m),
        )
    ]
    if clearance.points.shape[0]:
        constraints.append(
            (
                lambda b: (clearance_at(b, clearance, start) - floor_m) * _CLEARANCE_SCALE,
                lambda b: clearance_jacobian(b, clearance, start) * _CLEARANCE_SCALE,
            )
        )
    box = np.array([start.fitted_range_m[name] for name in start.variables.names]).T  # (2, k): lo, hi
    options = {"maxiter": config.endpoint.max_iterations, "ftol": config.endpoint.ftol}
    result = solve_coefficients(objective, b0, constraints, options, normalised_basis(start.variables, box))
    return result.x, bool(result.success)


def refit(
    start: Coefficients,
    points: np.ndarray,
    values: Mapping[str, np.ndarray],
    targets: EndpointTargets,
    clearance: ClearancePoints,
    margin_m: float,
    config: CertifiableFitConfig,
) -> tuple[Coefficients, bool]:
    """One refit from ``start`` (module docstring, step 3): clearance >= margin + cushion at the
    points, or, if SLSQP cannot meet that (the cushion can be out of the family's reach where the
    margin barely is), >= the margin itself. ``points``: the DOE's runs (n, k) of the
    coefficients' variables [m]. Returns the coefficients and convergence."""
    X_data = _design(start, np.asarray(points, dtype=float))
    X_grid = targets.design()
    m = X_data.shape[1]
    Y = np.stack([np.asarray(values[name], dtype=float) for name in PARAMETER_NAMES], -1)

    def objective(b: np.ndarray) -> tuple[float, np.ndarray]:
        residual = X_data @ b.reshape(m, 8) - Y
        return float(np.sum(residual * residual)), (2.0 * X_data.T @ residual).ravel()

    b0 = np.stack([start.parameters[name] for name in PARAMETER_NAMES], -1).ravel()
    for cushion_m in dict.fromkeys((config.cushion_m, 0.0)):
        x, converged = _solve_refit(objective, b0, X_grid, targets, clearance, start, margin_m + cushion_m, config)
        if converged:
            break
    B = x.reshape(m, 8)
    parameters = {name: tuple(float(v) for v in B[:, i]) for i, name in enumerate(PARAMETER_NAMES)}
    return replace(start, parameters=parameters, source_sha256=""), converged


def _prefixed(progress: ProgressCallback | None, prefix: str) -> ProgressCallback | None:
    """``progress`` with ``prefix`` before each stage name (None stays None)."""
    if progress is None:
        return None
    return lambda stage, done, total: progress(prefix + stage, done, total)


def fit_certifiable(
    coefficients: Coefficients,
    points: np.ndarray,
    values: Mapping[str, np.ndarray],
    config: CertifiableFitConfig | None = None,
    progress: ProgressCallback | None = None,
) -> tuple[Coefficients, RegionMap, dict]:
    """Constraint generation (module docstring) from ``coefficients`` (e.g. the build's fit).

    Args:
        coefficients: The starting fit (paper family).
        points: The DOE's runs, (n, k): the coefficients' variables [m] (L, W and any of x, d).
        values: The DOE optima per parameter (canonical form), name -> (n,).
        config: Settings; default :class:`CertifiableFitConfig`.
        progress: Gets each round's certificate stages, prefixed "round k: ", and its refit.

    Returns:
        (the final coefficients, their region map, a report per round: area fractions, points,
        seconds). The returned coefficients carry no sha256 until saved; certify them again
        after saving to link a map to the file.

    Raises:
        InvalidParameterError: a family other than the paper's (all 8 parameters regressed).
    """
    config = config or CertifiableFitConfig()
    if tuple(coefficients.family.free_parameter_names) != PARAMETER_NAMES:
        raise InvalidParameterError("family", coefficients.family.name, "a family regressing all 8 parameters")
    margin = coefficients.scene.margin_m if config.certificate.margin_m is None else config.certificate.margin_m
    grid = endpoint_targets(
        coefficients.fitted_range_m,
        coefficients.scene,
        coefficients.link_lengths_m,
        config.endpoint.grid_points,
        coefficients.variables,
    )
    extra_targets: EndpointTargets | None = None
    collected = np.empty((0, coefficients.variables.k + 1))
    current = coefficients
    rounds = []
    final = config.final_certificate or config.certificate
    for round_index in range(config.max_rounds + 1):
        start = time.perf_counter()
        last = round_index == config.max_rounds
        settings = final if last else config.certificate
        round_progress = _prefixed(progress, f"round {round_index}: ")
        region_map = certify_range(current, settings, progress=round_progress)
        record = _round_record(round_index, region_map, settings, collected, extra_targets)
        new_points, loose = _round_points(current, region_map, config, collected.shape[1], last)
        rounds.append(record)
        if last or (new_points.shape[0] == 0 and loose.shape[0] == 0):
            if not last and final != config.certificate:  # clean early: final cells
                region_map = certify_range(current, final, progress=round_progress)
                record["final_area_fraction"] = region_map.summary()["area_fraction"]
                record["final_cells"] = _cells(final)
            break
        collected = np.vstack([collected, new_points])
        if loose.shape[0]:
            more = _targets_at(current, loose)
            extra_targets = more if extra_targets is None else _merge_targets(extra_targets, more)
        targets = _merge_targets(grid, extra_targets)
        candidate, converged, collected = _refit_holding(
            current, (points, values, targets), collected, margin, config, record
        )
        record["refit_converged"] = converged
        if not converged:  # SLSQP's last iterate need not satisfy anything: keep the certified fit
            record["stopped"] = "refit did not converge; the previous coefficients are returned"
            break
        current = candidate
        record["refit_seconds"] = time.perf_counter() - start - region_map.seconds
        record["grid_endpoint_error_max_m"] = float(
            endpoint_errors_m(targets.design() @ _matrix(current), targets).max()
        )
    return current, region_map, {"rounds": rounds}


def _round_record(
    round_index: int,
    region_map: RegionMap,
    settings: RangeCertificateConfig,
    collected: np.ndarray,
    extra_targets: EndpointTargets | None,
) -> dict:
    """The report of one round of :func:`fit_certifiable` as its certificate leaves it: the certified
    area fractions, the clearance points and endpoint targets held so far, the certificate's time [s]
    and its cells."""
    summary = region_map.summary()
    return {
        "round": round_index,
        "area_fraction": summary["area_fraction"],
        "endpoint_within_tolerance_fraction": summary["endpoint_within_tolerance_fraction"],
        "clearance_points": int(collected.shape[0]),
        "endpoint_targets": 0 if extra_targets is None else int(extra_targets.lengths_m.size),
        "certify_seconds": region_map.seconds,
        **_cells(settings),
    }


def _round_points(
    current: Coefficients, region_map: RegionMap, config: CertifiableFitConfig, columns: int, last: bool
) -> tuple[np.ndarray, np.ndarray]:
    """The round's new clearance points (rows of ``columns`` values: the variables [m], then s) and the
    variables [m] of its loose endpoints (:func:`worst_points`); none in the last round, whose map is
    the answer."""
    if last:
        return np.empty((0, columns)), np.empty((0, columns - 1))
    return worst_points(
        current, region_map, config.points_per_round, config.feasible_slack_m, config.endpoint.fit_tolerance_m
    )


def _refit_holding(
    current: Coefficients,
    data: tuple[np.ndarray, Mapping[str, np.ndarray], EndpointTargets],
    collected: np.ndarray,
    margin: float,
    config: CertifiableFitConfig,
    record: dict,
) -> tuple[Coefficients, bool, np.ndarray]:
    """:func:`refit` holding the clearance at the ``collected`` points above ``margin`` [m]; if it does
    not converge, retried without the points with least room (:data:`RETRY_SLACKS_M`), the slack
    used noted in the round's ``record``.

    Args:
        data: The DOE's runs, their optima per parameter and the endpoint targets, as :func:`refit` takes them.

    Returns:
        (the refit coefficients, whether the refit converged, the clearance points it held).
    """
    points, values, targets = data
    candidate, converged = refit(current, points, values, targets, clearance_points(current, collected), margin, config)
    room = None
    if not converged:
        room = _room(current, collected[:, :-1], config.endpoint.fit_tolerance_m)
    for slack in RETRY_SLACKS_M:  # the points with least room are the hardest to hold: retry without them
        if converged:
            break
        roomy = room >= margin + slack
        if not 0 < np.count_nonzero(roomy) < roomy.size:
            continue
        collected, room = collected[roomy], room[roomy]
        candidate, converged = refit(
            current, points, values, targets, clearance_points(current, collected), margin, config
        )
        record["retried_without_points_below_m"] = slack
    return candidate, converged, collected


def _cells(settings: RangeCertificateConfig) -> dict[str, float]:
    """The cell sizes a round's map was certified with, as the quadtree uses them (fractions of
    the fitted range's side, powers of 1/2)."""
    search = settings.search_settings(0.0)
    return {"min_cell": 2.0**-search.max_depth_lw, "boundary_cell": 2.0**-search.boundary_depth_lw}


def _matrix(coefficients: Coefficients) -> np.ndarray:
    return np.stack([coefficients.parameters[name] for name in PARAMETER_NAMES], -1)


def _fit_block(coefficients: Coefficients, doe: DoeData, report: dict, seconds_free_rounds: list[dict]) -> dict:
    """The coefficients file's ``fit`` block after the clearance refit: R^2 and residuals of the
    final coefficients, and the rounds (without their times, so that the file is reproducible)."""
    values = doe.free_parameters()
    fitted = _design(coefficients, doe.points) @ _matrix(coefficients)
    r_squared, max_residual = {}, {}
    for i, name in enumerate(PARAMETER_NAMES):
        residual = np.asarray(values[name], dtype=float) - fitted[:, i]
        r_squared[name] = coefficient_of_determination(np.asarray(values[name], dtype=float), residual)
        max_residual[name] = float(np.max(np.abs(residual)))
    block = dict(coefficients.extra.get("fit", {}))
    block.update(r_squared=r_squared, max_residual=max_residual)
    block["regression"] = f"{block.get('regression', 'least squares')} + clearance constraint generation"
    block["clearance_refit"] = {
        "rounds": seconds_free_rounds,
        "max_deviation_from_doe": float(max(max_residual.values())),
        "stopped": report.get("stopped", "map clean or round limit"),
    }
    return block


def refit_for_clearance(
    start: Coefficients,
    doe: DoeData,
    config: CertifiableFitConfig,
    source: str,
    progress: ProgressCallback | None = None,
) -> tuple[Coefficients, str, RegionMap, dict]:
    """Constraint generation (:func:`fit_certifiable`) from ``start`` (the build's
    endpoint-constrained fit of ``doe``, as read from its file text), in memory; ``progress``
    gets its rounds (:func:`fit_certifiable`).

    Returns:
        The refitted coefficients as they read back from their file text (their ``fit`` block
        records the rounds; ``source`` names the file they will be written to, their sha256 is
        that of the text), the text, their region map (linked to that sha256: the map was
        computed from exactly the parameters the text holds, which the read-back checks), and
        the rounds with their times.

    Raises:
        InvalidParameterError: the family is not the paper's.
        DataFileError: the text does not read back with the certified parameters.
    """
    fitted, region_map, report = fit_certifiable(start, doe.points, doe.free_parameters(), config, progress)
    timeless = [{k: v for k, v in r.items() if not k.endswith("_seconds")} for r in report["rounds"]]
    fitted = replace(fitted, extra={**fitted.extra, "fit": _fit_block(fitted, doe, report, timeless)})
    text = dumps(fitted.to_json())
    saved = coefficients_from_json(json.loads(text), source, hashlib.sha256(text.encode("utf-8")).hexdigest())
    if saved.parameters != fitted.parameters:
        raise DataFileError(source, "the coefficients' text differs from the certified ones")
    region_map = replace(region_map, coefficients_source=source_name(source), coefficients_sha256=saved.source_sha256)
    return saved, text, region_map, report


def clearance_refit_lines(report: dict) -> list[str]:
    """One line per round: area fractions before the round's refit, points, times."""
    lines = []
    for r in report["rounds"]:
        fractions = ", ".join(f"{name} {100 * value:.2f} %" for name, value in r["area_fraction"].items())
        refit = "" if "refit_seconds" not in r else f", refit {r['refit_seconds']:.1f} s"
        stopped = f" ({r['stopped']})" if "stopped" in r else ""
        lines.append(
            f"certifiable regression round {r['round']}: {fractions}; {r['clearance_points']} clearance points held, "
            f"{r['endpoint_targets']} endpoint targets; certificate (cells >= 1/{round(1 / r['min_cell'])}) "
            f"{r['certify_seconds']:.1f} s{refit}{stopped}"
        )
    return lines
