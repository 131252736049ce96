"""What the family can reach where the region map is neither ``margin`` nor ``infeasible``.

The infeasibility certificate (``pipeline.certify.endpoints``) looks only at the end poses, so
a cell can be out of the family's reach (no sinusoid per joint both ends within the tolerance
and keeps the margin along the whole motion) without being proven so. For one obstacle
(L, W) this module searches the family directly:

    maximise z over the 8 parameters p and z  subject to
    c_j(theta(t_k; p)) >= z  for both links j and K uniform times t_k in [0, T],
    |tip(0) - P1| <= tolerance,  |tip(T) - P5| <= tolerance,

by SLSQP from the regression's parameters at (L, W) (a local search, holding 0.999 of the
tolerance so that its last iterate, checked afterwards, meets the tolerance). The trajectory it ends
with is then certified in continuous time (``pipeline.geometry.sinusoid_certificate``, analytic
route), and its endpoint errors are recomputed, so the figure reported is a true lower bound on
that trajectory's clearance: a *witness* that at least that much is reachable at (L, W) with
the tolerance. Where it stays below the margin, the local search found no trajectory that keeps
it: evidence, not a proof, that the cell is out of the family's reach.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from pipeline.certify.region_map import STATUSES, RegionMap
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import ANALYTIC, link_segments, segment_rectangle_distance
from pipeline.geometry.sinusoid_certificate import certify_trajectory
from pipeline.model.arm import PlanarArm
from pipeline.model.kinematics import forward_kinematics
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import desired_path
from pipeline.motion.trajectory import PARAMETER_NAMES, JointTrajectory
from pipeline.offline.coefficients import Coefficients
from pipeline.validation import check_positive, check_positive_int

_SEARCH_SAMPLES = 241
_MAX_ITERATIONS = 300
#: The search holds this fraction of the tolerance, so that an SLSQP iterate that ends a hair
#: outside its constraints (it stops on a line-search failure as often as on convergence)
#: still meets the tolerance itself.
_INSIDE = 0.999


@dataclass(frozen=True)
class Witness:
    """The best trajectory the local search found at one obstacle.

    Attributes:
        length_m, width_m: The obstacle [m].
        regression_clearance_m: Certified clearance of the coefficients' own trajectory [m].
        clearance_m: Certified clearance of the trajectory found [m] (a lower bound over [0, T]).
        endpoint_errors_m: |tip(0) - P1| and |tip(T) - P5| of the trajectory found [m].
        parameters: Its 8 parameters (:data:`PARAMETER_NAMES` order).
        within_tolerance: Both endpoint errors within the tolerance (False only if neither the
            search nor the coefficients' own trajectory met it: then it is no witness).
    """

    length_m: float
    width_m: float
    regression_clearance_m: float
    clearance_m: float
    endpoint_errors_m: tuple[float, float]
    parameters: tuple[float, ...]
    within_tolerance: bool = True

    def to_json(self) -> dict:
        """Plain JSON (lengths in m)."""
        return {
            "L_m": self.length_m,
            "W_m": self.width_m,
            "regression_clearance_m": self.regression_clearance_m,
            "clearance_m": self.clearance_m,
            "endpoint_errors_m": list(self.endpoint_errors_m),
            "parameters": dict(zip(PARAMETER_NAMES, self.parameters, strict=True)),
            "within_tolerance": self.within_tolerance,
        }


def _theta(parameters: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Joint angles (K, 2) of the 8 parameters at times t (K,)."""
    A, w, phi, gamma = (parameters[i::4] for i in range(4))
    return A * np.sin(w * t[:, None] + phi) + gamma


def _link_clearances(theta: np.ndarray, obstacle: Obstacle, arm: PlanarArm) -> np.ndarray:
    """Clearance of each link (K, 2) [m] against the rounded box (analytic route)."""
    elbow, tip = link_segments(theta, arm.link_lengths_m)
    r = obstacle.corner_radius_m
    center = np.broadcast_to(np.asarray(obstacle.center_m, dtype=float)[:2], elbow.shape)
    half = np.broadcast_to(np.array([obstacle.length_m / 2 - r, obstacle.width_m / 2 - r]), elbow.shape)
    c1 = segment_rectangle_distance(np.zeros_like(elbow), elbow, center, half) - arm.link_radii_m[0]
    c2 = segment_rectangle_distance(elbow, tip, center, half) - arm.link_radii_m[1]
    return np.stack([c1, c2], -1) - r


def _certified(parameters: np.ndarray, duration_s: float, arm: PlanarArm, obstacle: Obstacle) -> float:
    trajectory = JointTrajectory(tuple(float(v) for v in parameters), float(duration_s))
    return float(certify_trajectory(trajectory, arm, obstacle, route=ANALYTIC, tolerance_m=1e-5).certified_clearance_m)


def best_clearance_at(
    coefficients: Coefficients, arm: PlanarArm, length_m: float, width_m: float, tolerance_m: float
) -> Witness:
    """The local search of the module docstring at one obstacle (paper family coefficients).

    Raises:
        InvalidParameterError: a non-positive tolerance, or a family that does not regress all 8
            parameters.
    """
    check_positive("tolerance_m", tolerance_m)
    if tuple(coefficients.family.free_parameter_names) != PARAMETER_NAMES:
        raise InvalidParameterError("family", coefficients.family.name, "a family regressing all 8 parameters")
    scene = coefficients.scene
    obstacle = Obstacle.in_scene(length_m, width_m, scene)
    path = desired_path(obstacle, scene)
    ends = np.array([path.points_m[0], path.points_m[-1]])
    duration = path.duration_s
    times = np.linspace(0.0, duration, _SEARCH_SAMPLES)
    start = np.asarray(coefficients.predict_free(length_m, width_m), dtype=float).ravel()

    def clearance_rows(x: np.ndarray) -> np.ndarray:
        return (_link_clearances(_theta(x[:8], times), obstacle, arm) - x[8]).ravel() * 100.0

    def endpoint_rows(x: np.ndarray) -> np.ndarray:
        tips = forward_kinematics(_theta(x[:8], np.array([0.0, duration])), arm.link_lengths_m)
        return 1.0 - np.sum((tips - ends) ** 2, -1) / (_INSIDE * tolerance_m) ** 2

    z0 = float(_link_clearances(_theta(start, times), obstacle, arm).min())
    result = minimize(
        lambda x: -100.0 * x[8],
        np.append(start, z0),
        jac=lambda x: np.append(np.zeros(8), -100.0),
        method="SLSQP",
        constraints=[{"type": "ineq", "fun": clearance_rows}, {"type": "ineq", "fun": endpoint_rows}],
        options={"maxiter": _MAX_ITERATIONS, "ftol": 1e-10},
    )
    found = result.x[:8]
    errors = np.linalg.norm(
        forward_kinematics(_theta(found, np.array([0.0, duration])), arm.link_lengths_m) - ends, axis=-1
    )
    if errors.max() > tolerance_m:  # the search ended outside the tolerance: report the regression's trajectory
        found = start
        errors = np.linalg.norm(
            forward_kinematics(_theta(found, np.array([0.0, duration])), arm.link_lengths_m) - ends, axis=-1
        )
    return Witness(
        length_m=float(length_m),
        width_m=float(width_m),
        regression_clearance_m=_certified(start, duration, arm, obstacle),
        clearance_m=_certified(found, duration, arm, obstacle),
        endpoint_errors_m=(float(errors[0]), float(errors[1])),
        parameters=tuple(float(v) for v in found),
        within_tolerance=bool(errors.max() <= tolerance_m),
    )


def witnesses_for_map(coefficients: Coefficients, region_map: RegionMap, arm: PlanarArm, count: int) -> list[Witness]:
    """:func:`best_clearance_at` at the centres of ``count`` leaves that keep neither the margin
    nor are proven infeasible, spread evenly over them in (L, W) order (empty if there is none)."""
    check_positive_int("count", count)
    candidates = np.flatnonzero(
        (region_map.status == STATUSES.index("collision_free")) | (region_map.status == STATUSES.index("undecided"))
    )
    if candidates.size == 0:
        return []
    cells = [region_map.cell(int(k)) for k in candidates]
    centres = np.array([[sum(c.length_range_m) / 2, sum(c.width_range_m) / 2] for c in cells])
    order = np.lexsort((centres[:, 1], centres[:, 0]))
    picks = order[np.unique(np.linspace(0, order.size - 1, min(count, order.size)).round().astype(int))]
    return [
        best_clearance_at(coefficients, arm, float(L), float(W), region_map.endpoint_tolerance_m)
        for L, W in centres[picks]
    ]


def witness_lines(witnesses: list[Witness]) -> list[str]:
    """One line per witness (mm), or one saying there was no cell to search."""
    if not witnesses:
        return ["witnesses: every cell keeps the margin or is proven infeasible"]
    return [
        f"witness at L = {w.length_m:.4f} m, W = {w.width_m:.5f} m: the coefficients' trajectory "
        f"{1e3 * w.regression_clearance_m:.2f} mm, the best one found {1e3 * w.clearance_m:.2f} mm (certified), "
        f"its endpoint errors {1e3 * w.endpoint_errors_m[0]:.2f} / {1e3 * w.endpoint_errors_m[1]:.2f} mm"
        + ("" if w.within_tolerance else " (NOT within the tolerance: no witness)")
        for w in witnesses
    ]
