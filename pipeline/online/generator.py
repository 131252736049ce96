"""The online generator: coefficients + (L, W) -> the trajectory, in microseconds.

Per query the generator checks its arguments in Python, then does all the arithmetic in one call
of a compiled core (:func:`pipeline.online.kernel.query_core`, Numba; called through its compiled
entry, :data:`pipeline.online.kernel.query_core_entry`, since the checks have made every argument
of the core's types):

1. check L and W (numbers, finite, positive, larger than the rounded corners, not covering
   the arm's base): one :class:`pipeline.exceptions.ObstacleSizeError` naming L and W otherwise;
2. in the core: P1..P5 from the scene and their radii against the arm's reach annulus; the
   quartic's coefficients in closed form and T by the path's fixed Gauss-Legendre rule
   (:func:`pipeline.motion.path.symmetric_quartic`, :func:`pipeline.motion.path.symmetric_quartic_length_m`);
   the regression (the basis times a precomputed matrix per coefficients object); and the
   leaf of the region map holding the query;
3. the family's expansion (the exact-endpoints family's inverse kinematics) and the answer.

The core evaluates the NumPy routes' formulas; only the order of two sums differs, so T and
the parameters equal those of :func:`pipeline.online.batch.generate_batch`,
:meth:`pipeline.offline.coefficients.Coefficients.predict_free` and
:class:`pipeline.motion.path.QuarticPath` to rounding, within the bounds that
:mod:`pipeline.online.kernel` derives (about 1e-14 in the parameters and 1e-13 s in T), which
the certificate's rounding slack covers. The leaf is the map's own, exactly.

The answer's :class:`pipeline.model.obstacle.Obstacle` and :class:`pipeline.motion.path.QuarticPath`
are built only when asked for (lazily, then cached). No URDF, Pinocchio or Coal is needed here:
the arm's link lengths come from the coefficients file. The certified bounds come from the region
map attached to the coefficients (:func:`pipeline.online.loading.load_coefficients`): a lookup in
the same call.

Coefficients over more scene variables than (L, W) (:mod:`pipeline.offline.variables`) take their
values by keyword: ``generate(coefficients, L, W, x=0.05)``. x moves the obstacle and its path
rigidly: P1..P5 shift by x, T is the x = 0 path's (the even quartic's closed form), the
regression is evaluated at (L, W, x), the exact-endpoints family's inverse kinematics takes the
shifted P1 and P5, and the answer's ``scene`` is the moved scene, built on first access (its
``obstacle`` and ``path`` follow it; that path's T, the general quartic's, agrees with the answer's to rounding). Their
region map is one over the same variables (:mod:`pipeline.certify.region_map`, axes e.g.
(L, W, x)): inside its box the answer carries the bounds of the leaf holding (L, W, x). The
answer's ``variables`` keeps the values, for the messages of later refusals. Coefficients over
(L, W) alone take a route without the variables' checks.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from pipeline.certify.region_map import STATUSES, RegionMap
from pipeline.exceptions import (
    InexactEndpointsWarning,
    InvalidParameterError,
    ObstacleSizeError,
    OutOfFittedRangeError,
    OutOfFittedRangeWarning,
    RegionMapMismatchError,
    UnreachableObstacleError,
)
from pipeline.model.kinematics import inverse_kinematics
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.families import EndpointContext, TrajectoryFamily
from pipeline.motion.path import QuarticPath, constraint_points, desired_path
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.coefficients import Coefficients
from pipeline.online.kernel import NO_TABLES, query_core_entry
from pipeline.online.query_state import QueryPlan, state_of

OUT_OF_RANGE_POLICIES = ("warn", "error", "ignore")


@dataclass(frozen=True, eq=False)
class GeneratedTrajectory:
    """What the generator returns for one obstacle.

    Attributes:
        length_m, width_m: The obstacle's L, W [m].
        family: Trajectory family of the coefficients.
        scene: Scene of the coefficients, with the values of their extra variables (e.g. the
            obstacle's centre x, ``scene.centre_x_m``) in place.
        trajectory: The joint trajectory; ``trajectory.q(t)`` gives joint angles [rad].
        extrapolated: True if (L, W), or the value of an extra variable, lies outside the fitted range.
        reach_m: The reach annulus (min, max) [m] the constraint points were checked against.
        certified_clearance_m: Certified lower bound on the clearance of both links over all of
            [0, T] [m], from the region map of the coefficients (None without a map, or outside it).
        endpoint_error_bound_m: Certified upper bound on |tip(0) - P1| and |tip(T) - P5| [m] (same source).
        certificate_source: "range" if the two bounds come from the range certificate, else None.
        range_status: The map cell's status ("margin", "collision_free", "infeasible",
            "undecided"), or None.
        variables: The values of the coefficients' variables beyond L and W as (name, value [m])
            pairs in canonical order (e.g. (("x", 0.02),)); () for coefficients over (L, W).
        obstacle: The obstacle (built on first access).
        path: The desired path (P1..P5, T; built on first access).
    """

    length_m: float
    width_m: float
    family: TrajectoryFamily
    scene: Scene
    trajectory: JointTrajectory
    extrapolated: bool
    reach_m: tuple[float, float] | None = field(default=None, repr=False)
    certified_clearance_m: float | None = None
    endpoint_error_bound_m: float | None = None
    certificate_source: str | None = None
    range_status: str | None = None
    variables: tuple[tuple[str, float], ...] = ()

    @classmethod
    def trusted(
        cls,
        length_m: float,
        width_m: float,
        family: TrajectoryFamily,
        scene: Scene,
        trajectory: JointTrajectory,
        extrapolated: bool,
        reach_m: tuple[float, float] | None,
        bounds: tuple[float, float, str] | None = None,
        variables: tuple[tuple[str, float], ...] = (),
        moved: bool = False,
    ) -> GeneratedTrajectory:
        """Build without the dataclass machinery, for :func:`generate`, which has checked everything
        (``bounds``: clearance bound [m], endpoint bound [m] and status of the map's leaf, or None).
        With ``moved`` ``scene`` is the coefficients' scene, and the answer's scene, with the
        ``variables``' values in place, is built on first access."""
        answer = object.__new__(cls)
        fields = answer.__dict__  # fields left out keep their class defaults (None, ())
        fields["length_m"] = length_m
        fields["width_m"] = width_m
        fields["family"] = family
        fields["_unmoved_scene" if moved else "scene"] = scene
        fields["trajectory"] = trajectory
        fields["extrapolated"] = extrapolated
        fields["reach_m"] = reach_m
        if bounds is not None:
            fields["certified_clearance_m"], fields["endpoint_error_bound_m"], fields["range_status"] = bounds
            fields["certificate_source"] = RANGE_SOURCE
        if variables:
            fields["variables"] = variables
        return answer

    def __getattr__(self, name: str):
        """``scene`` of an answer built with ``moved`` (:meth:`trusted`), built on first access:
        the coefficients' scene with the values of ``variables`` in place."""
        fields = self.__dict__
        if name == "scene" and "_unmoved_scene" in fields:
            values = dict(fields["variables"])
            scene = fields["_unmoved_scene"].with_checked(centre_x_m=values.get("x"), top_y_m=values.get("d"))
            fields["scene"] = scene
            return scene
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def centre_x_m(self) -> float:
        """x of the obstacle's centre [m] (the x given to :func:`generate`, 0 without one)."""
        return self.scene.centre_x_m

    @cached_property
    def obstacle(self) -> Obstacle:
        """The rounded box L x W placed as the scene says."""
        return Obstacle.in_scene(self.length_m, self.width_m, self.scene)

    @cached_property
    def path(self) -> QuarticPath:
        """The desired path around the obstacle; its ``duration_s`` is this answer's T (to rounding
        for an obstacle moved by x, whose path is the general quartic's)."""
        return desired_path(self.obstacle, self.scene, self.reach_m)

    @cached_property
    def end_points_m(self) -> np.ndarray:
        """P1 and P5, where the path starts and ends [m], (2, 2): the path's first and last
        constraint points, without building the path."""
        return constraint_points(self.obstacle, self.scene)[[0, -1]]

    @property
    def duration_s(self) -> float:
        """T [s]."""
        return self.trajectory.duration_s

    def q(self, t_s, *, outside: str = "error"):
        """Joint angles [rad] at t [s] (see :meth:`JointTrajectory.q`)."""
        return self.trajectory.q(t_s, outside=outside)

    def dq(self, t_s, *, outside: str = "error"):
        """Joint velocities [rad/s] at t [s] (see :meth:`JointTrajectory.dq`)."""
        return self.trajectory.dq(t_s, outside=outside)

    def ddq(self, t_s, *, outside: str = "error"):
        """Joint accelerations [rad/s^2] at t [s] (see :meth:`JointTrajectory.ddq`)."""
        return self.trajectory.ddq(t_s, outside=outside)


class _Attached:
    """The type of :data:`ATTACHED`."""

    def __repr__(self) -> str:
        return "ATTACHED"


#: ``region_map=ATTACHED`` (the default of :func:`generate`): the map attached to the coefficients.
ATTACHED = _Attached()


def check_region_map(region_map: object, coefficients: Coefficients) -> None:
    """Refuse a ``region_map=`` argument that is not a map of exactly these coefficients.

    Raises:
        InvalidParameterError: not a :class:`RegionMap`.
        RegionMapMismatchError: a map of other coefficients.
    """
    if not isinstance(region_map, RegionMap):
        raise InvalidParameterError("region_map", type(region_map).__name__, "a RegionMap, ATTACHED or None")
    if not region_map.belongs_to(coefficients):
        raise RegionMapMismatchError(region_map.coefficients_sha256, coefficients.source_sha256)


def _size(value: object, size: tuple[object, object], name: str) -> float:
    """``value`` as a finite positive float, else ObstacleSizeError naming L and W."""
    if type(value) is not float:
        if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
            raise ObstacleSizeError(name, value, f"{name} a number in metres, not {type(value).__name__}", size)
        value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise ObstacleSizeError(name, value, f"{name} a positive finite number [m]", size)
    return value


def _check_range(
    plan: QueryPlan, length_m: float, width_m: float, policy: str, extra: tuple = (), stacklevel: int = 3
) -> bool:
    """True if a value lies outside its fitted range; raises or warns (attributed ``stacklevel``
    frames up: :func:`generate`'s caller) as ``policy`` says."""
    outside = False
    checks = (("L", length_m, plan.l_range), ("W", width_m, plan.w_range), *extra)
    for name, value, (lo, hi) in checks:
        if not lo <= value <= hi:
            outside = True
            if policy == "error":
                raise OutOfFittedRangeError(name, value, (lo, hi))
            if policy == "warn":
                message = str(OutOfFittedRangeError(name, value, (lo, hi)))
                warnings.warn(message, OutOfFittedRangeWarning, stacklevel=stacklevel)
    return outside


def _checked_bottom(plan, L: float, W: float, top: float) -> float:
    """d - W, the y of the obstacle's near edge [m], after refusing an obstacle smaller than its
    rounded corners or one that covers the arm's base (ObstacleSizeError naming L and W)."""
    smallest = plan.smallest
    if L < smallest or W < smallest or plan.height < smallest:
        raise ObstacleSizeError(
            "L, W",
            (L, W),
            f"L and W at least twice the obstacle's corner radius, 2 x {plan.corner_radius!r} = {smallest!r} m",
            (L, W),
        )
    bottom = top - W
    if bottom <= 0.0 <= top:
        raise ObstacleSizeError(
            "W", W, f"W less than d = {top!r} m: at this width the obstacle covers the arm's base", (L, W)
        )
    return bottom


def generate(
    coefficients: Coefficients,
    length_m: float,
    width_m: float,
    *,
    x: float | None = None,
    d: float | None = None,
    out_of_range: str = "warn",
    region_map: RegionMap | _Attached | None = ATTACHED,
) -> GeneratedTrajectory:
    """The trajectory for the obstacle L x W [m] from regression coefficients.

    Args:
        coefficients: Loaded with :func:`pipeline.load_coefficients` (with their region map attached).
        length_m, width_m: Obstacle size [m] (int or float; not strings).
        x, d: The obstacle's centre x and far edge y (``Scene.top_y_m``) [m], for coefficients that
            vary them (``coefficients.variables``): required for those, refused for others.
        out_of_range: Outside the fitted range: "warn" (OutOfFittedRangeWarning), "error"
            (OutOfFittedRangeError) or "ignore".
        region_map: Where the bounds come from: :data:`ATTACHED` (default) ``coefficients.region_map``,
            None no bounds, or another map of these coefficients. Inside its box the answer carries
            its certified clearance and endpoint bounds (``certificate_source == "range"``).

    Raises:
        InvalidParameterError: ``coefficients`` not a :class:`Coefficients`; an unknown policy; a
            variable of theirs without a finite value, or a value for one they do not vary.
        ObstacleSizeError (an InvalidParameterError): L or W not a finite positive number, below twice
            the corner radius, or W covering the arm's base (the message names L and W).
        UnreachableObstacleError: the path around this obstacle leaves the arm's reach.
        OutOfFittedRangeError: outside the fitted range with ``out_of_range="error"``.
        RegionMapMismatchError: ``region_map`` was made for other coefficients.
    """
    try:
        state = coefficients.online_state
        plan = state.plan
    except AttributeError:  # a first query (or not a Coefficients: refused)
        state = state_of(coefficients)
        plan = state.plan
    if region_map is ATTACHED or region_map is coefficients.region_map:  # checked when it was attached
        tables = state.attached_tables
    elif region_map is None:
        tables = NO_TABLES
    else:
        tables = _given_tables(coefficients, plan, region_map)
    if out_of_range not in OUT_OF_RANGE_POLICIES:
        raise InvalidParameterError("out_of_range", out_of_range, f"one of {OUT_OF_RANGE_POLICIES}")
    if plan.extra or x is not None or d is not None:
        fixed, values = _placed(plan, x, d)
    else:  # coefficients over (L, W) alone: the scene's own pose
        fixed, values = plan.fixed, ()
    L, W = length_m, width_m
    if type(L) is not float or type(W) is not float or not (0.0 < L < math.inf and 0.0 < W < math.inf):
        L = _size(length_m, (length_m, width_m), "L")
        W = _size(width_m, (length_m, width_m), "W")
    if not L >= plan.size_floor <= W < fixed[1]:  # else the full check (W < d: d - W > 0 for floats)
        _checked_bottom(plan, L, W, fixed[1])
    result = query_core_entry(L, W, *fixed, *tables)  # every argument of the core's types, checked above
    unreachable, _, duration, inside, leaf, clearance, endpoint, status, parameters, finite = result
    if unreachable >= 0 or not (inside and finite and plan.direct) or duration != duration or values:
        return _answer_of(coefficients, plan, result, L, W, fixed, values, out_of_range)
    answer = object.__new__(GeneratedTrajectory)
    fields = answer.__dict__  # as GeneratedTrajectory.trusted fills it, without a call
    fields["length_m"] = L
    fields["width_m"] = W
    fields["family"] = coefficients.family
    fields["scene"] = coefficients.scene
    fields["trajectory"] = JointTrajectory.trusted(parameters, duration)
    fields["extrapolated"] = False
    fields["reach_m"] = plan.reach
    if leaf >= 0:
        fields["certified_clearance_m"] = clearance
        fields["endpoint_error_bound_m"] = endpoint
        fields["range_status"] = STATUSES[status]
        fields["certificate_source"] = RANGE_SOURCE
    return answer


def _answer_of(
    coefficients: Coefficients,
    plan: QueryPlan,
    result: tuple,
    L: float,
    W: float,
    fixed: tuple,
    values: tuple[float, ...],
    out_of_range: str,
) -> GeneratedTrajectory:
    """The answer of a query that :func:`generate`'s common route does not cover, from the core's
    ``result`` for L, W [m] and its arguments ``fixed``: an unreachable point (refused), outside the
    fitted range (refused or warned as ``out_of_range`` says, attributed to :func:`generate`'s
    caller), T by the general path where the closed form does not apply, a family that expands its
    parameters, parameters that are not finite (refused), or ``values`` of extra variables."""
    unreachable, radius, duration, inside, leaf, clearance, endpoint, status, parameters, finite = result
    if unreachable >= 0:  # P4 and P5 mirror P2 and P1: the first of P1..P3 to fail is named
        raise _unreachable(plan, unreachable, radius, (L, W), values)
    extrapolated = not inside
    if extrapolated and out_of_range != "ignore":
        extra = tuple(zip(plan.extra, values, plan.extra_ranges, strict=True))
        _check_range(plan, L, W, out_of_range, extra, stacklevel=4)  # _check_range, here, generate, its caller
    c, top, y1 = fixed[:3]
    if duration != duration:  # NaN: approach_dx > start_dx, a scene the closed form does not cover
        centred = coefficients.scene.with_checked(centre_x_m=0.0, top_y_m=top)  # T does not depend on x
        duration = desired_path(Obstacle.in_scene(L, W, centred), centred).duration_s
    family = coefficients.family
    if not family.expands_to_itself:
        parameters = _expanded(coefficients, plan, parameters, duration, c, y1, (L, W, *values))
        finite = all(map(math.isfinite, parameters))
    if not finite:
        raise ObstacleSizeError("L, W", (L, W), "sizes at which the regression gives finite parameters", (L, W))
    bounds = None if leaf < 0 else (clearance, endpoint, STATUSES[status])
    trajectory, placed = JointTrajectory.trusted(parameters, duration), (plan.reach, bounds)
    if not values:
        return GeneratedTrajectory.trusted(L, W, family, coefficients.scene, trajectory, extrapolated, *placed)
    # One variable without zip: tuple(zip(..., strict=True)) costs about 1 us here, a tenth of a query.
    variables = ((plan.extra[0], values[0]),) if len(values) == 1 else tuple(zip(plan.extra, values, strict=True))
    return GeneratedTrajectory.trusted(
        L, W, family, coefficients.scene, trajectory, extrapolated, *placed, variables, moved=True
    )


def _given_tables(coefficients: Coefficients, plan: QueryPlan, region_map: object):
    """The lookup arrays of a map given in place of the attached one (:data:`NO_TABLES` for a map
    over other axes), after checking it.

    Raises:
        InvalidParameterError: ``region_map`` is not a :class:`RegionMap`.
        RegionMapMismatchError: ``region_map`` was made for other coefficients.
    """
    check_region_map(region_map, coefficients)
    return NO_TABLES if region_map.axes != plan.variables.names else region_map.lookup_tables


def _unreachable(plan: QueryPlan, point: int, radius: float, size: tuple[float, float], values: tuple):
    """The error for a query whose ``point`` (0-based: P1..P3) lies ``radius`` [m] from the base,
    outside the reach annulus; the message names the extra variables' ``values`` too."""
    variables = dict(zip(plan.extra, values, strict=True))
    return UnreachableObstacleError(f"P{point + 1}", radius, plan.reach, size_m=size, variables=variables)


def _expand_with_endpoints(
    coefficients: Coefficients,
    free: np.ndarray,
    start: tuple[float, float],
    end: tuple[float, float],
    duration: float,
    size: tuple[float, ...],
    names: tuple[str, ...] = ("L", "W"),
):
    """The 8 parameters of a family that needs the IK of P1 = ``start`` and P5 = ``end`` and T
    (``size``: the values of the variables ``names``, for the warning)."""
    family = coefficients.family
    start = inverse_kinematics(start, coefficients.link_lengths_m, coefficients.elbow)
    end = inverse_kinematics(end, coefficients.link_lengths_m, coefficients.elbow)
    context = EndpointContext((float(start[0]), float(start[1])), (float(end[0]), float(end[1])), duration)
    full = family.expand(free, context)
    if family.pins_endpoints and not bool(family.endpoints_exact(free, context)):
        where = ", ".join(f"{name} = {value!r} m" for name, value in zip(names, size, strict=True))
        warnings.warn(
            f"{where}: the {family.name} family could not pin "
            "the tip to P1 and P5 for these parameters (A1 clamped); endpoints are approximate",
            InexactEndpointsWarning,
            stacklevel=5,  # this, _expanded, _answer_of, generate: its caller
        )
    return full


def _expanded(
    coefficients: Coefficients,
    plan: QueryPlan,
    columns: tuple[float, ...],
    duration: float,
    centre_x: float,
    y1: float,
    values: tuple[float, ...],
) -> tuple[float, ...]:
    """The 8 parameters of a family whose :meth:`expand` is not the identity, from the core's
    ``columns``: with the inverse kinematics of P1 and P5 (at ``centre_x`` +- x1, height ``y1``
    [m]) and T where the family needs them (``values`` of the coefficients' variables, for the warning)."""
    family = coefficients.family
    free = np.array(columns[: plan.matrix_t.shape[1]])
    if family.uses_endpoint_context:
        x1 = values[0] / 2.0 + plan.start_dx
        start, end = (x1 + centre_x, y1), (-x1 + centre_x, y1)
        full = _expand_with_endpoints(coefficients, free, start, end, duration, values, plan.variables.names)
    else:
        full = family.expand(free, None)
    return tuple(full.tolist())


def _variable(value: object, name: str) -> float:
    """An extra variable's value as a finite float, else InvalidParameterError naming it."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidParameterError(name, value, f"{name} a number in metres, not {type(value).__name__}")
    value = float(value)
    if not math.isfinite(value):
        raise InvalidParameterError(name, value, f"{name} a finite number [m]")
    return value


def _extra_values(plan: QueryPlan, x: object, d: object) -> tuple[float | None, float | None]:
    """The values of x and d [m] as finite floats where the coefficients vary them, else None; a
    missing, unexpected or non-numeric one is refused by
    :meth:`pipeline.offline.variables.Variables.take` and :func:`_variable`, naming it."""
    values = {name: _variable(value, name) for name, value in plan.variables.take({"x": x, "d": d}).items()}
    return values.get("x"), values.get("d")


def _placed(plan: QueryPlan, x: object, d: object) -> tuple[tuple, tuple[float, ...]]:
    """The core's arguments after L and W and before the map's arrays for a query giving ``x`` and
    ``d`` (the obstacle's centre x, far edge d and the height y1 of P1 and P5 [m], the regression's
    variables past L and W, then the plan's), and the values of the coefficients' extra variables
    in their canonical order (``plan.extra``); values missing for a variable of the coefficients,
    given for one they do not vary, or not finite numbers are refused (:func:`_extra_values`)."""
    if not (
        (type(x), type(d)) == plan.given_types
        and (x is None or -math.inf < x < math.inf)
        and (d is None or -math.inf < d < math.inf)
    ):  # not finite floats for exactly the coefficients' variables: converted, or refused
        x, d = _extra_values(plan, x, d)
    values = (x,) if d is None else (d,) if x is None else (x, d)  # in canonical order, as plan.extra
    top = plan.top if d is None else d
    beyond = (*values, math.nan, math.nan)  # the regression's variables past the obstacle's size
    pose = (plan.centre_x if x is None else x, top, top if plan.y1_is_top else plan.y1, beyond[0], beyond[1])
    return (*pose, *plan.core), values


def generate_parameters(
    coefficients: Coefficients,
    lengths_m: np.ndarray,
    widths_m: np.ndarray,
    *,
    x: np.ndarray | None = None,
    d: np.ndarray | None = None,
) -> np.ndarray:
    """Batched generator: the 8 parameters (n, 8) for n obstacles, equal to :func:`generate`'s to rounding
    (``x``, ``d``: as there, one value per obstacle).

    Where the family's parameters are the regression's alone, this is the regression,
    vectorised and without checks; a family that needs each obstacle's path and inverse
    kinematics calls :func:`generate` per obstacle (range checks off).
    """
    if not coefficients.family.uses_endpoint_context:
        if x is None and d is None:
            return coefficients.predict_free(np.asarray(lengths_m, float), np.asarray(widths_m, float))
        extra = {name: v for name, v in (("x", x), ("d", d)) if v is not None}
        return coefficients.predict_free(np.asarray(lengths_m, float), np.asarray(widths_m, float), **extra)
    if x is None and d is None:
        pairs = zip(np.atleast_1d(lengths_m), np.atleast_1d(widths_m), strict=True)
        return np.array(
            [generate(coefficients, float(L), float(W), out_of_range="ignore").trajectory.parameters for L, W in pairs]
        )
    extra = coefficients.variables.take({"x": x, "d": d})
    rows = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, float)) for v in (lengths_m, widths_m, *extra.values())))
    return np.array(
        [
            generate(
                coefficients, L, W, out_of_range="ignore", **dict(zip(extra, values, strict=True))
            ).trajectory.parameters
            for L, W, *values in zip(*(row.tolist() for row in rows), strict=True)
        ]
    )


#: ``certificate_source`` of an answer whose bounds come from the range certificate.
RANGE_SOURCE = "range"
