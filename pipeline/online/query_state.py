"""What the online queries of one coefficients object share: the query plan (the regression matrix
and the scene's numbers, precomputed for the compiled core), and, loaded on first use, the arm,
its recorded limits and its dynamics.

One :class:`QueryState` per :class:`pipeline.offline.coefficients.Coefficients` object, owned by it
(``coefficients.online_state``, made by :func:`state_of` on the first query and dropped with the
coefficients): no module-level cache holds any of it. A copy of the coefficients
(``dataclasses.replace``, a pickle) starts without one.
"""

from __future__ import annotations

import math
from functools import cached_property
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from pipeline.certify.lookup import NO_TABLES, LookupTables
from pipeline.exceptions import InvalidParameterError
from pipeline.model.kinematics import reach_annulus_m
from pipeline.model.scene import Scene
from pipeline.motion.path import LENGTH_RULE_POWERS, LENGTH_RULE_WEIGHTS
from pipeline.offline.coefficients import Coefficients
from pipeline.offline.variables import Variables
from pipeline.online.kernel import plan_numbers

if TYPE_CHECKING:  # the arm, its limits and dynamics need Pinocchio and Coal: imported on first use
    from pipeline.model.arm import PlanarArm
    from pipeline.model.dynamics import PlanarDynamics
    from pipeline.model.limits import ArmLimits

__all__ = ["QueryPlan", "QueryState", "refuse_coefficients", "state_of"]

#: The scene variables :func:`pipeline.online.generator.generate` takes by keyword, in the order of
#: its arguments.
GIVEN: tuple[str, str] = ("x", "d")


class QueryPlan(NamedTuple):
    """What every query with one coefficients object shares, precomputed once: the regression
    matrix and the scene's numbers as plain floats (:func:`pipeline.online.generator.generate` and
    :func:`pipeline.online.batch.generate_batch` read it as ``state_of(coefficients).plan``)."""

    matrix_t: np.ndarray  # (basis, k): the regression, basis (1, L, W, L^2, LW, W^2 over (L, W)) -> free parameters
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
    size_floor: float  # smallest, or inf where the obstacle's height is below it (every query is refused)
    corner_radius: float
    height: float
    variables: Variables
    extra: tuple[str, ...]  # the variables beyond L and W, () for the (L, W) route
    extra_ranges: tuple[tuple[float, float], ...]
    # What the route of coefficients over more variables (_generate_moved) reads:
    given_types: tuple[type, type]  # type(x), type(d) of a query that gives exactly the variables, as floats
    centre_x: float  # the scene's centre x [m], for coefficients that do not vary x
    y1_is_top: bool  # y1 = d (the scene's start_y_m is None): a value of d moves P1 and P5 too
    core: tuple  # the compiled core's arguments after the query's five numbers, before the map's tables
    fixed: tuple  # the core's arguments after L and W, before the map's tables, at the scene's own pose
    direct: bool  # the family's parameters are the regression's (its expand is the identity)


class QueryState:
    """What the queries of one coefficients object share (module docstring).

    Attributes:
        coefficients: The coefficients.
        plan: Their :class:`QueryPlan`.
    """

    def __init__(self, coefficients: Coefficients) -> None:
        self.coefficients = coefficients
        self.plan = _built_plan(coefficients)

    @cached_property
    def attached_tables(self) -> LookupTables:
        """The lookup arrays of the coefficients' attached map (checked when it was attached), built
        on first use; :data:`pipeline.certify.lookup.NO_TABLES` without one, or for a map over other
        axes than their variables."""
        region_map = self.coefficients.region_map
        if region_map is None or region_map.axes != self.plan.variables.names:
            return NO_TABLES
        return region_map.lookup_tables

    @cached_property
    def arm(self) -> PlanarArm:
        """The arm the coefficients were fitted with (:func:`pipeline.online.arm_check.arm_for`),
        loaded on first use."""
        from pipeline.online.arm_check import arm_for

        return arm_for(self.coefficients)

    @cached_property
    def limits(self) -> ArmLimits:
        """:meth:`ArmLimits.recorded` of :attr:`arm` and the coefficients' provenance."""
        from pipeline.model.limits import ArmLimits

        return ArmLimits.recorded(self.arm, self.coefficients.provenance)

    @cached_property
    def dynamics(self) -> PlanarDynamics:
        """The closed-form dynamics of :attr:`arm`, identified on first use."""
        from pipeline.model.dynamics import identify_dynamics

        return self.arm.derived(identify_dynamics)

    def limits_of(self, arm: PlanarArm) -> ArmLimits:
        """The recorded limits for ``arm``: :attr:`limits` when it is :attr:`arm`, else read anew."""
        if arm is self.__dict__.get("arm"):
            return self.limits
        from pipeline.model.limits import ArmLimits

        return ArmLimits.recorded(arm, self.coefficients.provenance)


