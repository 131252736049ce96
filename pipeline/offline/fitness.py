"""The objective the PSO minimises for one obstacle: the paper's Eq. 5 plus a clearance penalty.

fitness = sum_j w_j |p_d(t_j) - p_a(t_j)|^2                       (Eq. 5, [m^2])
        + penalty_weight * sum_k sum_links max(0, margin - clearance)^2

with w_j = ``endpoint_weight`` (100) for the first and last ``weighted_points`` (3) of the
n path points (uniform in x, timed by Eq. 7) and 1 elsewhere. The clearance is the exact
link-to-rounded-box distance at ``clearance_samples`` times uniform in [0, T]: the paper's
sampled points on link 2 (Eq. 6) are replaced by the exact distance of both links.

Two routes compute the clearance: ``"analytic"`` (vectorised, for the PSO's hot loop) and
``"coal"`` (Pinocchio geometry model + Coal, the canonical one); tests prove them equal
wherever every link clears the obstacle. Where a link overlaps it, Coal reports a
penetration depth and the analytic route minus the radii: both are <= 0, so both routes
penalise, by different amounts.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import ANALYTIC, ClearanceFunction, ClearanceRoute, route_from_name
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.families import PAPER, EndpointContext, TrajectoryFamily
from pipeline.motion.path import QuarticPath, desired_path
from pipeline.motion.trajectory import joint_angles
from pipeline.validation import check_non_negative, check_positive, check_positive_int


@dataclass(frozen=True)
class FitnessConfig:
    """Settings of the objective.

    Attributes:
        n_points: n, path points of Eq. 5 (uniform in x from P1 to P5). The paper does not
            give n. With 11, its three weighted points at each end span a fifth of the path and
            the DOE optima vary smoothly with (L, W); with 51 they jump between local optima
            from one obstacle to the next, and no quadratic regression follows them (README).
        weighted_points: Points at each end weighted by ``endpoint_weight`` (paper: 3).
        endpoint_weight: Weight of those points (paper: 100).
        clearance_samples: Times, uniform in [0, T], at which the clearance is penalised.
        penalty_weight: Weight of the clearance penalty [1/m^2 relative to Eq. 5's m^2].
        penalty_margin_m: Clearance below which the penalty is active [m]; None means the
            scene's safety margin plus ``margin_buffer_m``.
        margin_buffer_m: Extra clearance asked of the optimiser beyond the scene's margin [m],
            so that the optimum keeps the margin on the dense check, not only at the samples.
        clearance_route: :data:`pipeline.geometry.clearance.ANALYTIC` (fast, default) or
            :data:`pipeline.geometry.clearance.COAL` (Pinocchio + Coal).
        elbow: Elbow branch (+1 or -1): the exact-endpoints family's inverse kinematics
            use it, and every family is penalised (same weight) where elbow * theta2 falls
            below ``min_elbow_angle_rad``, so all optima lie on one branch and regress smoothly.
        min_elbow_angle_rad: Smallest elbow * theta2 without penalty [rad] (keeps away from
            the stretched-out singularity).
    """

    n_points: int = 11
    weighted_points: int = 3
    endpoint_weight: float = 100.0
    clearance_samples: int = 121
    penalty_weight: float = 1.0e4
    penalty_margin_m: float | None = None
    margin_buffer_m: float = 0.002
    clearance_route: ClearanceRoute = ANALYTIC
    elbow: int = 1
    min_elbow_angle_rad: float = 0.05

    def __post_init__(self) -> None:
        check_positive_int("n_points", self.n_points, minimum=7)
        check_positive_int("weighted_points", self.weighted_points)
        if 2 * self.weighted_points >= self.n_points:
            raise InvalidParameterError("weighted_points", self.weighted_points, "fewer than n_points / 2")
        check_positive("endpoint_weight", self.endpoint_weight)
        check_positive_int("clearance_samples", self.clearance_samples, minimum=2)
        check_non_negative("penalty_weight", self.penalty_weight)
        if self.penalty_margin_m is not None:
            check_non_negative("penalty_margin_m", self.penalty_margin_m)
        check_non_negative("margin_buffer_m", self.margin_buffer_m)
        if not isinstance(self.clearance_route, ClearanceRoute):
            raise InvalidParameterError("clearance_route", self.clearance_route, "a ClearanceRoute (COAL or ANALYTIC)")
        if self.elbow not in (1, -1):
            raise InvalidParameterError("elbow", self.elbow, "+1 or -1")
        check_non_negative("min_elbow_angle_rad", self.min_elbow_angle_rad)

    def to_json(self) -> dict:
        """Plain-JSON settings (the route by name), as the build records them."""
        return {**{f.name: getattr(self, f.name) for f in fields(self)}, "clearance_route": self.clearance_route.name}

    @classmethod
    def from_json(cls, document: dict) -> FitnessConfig:
        """Inverse of :meth:`to_json`.

        Raises:
            InvalidParameterError: an unknown route or a bad setting. TypeError: an unknown key.
        """
        document = dict(document)
        if "clearance_route" in document:
            document["clearance_route"] = route_from_name(document["clearance_route"])
        return cls(**document)


@dataclass(eq=False)
class FitnessProblem:
    """Everything the objective needs for one obstacle, precomputed once.

    Build with :func:`fitness_problem`. Parameters passed to the methods are the family's
    free parameters, shape (k,) or (P, k).
    """

    arm: PlanarArm
    obstacle: Obstacle
    scene: Scene
    path: QuarticPath
    config: FitnessConfig
    family: TrajectoryFamily
    context: EndpointContext
    times_s: np.ndarray
    targets_m: np.ndarray
    weights: np.ndarray
    clearance_times_s: np.ndarray
    penalty_margin_m: float
    clearance_function: ClearanceFunction | None = field(default=None)

    def full_parameters(self, free: np.ndarray) -> np.ndarray:
        """The 8 sinusoid parameters (..., 8) from free parameters (..., k)."""
        return self.family.expand(free, self.context)

    def tip_positions(self, full: np.ndarray, times_s: np.ndarray) -> np.ndarray:
        """End-effector (x, y) [m] by Eq. 2 at the given times: shape (..., m, 2)."""
        return self.arm.end_effector_planar(joint_angles(full, times_s))

    def tracking_errors(self, full: np.ndarray) -> np.ndarray:
        """Desired minus actual tip position at the n path points [m]: (..., n, 2)."""
        return self.targets_m - self.tip_positions(full, self.times_s)

    def clearance(self, full: np.ndarray) -> np.ndarray:
        """Link clearance [m] at the penalty times: shape (..., k, 2)."""
        return self.clearance_at(joint_angles(full, self.clearance_times_s))

    def clearance_at(self, q: np.ndarray) -> np.ndarray:
        """Link clearance [m] for configurations q (..., 2) by the configured route: (..., 2)."""
        flat = q.reshape(-1, 2)
        return self.clearance_function(flat).reshape(q.shape)

    def violations(self, full: np.ndarray) -> np.ndarray:
        """Penalised shortfalls at the penalty times, shape (..., k, 3): clearance of link 1
        and link 2 below the penalty margin [m], and elbow * theta2 below its minimum [rad]."""
        q = joint_angles(full, self.clearance_times_s)
        clearance = self.clearance_at(q)
        elbow = self.config.min_elbow_angle_rad - self.config.elbow * q[..., 1:2]
        return np.maximum(0.0, np.concatenate([self.penalty_margin_m - clearance, elbow], -1))

    def residuals(self, free: np.ndarray) -> np.ndarray:
        """Residual vector r with fitness = sum(r**2), for scipy.optimize.least_squares."""
        full = self.full_parameters(np.asarray(free, dtype=float))
        tracking = self.tracking_errors(full) * np.sqrt(self.weights)[:, None]
        penalty = np.sqrt(self.config.penalty_weight) * self.violations(full)
        return np.concatenate([tracking.ravel(), penalty.ravel()])

    def evaluate(self, free: np.ndarray) -> np.ndarray:
        """Fitness of free parameters (P, k) -> (P,), or (k,) -> scalar array."""
        full = self.full_parameters(np.asarray(free, dtype=float))
        errors = self.tracking_errors(full)
        tracking = np.sum(self.weights * np.sum(errors * errors, axis=-1), axis=-1)
        violation = self.violations(full)
        return tracking + self.config.penalty_weight * np.sum(violation * violation, axis=(-2, -1))

    def endpoint_errors_m(self, full: np.ndarray) -> tuple[float, float]:
        """Distance of the tip from P1 at t = 0 and from P5 at t = T [m]."""
        tips = self.tip_positions(full, np.array([0.0, self.path.duration_s]))
        return (
            float(np.linalg.norm(tips[0] - self.path.points_m[0])),
            float(np.linalg.norm(tips[1] - self.path.points_m[-1])),
        )


def fitness_problem(
    arm: PlanarArm,
    length_m: float,
    width_m: float,
    scene: Scene,
    config: FitnessConfig,
    family: TrajectoryFamily = PAPER,
) -> FitnessProblem:
    """Precompute the objective for the obstacle L x W.

    Raises:
        InvalidParameterError: non-positive or NaN L or W.
        UnreachableObstacleError: the path's constraint points are outside the arm's reach.
    """
    if not isinstance(family, TrajectoryFamily):
        raise InvalidParameterError("family", family, "a TrajectoryFamily (pipeline.motion.families)")
    obstacle = Obstacle.in_scene(length_m, width_m, scene)
    path = desired_path(obstacle, scene, arm.reach_m)
    config.clearance_route.check_arm(arm)
    times, targets = path.samples(config.n_points)
    weights = np.ones(config.n_points)
    weights[: config.weighted_points] = config.endpoint_weight
    weights[-config.weighted_points :] = config.endpoint_weight
    margin = config.penalty_margin_m
    if margin is None:
        margin = scene.margin_m + config.margin_buffer_m
    return FitnessProblem(
        arm=arm,
        obstacle=obstacle,
        scene=scene,
        path=path,
        config=config,
        family=family,
        context=family.endpoint_context(path, arm.link_lengths_m, config.elbow),
        times_s=times,
        targets_m=targets,
        weights=weights,
        clearance_times_s=np.linspace(0.0, path.duration_s, config.clearance_samples),
        penalty_margin_m=margin,
        clearance_function=config.clearance_route.function(arm, obstacle),
    )
