"""Trajectory families: which of the 8 sinusoid parameters are searched, and how the rest follow.

* ``paper``: all 8 parameters are free (the paper's method).
* ``exact-endpoints``: per joint, the end effector is pinned to P1 at t = 0 and to P5 at
  t = T by construction. With theta_s, theta_e the joint angles of P1 and P5 (analytic
  IK, one elbow branch), joint 1 keeps (w1, phi1) free and
  A1 = (theta1_e - theta1_s) / (sin(w1 T + phi1) - sin(phi1)), gamma1 = theta1_s - A1 sin(phi1).
  P1 and P5 are mirror images, so theta2_s = theta2_e: joint 2 keeps (A2, w2) free with
  phi2 = (pi - w2 T) / 2 (so that sin(w2 T + phi2) = sin(phi2)) and
  gamma2 = theta2_s - A2 sin(phi2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .exceptions import InvalidParameterError, UnreachableObstacleError
from .trajectory import PARAMETER_NAMES, canonicalize

FAMILY_NAMES: tuple[str, ...] = ("paper", "exact-endpoints")

#: Free parameters of each family, in the order the PSO searches them.
FREE_PARAMETERS: dict[str, tuple[str, ...]] = {
    "paper": PARAMETER_NAMES,
    "exact-endpoints": ("w1", "phi1", "A2", "w2"),
}

# Search box per parameter name: A [rad], w [rad/s], phi [rad], gamma [rad].
_BOUNDS = {"A": (-3.0, 3.0), "w": (0.2, 2.5), "phi": (-np.pi / 2, np.pi / 2), "gamma": (-np.pi, np.pi)}

# Smallest |sin(w1 T + phi1) - sin(phi1)| allowed before A1 is clamped (A1 would blow up).
_MIN_DENOMINATOR = 1e-3


@dataclass(frozen=True)
class EndpointContext:
    """What an exact-endpoints trajectory needs to know about one obstacle.

    Attributes:
        theta_start_rad: Joint angles at P1 [rad], shape (2,).
        theta_end_rad: Joint angles at P5 [rad], shape (2,).
        duration_s: T [s].
    """

    theta_start_rad: tuple[float, float]
    theta_end_rad: tuple[float, float]
    duration_s: float


def check_family(name: str) -> str:
    """Return ``name`` if it is a known family, else raise InvalidParameterError."""
    if name not in FAMILY_NAMES:
        raise InvalidParameterError("family", name, f"one of {FAMILY_NAMES}")
    return name


def search_bounds(family: str) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) of the PSO search box over the family's free parameters."""
    names = FREE_PARAMETERS[check_family(family)]
    lower = np.array([_BOUNDS[n.rstrip("12")][0] for n in names])
    upper = np.array([_BOUNDS[n.rstrip("12")][1] for n in names])
    return lower, upper


