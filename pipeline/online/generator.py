"""The online generator: coefficients + (L, W) -> the trajectory, in microseconds.

Evaluating the regression is a 6-term polynomial per parameter; the only other work is the
path's duration T. Per query the generator does only what the answer needs, once:

1. check L and W (numbers, finite, positive, larger than the rounded corners, not covering
   the arm's base): one :class:`pipeline.exceptions.ObstacleSizeError` naming L and W otherwise;
2. P1..P5 from the scene and their radii against the arm's reach annulus;
3. the quartic's coefficients in closed form and T by the fixed Gauss-Legendre rule
   (:func:`pipeline.motion.path.symmetric_quartic`, :func:`pipeline.motion.path.symmetric_quartic_length_m`);
4. the regression (a precomputed (k, 6) matrix per coefficients object) and the family's expansion.

The answer's :class:`pipeline.model.obstacle.Obstacle` and :class:`pipeline.motion.path.QuarticPath`
are built only when asked for (lazily, then cached); their T equals the answer's to the last bit.
No URDF, Pinocchio or Coal is needed here: the arm's link lengths come from the coefficients file.
The certified bounds come from the region map attached to the coefficients
(:func:`pipeline.online.loading.load_coefficients`): a lookup in microseconds.
"""

from __future__ import annotations

import math
import warnings
import weakref
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np

from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import (
    InexactEndpointsWarning,
    InvalidParameterError,
    ObstacleSizeError,
    OutOfFittedRangeError,
    OutOfFittedRangeWarning,
    RegionMapMismatchError,
    UnreachableObstacleError,
)
from pipeline.model.kinematics import inverse_kinematics, reach_annulus_m
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.families import EndpointContext, TrajectoryFamily
from pipeline.motion.path import QuarticPath, desired_path, symmetric_quartic, symmetric_quartic_length_m
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.coefficients import Coefficients

OUT_OF_RANGE_POLICIES = ("warn", "error", "ignore")


@dataclass(frozen=True, eq=False)
class GeneratedTrajectory:
    """What the generator returns for one obstacle.

    Attributes:
        length_m, width_m: The obstacle's L, W [m].
        family: Trajectory family of the coefficients.
        scene: Scene of the coefficients.
        trajectory: The joint trajectory; ``trajectory.q(t)`` gives joint angles [rad].
        extrapolated: True if (L, W) lies outside the fitted range.
        reach_m: The reach annulus (min, max) [m] the constraint points were checked against.
        certified_clearance_m: Certified lower bound on the clearance of both links over all of
            [0, T] [m], from the region map of the coefficients (None without a map, or outside it).
        endpoint_error_bound_m: Certified upper bound on |tip(0) - P1| and |tip(T) - P5| [m] (same source).
        certificate_source: "range" if the two bounds come from the range certificate, else None.
        range_status: The map cell's status ("margin", "collision_free", "infeasible",
            "undecided"), or None.
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
    ) -> GeneratedTrajectory:
        """Build without the dataclass machinery, for :func:`generate`, which has checked everything."""
        answer = object.__new__(cls)
        answer.__dict__.update(
            length_m=length_m,
            width_m=width_m,
            family=family,
            scene=scene,
            trajectory=trajectory,
            extrapolated=extrapolated,
            reach_m=reach_m,
            certified_clearance_m=None if bounds is None else bounds[0],
            endpoint_error_bound_m=None if bounds is None else bounds[1],
            certificate_source=None if bounds is None else RANGE_SOURCE,
            range_status=None if bounds is None else bounds[2],
        )
        return answer

    @cached_property
    def obstacle(self) -> Obstacle:
        """The rounded box L x W placed as the scene says."""
        return Obstacle.in_scene(self.length_m, self.width_m, self.scene)

    @cached_property
    def path(self) -> QuarticPath:
        """The desired path around the obstacle; its ``duration_s`` is this answer's T."""
        return desired_path(self.obstacle, self.scene, self.reach_m)

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


class QueryPlan(NamedTuple):
    """What every query with one coefficients object shares, precomputed once: the regression
    matrix and the scene's numbers as plain floats (:func:`generate` and
    ``pipeline.online.batch.generate_batch`` read it through :func:`query_plan`)."""

    matrix_t: np.ndarray  # (6, k): the regression, basis (1, L, W, L^2, LW, W^2) -> free parameters
    l_range: tuple[float, float]
    w_range: tuple[float, float]
    reach: tuple[float, float]
    top: float
    y1: float
    start_dx: float
    approach_dx: float
    approach_dy: float
    apex_dy: float
    speed: float
    smallest: float  # smallest L and W: twice the corner radius [m]
    corner_radius: float
    height: float


_PLANS: weakref.WeakKeyDictionary[Coefficients, QueryPlan] = weakref.WeakKeyDictionary()


