"""The online generator: coefficients + (L, W) -> the trajectory, in microseconds.

Evaluating the regression is a 6-term polynomial per parameter; the only other work is
the path's duration T (a Gauss-Legendre arc length of the quartic). No URDF, Pinocchio or
Coal is needed here: the arm's link lengths come from the coefficients file.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .coefficients import Coefficients
from .exceptions import InvalidParameterError, OutOfFittedRangeError, OutOfFittedRangeWarning
from .family import endpoint_context, expand, reach_annulus_m
from .obstacle import Obstacle
from .path import QuarticPath, desired_path
from .scene import Scene
from .trajectory import JointTrajectory

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
    family: str
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
        coefficients: Loaded with :func:`pipeline.coefficients.load_coefficients`.
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
    context = (
        endpoint_context(path, coefficients.link_lengths_m, coefficients.elbow)
        if coefficients.family != "paper"
        else None
    )
    full = expand(coefficients.family, free, context)
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

    For the paper family this is the regression alone, vectorised and without checks; the
    exact-endpoints family needs each obstacle's path and inverse kinematics, so it calls
    :func:`generate` per obstacle (range checks off).
    """
    if coefficients.family == "paper":
        return coefficients.predict_free(np.asarray(lengths_m, float), np.asarray(widths_m, float))
    pairs = zip(np.atleast_1d(lengths_m), np.atleast_1d(widths_m), strict=True)
    return np.array(
        [generate(coefficients, float(L), float(W), out_of_range="ignore").trajectory.parameters for L, W in pairs]
    )