def polish_bounds(family: str) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the local polish: the search box, except that phases are unbounded.

    A phase is 2 pi periodic (and pi periodic with A's sign flip, Eq. 8): a bound on it would
    stop a local solver at +-pi/2 when the optimum lies just across, in the same motion family.
    """
    lower, upper = search_bounds(family)
    phases = np.array([name.startswith("phi") for name in FREE_PARAMETERS[family]])
    return np.where(phases, -np.inf, lower), np.where(phases, np.inf, upper)


def reach_annulus_m(link_lengths_m: tuple[float, float]) -> tuple[float, float]:
    """Radii of the annulus the tip can reach around joint 1 [m]: (|l1 - l2|, l1 + l2)."""
    l1, l2 = link_lengths_m
    return abs(l1 - l2), l1 + l2


def inverse_kinematics(point_m: np.ndarray, link_lengths_m: tuple[float, float], elbow: int = 1) -> np.ndarray:
    """Joint angles [rad] placing the tip at ``point_m`` (x, y) [m]; ``elbow`` = +1 or -1 picks the branch.

    Raises:
        UnreachableObstacleError: the point is outside the reachable annulus.
    """
    l1, l2 = link_lengths_m
    x, y = float(point_m[0]), float(point_m[1])
    radius = float(np.hypot(x, y))
    cos2 = (radius**2 - l1**2 - l2**2) / (2 * l1 * l2)
    if not -1.0 - 1e-12 <= cos2 <= 1.0 + 1e-12:
        raise UnreachableObstacleError("target", radius, reach_annulus_m(link_lengths_m))
    cos2 = min(1.0, max(-1.0, cos2))
    theta2 = elbow * float(np.arccos(cos2))
    theta1 = float(np.arctan2(y, x) - np.arctan2(l2 * np.sin(theta2), l1 + l2 * np.cos(theta2)))
    return np.array([theta1, theta2])


def forward_kinematics(theta_rad: np.ndarray, link_lengths_m: tuple[float, float]) -> np.ndarray:
    """Tip (x, y) [m] of joint angles (..., 2) [rad] by the paper's Eq. 2: shape (..., 2)."""
    theta = np.asarray(theta_rad, dtype=float)
    l1, l2 = link_lengths_m
    a1, a12 = theta[..., 0], theta[..., 0] + theta[..., 1]
    return np.stack([l1 * np.cos(a1) + l2 * np.cos(a12), l1 * np.sin(a1) + l2 * np.sin(a12)], -1)


def endpoint_context(path, link_lengths_m: tuple[float, float], elbow: int = 1) -> EndpointContext:
    """Joint angles of P1 and P5 (analytic IK on the given elbow branch) and T, for a
    :class:`pipeline.path.QuarticPath` ``path``."""
    start = inverse_kinematics(path.points_m[0], link_lengths_m, elbow)
    end = inverse_kinematics(path.points_m[-1], link_lengths_m, elbow)
    return EndpointContext((float(start[0]), float(start[1])), (float(end[0]), float(end[1])), path.duration_s)


def expand(family: str, free: np.ndarray, context: EndpointContext | None) -> np.ndarray:
    """The 8 parameters (..., 8) from the family's free parameters (..., k)."""
    free = np.asarray(free, dtype=float)
    if check_family(family) == "paper":
        return free
    if context is None:
        raise InvalidParameterError("context", None, "an EndpointContext for the exact-endpoints family")
    w1, phi1, a2, w2 = np.moveaxis(free, -1, 0)
    t_end = context.duration_s
    th_s, th_e = context.theta_start_rad, context.theta_end_rad
    denominator = np.sin(w1 * t_end + phi1) - np.sin(phi1)
    denominator = np.where(
        np.abs(denominator) < _MIN_DENOMINATOR, np.copysign(_MIN_DENOMINATOR, denominator), denominator
    )
    a1 = (th_e[0] - th_s[0]) / denominator
    gamma1 = th_s[0] - a1 * np.sin(phi1)
    phi2 = (np.pi - w2 * t_end) / 2.0
    gamma2 = th_s[1] - a2 * np.sin(phi2)
    return np.stack([a1, w1, phi1, gamma1, a2, w2, phi2, gamma2], -1)


def canonical_free(family: str, free: np.ndarray) -> np.ndarray:
    """Map free parameters (..., k) to one canonical form (Eq. 8), keeping the motion.

    paper: the 8 parameters as :func:`pipeline.trajectory.canonicalize`. exact-endpoints:
    (w1, phi1) get w1 >= 0 and phi1 in [-pi/2, pi/2) (A1 follows from them, so it flips by
    itself); w2 -> |w2|, since with phi2 pinned joint 2 moves as A2 cos(w2 (t - T/2)) + const,
    even in w2; A2 keeps its sign, which matters.
    """
    free = np.asarray(free, dtype=float)
    if check_family(family) == "paper":
        return canonicalize(free)
    out = free.copy()
    joint1 = np.stack([np.ones_like(free[..., 0]), free[..., 0], free[..., 1], np.zeros_like(free[..., 0])], -1)
    joint1 = canonicalize(np.concatenate([joint1, joint1], -1))[..., :4]
    out[..., 0], out[..., 1] = joint1[..., 1], joint1[..., 2]
    out[..., 3] = np.abs(free[..., 3])
    return out