class _Attached:
    """The type of :data:`ATTACHED`."""

    def __repr__(self) -> str:
        return "ATTACHED"


#: ``region_map=ATTACHED`` (the default of :func:`generate`): the map attached to the coefficients.
ATTACHED = _Attached()


def _refuse_coefficients(coefficients: object) -> InvalidParameterError:
    return InvalidParameterError(
        "coefficients",
        coefficients if isinstance(coefficients, str | int | float | type(None)) else type(coefficients).__name__,
        "a Coefficients object from pipeline.load_coefficients(path)",
    )


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


def query_plan(coefficients: Coefficients) -> QueryPlan:
    """The :class:`QueryPlan` of ``coefficients``, built on first use and kept while they live.

    Raises:
        InvalidParameterError: ``coefficients`` is not a :class:`Coefficients` (e.g. a path).
    """
    if not isinstance(coefficients, Coefficients):
        raise _refuse_coefficients(coefficients)
    plan = _PLANS.get(coefficients)
    if plan is None:
        scene = coefficients.scene
        names = coefficients.family.free_parameter_names
        # The transposed view, as pipeline.offline.regression.predict uses: the same sums to the last bit.
        matrix = np.array([coefficients.parameters[name] for name in names], dtype=float)
        matrix.setflags(write=False)
        matrix = matrix.T
        plan = QueryPlan(
            matrix_t=matrix,
            l_range=tuple(coefficients.fitted_range_m["L"]),
            w_range=tuple(coefficients.fitted_range_m["W"]),
            reach=reach_annulus_m(coefficients.link_lengths_m),
            top=float(scene.top_y_m),
            y1=float(scene.y1_m),
            start_dx=float(scene.start_dx_m),
            approach_dx=float(scene.approach_dx_m),
            approach_dy=float(scene.approach_dy_m),
            apex_dy=float(scene.apex_dy_m),
            speed=float(scene.speed_m_s),
            smallest=2.0 * float(scene.corner_radius_m),
            corner_radius=float(scene.corner_radius_m),
            height=float(scene.obstacle_height_m),
        )
        _PLANS[coefficients] = plan
    return plan


def _size(value: object, size: tuple[object, object], name: str) -> float:
    """``value`` as a finite positive float, else ObstacleSizeError naming L and W."""
    if type(value) is not float:
        if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
            raise ObstacleSizeError(name, value, f"{name} a number in metres, not {type(value).__name__}", size)
        value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise ObstacleSizeError(name, value, f"{name} a positive finite number [m]", size)
    return value


def _check_range(plan: QueryPlan, length_m: float, width_m: float, policy: str) -> bool:
    outside = False
    for name, value, (lo, hi) in (("L", length_m, plan.l_range), ("W", width_m, plan.w_range)):
        if not lo <= value <= hi:
            outside = True
            if policy == "error":
                raise OutOfFittedRangeError(name, value, (lo, hi))
            if policy == "warn":
                warnings.warn(str(OutOfFittedRangeError(name, value, (lo, hi))), OutOfFittedRangeWarning, stacklevel=3)
    return outside


