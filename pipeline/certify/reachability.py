"""What the family can reach where the region map is neither ``margin`` nor ``infeasible``.

The infeasibility certificate (``pipeline.certify.endpoints``) looks only at the end poses, so
a cell can be out of the family's reach (no sinusoid per joint both ends within the tolerance
and keeps the margin along the whole motion) without being proven so. For one obstacle
(L, W) this module searches the family directly:

    maximise z over the 8 parameters p and z  subject to
    c_j(theta(t_k; p)) >= z  for both links j and K uniform times t_k in [0, T],
    |tip(0) - P1| <= tolerance,  |tip(T) - P5| <= tolerance,

    and the trajectory stays in the family: joint angles within the URDF's limits, on the
    elbow branch (elbow * theta2 > 0: with |theta2| <= pi, the branch of the end poses that the
    infeasibility certificate bounds) and joint speeds within the URDF's limits, at the K times,

by SLSQP from the regression's parameters at (L, W) and from ``restarts`` random perturbations
of them (a local search, holding 0.999 of the tolerance and of the speed limits so that its
last iterate, checked afterwards, meets them). Each end point is then checked exactly: endpoint
errors recomputed, joint ranges and peak speeds over [0, T] in closed form; the best of those
that pass is certified in continuous time (``pipeline.geometry.sinusoid_certificate``,
analytic route), so the figure reported is a true lower bound on a member of the family: a
*witness* that at least that much is reachable at (L, W) with the tolerance. Where it stays
below the margin, the local search found no trajectory that keeps it: evidence, not a proof,
that the cell is out of the family's reach.

Without the family constraints the search is not evidence of anything: from perturbed starts
it finds trajectories that end on the other elbow branch (theta2 past pi, outside the URDF's
limits) and clear the box by 10 cm where every end pose on the family's branch is within about
1 cm of it. With them, ``python -m pipeline.certify_range results/coefficients.json --jobs 2
--witnesses 12 --witness-restarts 6`` (default build, 2.7 min) finds 9.96-10.04 mm at the
centres of 12 leaves of the band near W = 0.1193 m where the map misses the margin (below 10 mm
at 5 of them, each with its error at P5 at the full 2.00 mm), the coefficients' own
trajectories 9.92-10.02 mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from pipeline.certify.region_map import STATUSES, RegionMap
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import ANALYTIC, analytic_link_clearance
from pipeline.geometry.sinusoid_certificate import certify_trajectory
from pipeline.model.arm import PlanarArm
from pipeline.model.kinematics import forward_kinematics
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import desired_path
from pipeline.motion.trajectory import PARAMETER_NAMES, JointTrajectory, joint_angles, joint_velocities
from pipeline.offline.coefficients import Coefficients
from pipeline.validation import check_non_negative, check_positive, check_positive_int

_SEARCH_SAMPLES = 241
_MAX_ITERATIONS = 300
#: Standard deviations of the restarts' perturbations of (A, w, phi, gamma) per joint [rad, rad/s, rad, rad].
_RESTART_SCALE = np.array([0.3, 0.3, 0.3, 0.1] * 2)
#: The search holds this fraction of the tolerance, so that an SLSQP iterate that ends a hair
#: outside its constraints (it stops on a line-search failure as often as on convergence)
#: still meets the tolerance itself.
_INSIDE = 0.999
#: Smallest elbow * theta2 the search holds at its samples [rad] (the family's branch is > 0).
_BRANCH_INSIDE_RAD = 1e-3


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
        within_family: Joint angles within the URDF's limits and on the elbow branch, joint
            speeds within the URDF's limits, over all of [0, T] (closed form; False only if no
            search ended inside and the coefficients' own trajectory is outside: no witness).
    """

    length_m: float
    width_m: float
    regression_clearance_m: float
    clearance_m: float
    endpoint_errors_m: tuple[float, float]
    parameters: tuple[float, ...]
    within_tolerance: bool = True
    within_family: bool = True

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
            "within_family": self.within_family,
        }


def _certified(parameters: np.ndarray, duration_s: float, arm: PlanarArm, obstacle: Obstacle) -> float:
    trajectory = JointTrajectory(tuple(float(v) for v in parameters), float(duration_s))
    return float(certify_trajectory(trajectory, arm, obstacle, route=ANALYTIC, tolerance_m=1e-5).certified_clearance_m)


def in_family(trajectory: JointTrajectory, arm: PlanarArm, elbow: int) -> bool:
    """Joint angles within ``arm``'s limits and elbow * theta2 > 0, joint speeds within its
    limits, over all of [0, T] (closed form)."""
    ranges = trajectory.angle_ranges_rad()
    within = all(lo >= lim[0] and hi <= lim[1] for (lo, hi), lim in zip(ranges, arm.position_limits_rad, strict=True))
    branch = min(elbow * ranges[1][0], elbow * ranges[1][1]) > 0.0
    speeds = bool(np.all(trajectory.peak_velocity_rad_s() <= np.asarray(arm.velocity_limits_rad_s)))
    return within and branch and speeds