def refuse_coefficients(coefficients: object) -> InvalidParameterError:
    """The error for a ``coefficients`` argument that is not a :class:`Coefficients`."""
    return InvalidParameterError(
        "coefficients",
        coefficients if isinstance(coefficients, str | int | float | type(None)) else type(coefficients).__name__,
        "a Coefficients object from pipeline.load_coefficients(path)",
    )


def state_of(coefficients: Coefficients) -> QueryState:
    """The :class:`QueryState` of ``coefficients``, made on first use and kept by them.

    Raises:
        InvalidParameterError: ``coefficients`` is not a :class:`Coefficients` (e.g. a path).
    """
    if not isinstance(coefficients, Coefficients):
        raise refuse_coefficients(coefficients)
    state = coefficients.online_state
    if state is None:
        state = QueryState(coefficients)
        object.__setattr__(coefficients, "online_state", state)  # owned by the (frozen) coefficients
    return state


def _built_plan(coefficients: Coefficients) -> QueryPlan:
    """The :class:`QueryPlan` of ``coefficients`` (checked: a Coefficients)."""
    scene = coefficients.scene
    names = coefficients.family.free_parameter_names
    # The transposed view (basis x free parameters), as pipeline.offline.regression.predict uses.
    matrix = np.array([coefficients.parameters[name] for name in names], dtype=float)
    matrix.setflags(write=False)
    matrix = matrix.T
    variables = coefficients.variables
    ranges = [tuple(coefficients.fitted_range_m[name]) for name in variables.names]
    core = _core_arguments(matrix, variables, scene, ranges, reach_annulus_m(coefficients.link_lengths_m))
    smallest, top, nan_pair = 2.0 * float(scene.corner_radius_m), float(scene.top_y_m), (math.nan, math.nan)
    plan = QueryPlan(
        matrix_t=matrix,
        l_range=tuple(coefficients.fitted_range_m["L"]),
        w_range=tuple(coefficients.fitted_range_m["W"]),
        reach=reach_annulus_m(coefficients.link_lengths_m),
        top=top,
        y1=float(scene.y1_m),
        start_dx=float(scene.start_dx_m),
        approach_dx=float(scene.approach_dx_m),
        approach_dy=float(scene.approach_dy_m),
        apex_dy=float(scene.apex_dy_m),
        speed=float(scene.speed_m_s),
        smallest=smallest,
        size_floor=smallest if float(scene.obstacle_height_m) >= smallest else math.inf,
        corner_radius=float(scene.corner_radius_m),
        height=float(scene.obstacle_height_m),
        variables=variables,
        extra=variables.extra,
        extra_ranges=tuple(tuple(coefficients.fitted_range_m[name]) for name in variables.extra),
        given_types=tuple(float if name in variables.extra else type(None) for name in GIVEN),
        centre_x=float(scene.centre_x_m),
        y1_is_top=scene.start_y_m is None,
        core=core,
        fixed=(float(scene.centre_x_m), top, float(scene.y1_m), *nan_pair, *core),
        direct=coefficients.family.expands_to_itself,
    )
    return plan


def _core_arguments(matrix_t: np.ndarray, variables: Variables, scene: Scene, ranges: list, reach: tuple) -> tuple:
    """The arguments of :func:`pipeline.online.kernel.query_core` that every query of one
    coefficients object shares: private arrays, writable only because Numba's dispatch of a
    read-only array costs twice as much (one compiled core serves every plan)."""
    terms, count = matrix_t.shape
    if terms != variables.basis_size or not 0 < count <= 8:  # the core reads exactly these sizes
        names = ", ".join(variables.names)
        raise InvalidParameterError(
            "coefficients' parameters",
            f"{count} parameters of {terms} terms",
            f"1 to 8 parameters of {variables.basis_size} terms each (the quadratic basis in {names})",
        )
    padded = np.zeros((matrix_t.shape[0], 8))
    padded[:, : matrix_t.shape[1]] = matrix_t
    scene_numbers = (scene.start_dx_m, scene.approach_dx_m, scene.approach_dy_m, scene.apex_dy_m, scene.speed_m_s)
    rule = np.vstack([LENGTH_RULE_POWERS, LENGTH_RULE_WEIGHTS])
    return variables.k, plan_numbers((*scene_numbers, *reach), np.array(ranges, dtype=float), padded, rule)