def generate(
    coefficients: Coefficients,
    length_m: float,
    width_m: float,
    *,
    out_of_range: str = "warn",
    region_map: RegionMap | _Attached | None = ATTACHED,
) -> GeneratedTrajectory:
    """The trajectory for the obstacle L x W [m] from regression coefficients.

    Args:
        coefficients: Loaded with :func:`pipeline.load_coefficients` (with their region map attached).
        length_m, width_m: Obstacle size [m] (int or float; not strings).
        out_of_range: What to do outside the fitted range: "warn" (an
            OutOfFittedRangeWarning), "error" (OutOfFittedRangeError) or "ignore".
        region_map: The range certificate to read the bounds from: :data:`ATTACHED` (default) the
            map attached to the coefficients (``coefficients.region_map``), None no bounds, or
            another map of these coefficients. Inside the fitted range the answer then carries
            its certified clearance and endpoint bounds (``certificate_source == "range"``),
            found in microseconds.

    Raises:
        InvalidParameterError: ``coefficients`` is not a :class:`Coefficients`; an unknown
            ``out_of_range`` policy.
        ObstacleSizeError (an InvalidParameterError): L or W not a number, not finite and positive,
            smaller than twice the corner radius, or W covering the arm's base; the message names L and W.
        UnreachableObstacleError: the path around this obstacle leaves the arm's reach.
        OutOfFittedRangeError: outside the fitted range with ``out_of_range="error"``.
        RegionMapMismatchError: ``region_map`` was made for other coefficients.
    """
    try:
        plan = _PLANS.get(coefficients)
    except TypeError:  # not weak-referenceable: not a Coefficients
        raise _refuse_coefficients(coefficients) from None
    if plan is None:
        plan = query_plan(coefficients)
    if region_map is ATTACHED:
        region_map = coefficients.region_map
    elif region_map is not None:
        check_region_map(region_map, coefficients)
    if out_of_range not in OUT_OF_RANGE_POLICIES:
        raise InvalidParameterError("out_of_range", out_of_range, f"one of {OUT_OF_RANGE_POLICIES}")
    L, W = length_m, width_m
    if type(L) is not float or type(W) is not float or not (0.0 < L < math.inf and 0.0 < W < math.inf):
        L = _size(length_m, (length_m, width_m), "L")
        W = _size(width_m, (length_m, width_m), "W")
    matrix_t, (l_lo, l_hi), (w_lo, w_hi), reach, top, y1 = plan[:6]
    start_dx, approach_dx, approach_dy, apex_dy, speed = plan[6:11]
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
    # P1, P2, P3 (P4, P5 mirror P2, P1: the same radii) and their distance from the base.
    x1, x2 = L / 2.0 + start_dx, L / 2.0 + approach_dx
    y2, y3 = bottom - approach_dy, bottom - apex_dy
    lo, hi = reach
    r1, r2, r3 = math.hypot(x1, y1), math.hypot(x2, y2), abs(y3)
    if not (lo <= r1 <= hi and lo <= r2 <= hi and lo <= r3 <= hi):
        name, radius = next((n, r) for n, r in (("P1", r1), ("P2", r2), ("P3", r3)) if not lo <= r <= hi)
        raise UnreachableObstacleError(name, radius, reach, size_m=(L, W))
    extrapolated = not (l_lo <= L <= l_hi and w_lo <= W <= w_hi)
    if extrapolated and out_of_range != "ignore":
        _check_range(plan, L, W, out_of_range)
    if x1 > x2 > 0.0:
        c4, c2, _ = symmetric_quartic(x1, y1, x2, y2, y3)
        duration = symmetric_quartic_length_m(x1, c4, c2) / speed
    else:  # approach_dx > start_dx: a scene the closed form does not cover
        duration = desired_path(Obstacle.in_scene(L, W, coefficients.scene), coefficients.scene).duration_s
    # The regression: (1, L, W, L^2, LW, W^2) @ B^T, as pipeline.offline.regression.predict (same bits).
    free = np.array([1.0, L, W, L * L, L * W, W * W]).dot(matrix_t)
    family = coefficients.family
    if family.uses_endpoint_context:
        full = _expand_with_endpoints(coefficients, free, x1, y1, duration, (L, W))
    else:
        full = family.expand(free, None)
    parameters = tuple(full.tolist())
    if not all(map(math.isfinite, parameters)):
        raise ObstacleSizeError("L, W", (L, W), "sizes at which the regression gives finite parameters", (L, W))
    bounds = None if region_map is None or extrapolated else region_map.bounds_at(L, W)
    return GeneratedTrajectory.trusted(
        L, W, family, coefficients.scene, JointTrajectory.trusted(parameters, duration), extrapolated, reach, bounds
    )


def _expand_with_endpoints(
    coefficients: Coefficients, free: np.ndarray, x1: float, y1: float, duration: float, size: tuple[float, float]
):
    """The 8 parameters of a family that needs the IK of P1 = (x1, y1) and P5 = (-x1, y1) and T."""
    family = coefficients.family
    start = inverse_kinematics((x1, y1), coefficients.link_lengths_m, coefficients.elbow)
    end = inverse_kinematics((-x1, y1), coefficients.link_lengths_m, coefficients.elbow)
    context = EndpointContext((float(start[0]), float(start[1])), (float(end[0]), float(end[1])), duration)
    full = family.expand(free, context)
    if family.pins_endpoints and not bool(family.endpoints_exact(free, context)):
        warnings.warn(
            f"L = {size[0]!r} m, W = {size[1]!r} m: the {family.name} family could not pin "
            "the tip to P1 and P5 for these parameters (A1 clamped); endpoints are approximate",
            InexactEndpointsWarning,
            stacklevel=3,
        )
    return full


def generate_parameters(coefficients: Coefficients, lengths_m: np.ndarray, widths_m: np.ndarray) -> np.ndarray:
    """Batched generator: the 8 parameters (n, 8) for n obstacles, equal to :func:`generate`'s.

    Where the family's parameters are the regression's alone, this is the regression,
    vectorised and without checks; a family that needs each obstacle's path and inverse
    kinematics calls :func:`generate` per obstacle (range checks off).
    """
    if not coefficients.family.uses_endpoint_context:
        return coefficients.predict_free(np.asarray(lengths_m, float), np.asarray(widths_m, float))
    pairs = zip(np.atleast_1d(lengths_m), np.atleast_1d(widths_m), strict=True)
    return np.array(
        [generate(coefficients, float(L), float(W), out_of_range="ignore").trajectory.parameters for L, W in pairs]
    )


#: ``certificate_source`` of an answer whose bounds come from the range certificate.
RANGE_SOURCE = "range"