def best_clearance_at(
    coefficients: Coefficients,
    arm: PlanarArm,
    length_m: float,
    width_m: float,
    tolerance_m: float,
    restarts: int = 0,
    rng: np.random.Generator | None = None,
) -> Witness:
    """The local search of the module docstring at one obstacle (paper family coefficients).

    Args:
        coefficients: Paper family coefficients (the first start is their trajectory).
        arm: The arm (link lengths and radii, joint limits).
        length_m, width_m: The obstacle [m].
        tolerance_m: Endpoint tolerance [m].
        restarts: Further starts, each the regression's parameters perturbed by N(0,
            ``_RESTART_SCALE``) [count].
        rng: Source of the perturbations; required when ``restarts`` > 0.

    Raises:
        InvalidParameterError: a non-positive tolerance, a negative restart count or restarts
            without a generator, or a family that does not regress all 8 parameters.
    """
    check_positive("tolerance_m", tolerance_m)
    check_non_negative("restarts", restarts)
    if restarts and rng is None:
        raise InvalidParameterError("rng", rng, "a numpy.random.Generator when restarts > 0")
    if tuple(coefficients.family.free_parameter_names) != PARAMETER_NAMES:
        raise InvalidParameterError("family", coefficients.family.name, "a family regressing all 8 parameters")
    search = _Search.at(coefficients, arm, length_m, width_m, tolerance_m)
    regression = np.asarray(coefficients.predict_free(length_m, width_m), dtype=float).ravel()
    starts = [regression] + [regression + rng.normal(0.0, 1.0, 8) * _RESTART_SCALE for _ in range(restarts)]
    chosen, (errors, member) = search.best(regression, starts)
    duration, obstacle = search.duration_s, search.obstacle
    regression_clearance = _certified(regression, duration, arm, obstacle)
    return Witness(
        length_m=float(length_m),
        width_m=float(width_m),
        regression_clearance_m=regression_clearance,
        clearance_m=regression_clearance if chosen is regression else _certified(chosen, duration, arm, obstacle),
        endpoint_errors_m=(float(errors[0]), float(errors[1])),
        parameters=tuple(float(v) for v in chosen),
        within_tolerance=bool(errors.max() <= tolerance_m),
        within_family=member,
    )


