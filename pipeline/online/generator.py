"""The online generator: coefficients + (L, W) -> the trajectory, in microseconds.

Evaluating the regression is a 6-term polynomial per parameter; the only other work is
the path's duration T (a Gauss-Legendre arc length of the quartic). No URDF, Pinocchio or
Coal is needed here: the arm's link lengths come from the coefficients file.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import (
    InexactEndpointsWarning,
    InvalidParameterError,
    OutOfFittedRangeError,
    OutOfFittedRangeWarning,
)
from pipeline.model.kinematics import reach_annulus_m
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.families import TrajectoryFamily
from pipeline.motion.path import QuarticPath, desired_path
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
        obstacle: The obstacle.
        path: The desired path (P1..P5, T).
        trajectory: The joint trajectory; ``trajectory.q(t)`` gives joint angles [rad].
        extrapolated: True if (L, W) lies outside the fitted range.
    """

    length_m: float
    width_m: float
    family: TrajectoryFamily
    scene: Scene
    obstacle: Obstacle
    path: QuarticPath
    trajectory: JointTrajectory
    extrapolated: bool

    @property
    def duration_s(self) -> float:
        """T [s]."""
        return self.trajectory.duration_s

    def q(self, t_s):
        """Joint angles [rad] at t [s] (see :meth:`JointTrajectory.q`)."""
        return self.trajectory.q(t_s)


def _check_range(coefficients: Coefficients, length_m: float, width_m: float, policy: str) -> bool:
    if policy not in OUT_OF_RANGE_POLICIES:
        raise InvalidParameterError("out_of_range", policy, f"one of {OUT_OF_RANGE_POLICIES}")
    for name, value in (("L", length_m), ("W", width_m)):
        lo, hi = coefficients.fitted_range_m[name]
        if not lo <= value <= hi:
            if policy == "error":
                raise OutOfFittedRangeError(name, value, (lo, hi))
            if policy == "warn":
                warnings.warn(str(OutOfFittedRangeError(name, value, (lo, hi))), OutOfFittedRangeWarning, stacklevel=3)
    return not coefficients.in_range(length_m, width_m)


def generate(
    coefficients: Coefficients, length_m: float, width_m: float, *, out_of_range: str = "warn"
) -> GeneratedTrajectory:
    """The trajectory for the obstacle L x W [m] from regression coefficients.

    Args:
        coefficients: Loaded with :func:`pipeline.offline.coefficients.load_coefficients`.
        length_m, width_m: Obstacle size [m].
        out_of_range: What to do outside the fitted range: "warn" (an
            OutOfFittedRangeWarning), "error" (OutOfFittedRangeError) or "ignore".

    Raises:
        InvalidParameterError: non-positive or NaN L or W.
        UnreachableObstacleError: the path around this obstacle leaves the arm's reach.
        OutOfFittedRangeError: outside the fitted range with ``out_of_range="error"``.
    """
    scene = coefficients.scene
    obstacle = Obstacle.in_scene(length_m, width_m, scene)
    path = desired_path(obstacle, scene, reach_annulus_m(coefficients.link_lengths_m))
    extrapolated = _check_range(coefficients, obstacle.length_m, obstacle.width_m, out_of_range)
    free = coefficients.predict_free(obstacle.length_m, obstacle.width_m)
    family = coefficients.family
    context = (
        family.endpoint_context(path, coefficients.link_lengths_m, coefficients.elbow)
        if family.uses_endpoint_context
        else None
    )
    full = family.expand(free, context)
    if family.pins_endpoints and not bool(family.endpoints_exact(free, context)):
        warnings.warn(
            f"L = {obstacle.length_m} m, W = {obstacle.width_m} m: the {family.name} family could not pin "
            "the tip to P1 and P5 for these parameters (A1 clamped); endpoints are approximate",
            InexactEndpointsWarning,
            stacklevel=2,
        )
    return GeneratedTrajectory(
        length_m=obstacle.length_m,
        width_m=obstacle.width_m,
        family=coefficients.family,
        scene=scene,
        obstacle=obstacle,
        path=path,
        trajectory=JointTrajectory(tuple(full), path.duration_s),
        extrapolated=extrapolated,
    )


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