@dataclass(frozen=True)
class _Search:
    """The local search of the module docstring at one obstacle: its SLSQP problem and its choice.

    Attributes:
        arm: The arm (link lengths and radii, joint limits).
        obstacle: The obstacle in the coefficients' scene.
        elbow: The coefficients' elbow branch (+1 or -1).
        ends: The path's first and last points P1 and P5, (2, 2) [m].
        duration_s: The path's duration T [s].
        times_s: The search's samples over [0, T] [s].
        limits_rad: The arm's joint angle limits, (2, 2) [rad].
        speed_limits_rad_s: The joint speed limits the search holds (a hair inside the arm's) [rad/s].
        tolerance_m: Endpoint tolerance [m].
    """

    arm: PlanarArm
    obstacle: Obstacle
    elbow: int
    ends: np.ndarray
    duration_s: float
    times_s: np.ndarray
    limits_rad: np.ndarray
    speed_limits_rad_s: np.ndarray
    tolerance_m: float

    @classmethod
    def at(
        cls, coefficients: Coefficients, arm: PlanarArm, length_m: float, width_m: float, tolerance_m: float
    ) -> _Search:
        """The search at obstacle (``length_m``, ``width_m``) [m] of the coefficients' scene."""
        scene = coefficients.scene
        obstacle = Obstacle.in_scene(length_m, width_m, scene)
        path = desired_path(obstacle, scene)
        return cls(
            arm=arm,
            obstacle=obstacle,
            elbow=coefficients.elbow,
            ends=np.array([path.points_m[0], path.points_m[-1]]),
            duration_s=path.duration_s,
            times_s=np.linspace(0.0, path.duration_s, _SEARCH_SAMPLES),
            limits_rad=np.asarray(arm.position_limits_rad, dtype=float),
            speed_limits_rad_s=_INSIDE * np.asarray(arm.velocity_limits_rad_s, dtype=float),
            tolerance_m=tolerance_m,
        )

    def sampled_clearance(self, parameters: np.ndarray) -> float:
        """The least clearance [m] of both links over the search's samples."""
        return float(analytic_link_clearance(joint_angles(parameters, self.times_s), self.arm, self.obstacle).min())

    def clearance_rows(self, x: np.ndarray) -> np.ndarray:
        """Each sample's clearance above the clearance variable ``x[8]`` [m], scaled to cm."""
        angles = joint_angles(x[:8], self.times_s)
        return (analytic_link_clearance(angles, self.arm, self.obstacle) - x[8]).ravel() * 100.0

    def endpoint_rows(self, x: np.ndarray) -> np.ndarray:
        """1 - (endpoint error / held tolerance)^2 at t = 0 and T: >= 0 where the tolerance is held."""
        tips = forward_kinematics(joint_angles(x[:8], np.array([0.0, self.duration_s])), self.arm.link_lengths_m)
        return 1.0 - np.sum((tips - self.ends) ** 2, -1) / (_INSIDE * self.tolerance_m) ** 2

    def family_rows(self, x: np.ndarray) -> np.ndarray:
        """The family's constraints at the samples: room to the angle limits [rad], the elbow branch
        [rad] and room to the speed limits [rad/s]."""
        theta = joint_angles(x[:8], self.times_s)
        limits = self.limits_rad
        return np.concatenate(
            [
                (theta - limits[:, 0]).ravel(),
                (limits[:, 1] - theta).ravel(),
                self.elbow * theta[:, 1] - _BRANCH_INSIDE_RAD,
                (self.speed_limits_rad_s - np.abs(joint_velocities(x[:8], self.times_s))).ravel(),
            ]
        )

    def outcome(self, parameters: np.ndarray) -> tuple[np.ndarray, bool]:
        """|tip(0) - P1| and |tip(T) - P5| [m], and whether the trajectory is in the family."""
        tips = forward_kinematics(joint_angles(parameters, np.array([0.0, self.duration_s])), self.arm.link_lengths_m)
        trajectory = JointTrajectory(tuple(float(v) for v in parameters), self.duration_s)
        return np.linalg.norm(tips - self.ends, axis=-1), in_family(trajectory, self.arm, self.elbow)

    def search(self, start: np.ndarray) -> np.ndarray:
        """SLSQP from ``start``: the parameters maximising the sampled clearance within the constraints."""
        result = minimize(
            lambda x: -100.0 * x[8],
            np.append(start, self.sampled_clearance(start)),
            jac=lambda x: np.append(np.zeros(8), -100.0),
            method="SLSQP",
            constraints=[
                {"type": "ineq", "fun": self.clearance_rows},
                {"type": "ineq", "fun": self.endpoint_rows},
                {"type": "ineq", "fun": self.family_rows},
            ],
            options={"maxiter": _MAX_ITERATIONS, "ftol": 1e-10},
        )
        return result.x[:8]

    def best(self, regression: np.ndarray, starts: list[np.ndarray]) -> tuple[np.ndarray, tuple[np.ndarray, bool]]:
        """Of the regression's own parameters and the search's result from each start, the one with
        the largest sampled clearance that ends within the tolerance and in the family, with its
        :meth:`outcome`; the regression's if none does."""
        regression_outcome = self.outcome(regression)
        chosen, chosen_outcome, best_sampled = regression, regression_outcome, -np.inf
        for found in [regression, *(self.search(start) for start in starts)]:
            result = regression_outcome if found is regression else self.outcome(found)
            if result[0].max() > self.tolerance_m or not result[1]:
                continue
            sampled = self.sampled_clearance(found)
            if sampled > best_sampled:
                chosen, chosen_outcome, best_sampled = found, result, sampled
        return chosen, chosen_outcome


def witnesses_for_map(
    coefficients: Coefficients,
    region_map: RegionMap,
    arm: PlanarArm,
    count: int,
    restarts: int = 0,
    rng: np.random.Generator | None = None,
) -> list[Witness]:
    """:func:`best_clearance_at` (with ``restarts`` and ``rng``) at the centres of ``count``
    leaves that keep neither the margin nor are proven infeasible, spread evenly over them in
    (L, W) order (empty if there is none)."""
    check_positive_int("count", count)
    candidates = np.flatnonzero(
        (region_map.status == STATUSES.index("collision_free")) | (region_map.status == STATUSES.index("undecided"))
    )
    if candidates.size == 0:
        return []
    centres = region_map.leaf_centres_m()[candidates, :2]
    order = np.lexsort((centres[:, 1], centres[:, 0]))
    picks = order[np.unique(np.linspace(0, order.size - 1, min(count, order.size)).round().astype(int))]
    return [
        best_clearance_at(coefficients, arm, float(L), float(W), region_map.endpoint_tolerance_m, restarts, rng)
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
        + ("" if w.within_family else " (NOT within the joint limits and the elbow branch: no witness)")
        for w in witnesses
    ]
