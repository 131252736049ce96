"""The benchmark's peer for the time-optimal timing: TOPP-RA (the ``toppra`` library) on our path and limits.

TOPP-RA (Pham & Pham, 2018) finds the time-optimal timing s(t) of a fixed geometric path q(s) under
constraints linear in the path acceleration u = s'' and the squared path speed x = s'^2: joint
speeds ``|q'(s)| sqrt(x) <= v``, joint accelerations ``|q''(s) x + q'(s) u| <= a`` and joint torques
``|M q'(s) u + (M q''(s) + C(q'(s))) x| <= tau`` (no gravity: the arm moves in a horizontal plane).
It discretizes the path at N + 1 gridpoints s_0 < ... < s_N and computes, by one backward pass
(controllable sets) and one forward pass (greedy), the squared path speeds x_k at the gridpoints,
with a constant path acceleration u_k = (x_{k+1} - x_k) / (2 ds) on each segment. This module runs
it on the SAME path as ours and the SAME limits, and measures how far its output exceeds them.

**The path.** :func:`sinusoid_path` evaluates our sinusoids theta_i(s) = A_i sin(w_i s + phi_i) +
gamma_i and their first two derivatives exactly, with the path parameter s equal to our path time
t in [0, T] [s]; TOPP-RA sees the exact path, not a spline fitted to it.

**The constraints.** Joint speeds (:class:`toppra.constraint.JointVelocityConstraint`), joint
accelerations (:class:`toppra.constraint.JointAccelerationConstraint`, interpolation scheme) and
joint torques (:class:`toppra.constraint.JointTorqueConstraint` with the closed-form inverse
dynamics :meth:`pipeline.model.dynamics.PlanarDynamics.torque`, in the scalar form of
:func:`scalar_inverse_dynamics`, interpolation scheme, no dry friction). A quantity whose limits
are infinite for both joints gets no constraint; an infinite limit of one joint beside a finite
one of the other is passed to toppra as :data:`UNLIMITED` (a bound no motion of this arm
reaches; toppra's own speed constraint takes an infinite speed limit as it is). Joint position
limits are not constraints of a timing (the path is fixed); jerk limits are ignored (TOPP-RA has
none). The solver is toppra's ``seidel`` (an exact 2-variable LP), the gridpoints uniform in s,
the path at rest at both ends (s' = 0 at s = 0 and s = T).

**Why the motion is reconstructed rather than taken from ``compute_trajectory``.** toppra's
``compute_trajectory`` fits a cubic spline through the gridpoints' (t_k, q(s_k)) (its default
``ParametrizeSpline``): between gridpoints that spline is neither our path nor TOPP-RA's
parameterization, so its speeds, accelerations and torques measure the spline fit, not TOPP-RA.
The parameterization TOPP-RA actually computed is x_k and the constant u_k per segment; its
motion is reconstructed here exactly: on segment k, s(tau) = s_k + sqrt(x_k) tau + u_k tau^2 / 2,
s'(tau) = sqrt(x_k) + u_k tau, for tau in [0, 2 ds / (sqrt x_k + sqrt x_{k+1})], and
q = theta(s), dq = theta'(s) s', ddq = theta''(s) s'^2 + theta'(s) u_k, tau = M(q) ddq + c(q, dq).
Its duration is sum_k 2 ds / (sqrt x_k + sqrt x_{k+1}). TOPP-RA enforces the constraints at the
gridpoints only (the interpolation scheme: at s_k with u_k and at s_{k+1} with the same u_k),
so between gridpoints the motion may exceed a limit by O(ds^2); :func:`toppra_timing` samples the
reconstruction at ``oversample`` x ``gridpoints`` instants uniform over its duration and reports
the largest relative excess per quantity.

**Failure.** toppra signals a path it cannot parameterize (uncontrollable, or a numerical failure
of its forward pass) by None / NaN; :func:`toppra_timing` raises :class:`ToppraPeerError` (a
:class:`pipeline.exceptions.PipelineError`) with toppra's return code, rather than returning an
infinite duration a table might average.
"""

from __future__ import annotations

import importlib.util
import math
import time
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import PipelineError
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.trajectory import JointTrajectory, joint_accelerations, joint_angles, joint_velocities
from pipeline.validation import check_positive_int

__all__ = [
    "EXCESS_QUANTITIES",
    "UNLIMITED",
    "ToppraPeerError",
    "ToppraResult",
    "ToppraSettings",
    "scalar_inverse_dynamics",
    "sinusoid_path",
    "toppra_available",
    "toppra_path_speeds",
    "toppra_timing",
    "toppra_version",
]

#: The quantities of :attr:`ToppraResult.excess`, in order.
EXCESS_QUANTITIES: tuple[str, ...] = ("speed", "acceleration", "torque")
#: What an infinite limit of one joint becomes in a toppra constraint whose other joint is limited
#: (rad/s^2 or N m): toppra's linear constraints want finite bounds; no motion of the arm reaches it.
UNLIMITED = 1e9


class ToppraPeerError(PipelineError):
    """TOPP-RA could not time the path (toppra returned None or NaN), or the limits leave it nothing to do.

    Attributes:
        reason: What failed, with toppra's return code when it gave one.
    """

    def __init__(self, reason: str) -> None:
        self.reason = reason
        super().__init__(f"TOPP-RA peer: {reason}")


@dataclass(frozen=True)
class ToppraSettings:
    """How TOPP-RA is run and its output checked.

    Attributes:
        gridpoints: Number of gridpoints N + 1 of TOPP-RA's discretization, uniform over the path
            time [0, T] (>= 2).
        oversample: The reconstructed motion is sampled at ``oversample * gridpoints`` instants
            uniform over its duration (>= 1).
    """

    gridpoints: int = 2000
    oversample: int = 100

    def __post_init__(self) -> None:
        check_positive_int("gridpoints", self.gridpoints, minimum=2)
        check_positive_int("oversample", self.oversample, minimum=1)


@dataclass(frozen=True)
class ToppraResult:
    """TOPP-RA's timing of one path and the sampled check of its limits.

    Attributes:
        duration_s: Duration [s] of TOPP-RA's timing (at rest at both ends), from its
            parameterization (module docstring).
        gridpoints: Number of gridpoints it used.
        solve_s: Wall time [s] of the toppra call: constraints, algorithm set-up (which evaluates
            the constraints at the gridpoints) and ``compute_parameterization``.
        samples: Number of instants the reconstructed motion was sampled at.
        max_speed_rad_s: Largest sampled |dq_i| [rad/s], per joint.
        max_acceleration_rad_s2: Largest sampled |ddq_i| [rad/s^2], per joint.
        max_torque_n_m: Largest sampled |tau_i| [N m], per joint.
        excess: Largest relative excess over the limits, per quantity of
            :data:`EXCESS_QUANTITIES` (speed, acceleration, torque): max over joints of
            max(0, value / limit - 1); 0 for an infinite limit.
    """

    duration_s: float
    gridpoints: int
    solve_s: float
    samples: int
    max_speed_rad_s: tuple[float, float]
    max_acceleration_rad_s2: tuple[float, float]
    max_torque_n_m: tuple[float, float]
    excess: tuple[float, float, float]


def toppra_available() -> bool:
    """True if the ``toppra`` library can be imported (the optional ``bench`` extra)."""
    return importlib.util.find_spec("toppra") is not None


def toppra_version() -> str | None:
    """Installed version of the ``toppra`` distribution, or None."""
    from importlib import metadata

    try:
        return metadata.version("toppra")
    except metadata.PackageNotFoundError:
        return None


_PATH_CLASS: list[type] = []


def sinusoid_path(trajectory: JointTrajectory):
    """Our path q(s) = theta(s), s in [0, T] (s is our path time [s]), evaluated exactly, as a
    :class:`toppra.interpolator.AbstractGeometricPath`: ``path(s, order)`` gives theta [rad],
    theta' [rad/s] (order 1) or theta'' [rad/s^2] (order 2) at path positions s [s], shape (n, 2)
    for an array of n positions, (2,) for a scalar. (The class is made on first use, so this
    module imports without toppra.)"""
    if not _PATH_CLASS:
        from toppra.interpolator import AbstractGeometricPath

        evaluators = (joint_angles, joint_velocities, joint_accelerations)

        class SinusoidPath(AbstractGeometricPath):
            """Our sinusoids over the path time [0, T], exactly (see :func:`sinusoid_path`)."""

            def __init__(self, trajectory: JointTrajectory) -> None:
                self.trajectory = trajectory
                self._parameters = np.asarray(trajectory.parameters, dtype=float)

            def __call__(self, path_positions, order: int = 0) -> np.ndarray:
                s = np.asarray(path_positions, dtype=float)
                values = evaluators[order](self._parameters, np.atleast_1d(s).ravel())
                return values[0] if s.ndim == 0 else values

            @property
            def dof(self) -> int:
                return 2

            @property
            def path_interval(self) -> np.ndarray:
                return np.array([0.0, self.trajectory.duration_s])

        _PATH_CLASS.append(SinusoidPath)
    return _PATH_CLASS[0](trajectory)


def _bounds(limits: tuple[float, float]) -> np.ndarray | None:
    """toppra's (2, 2) [lower, upper] bounds for symmetric per-joint limits; None if both are infinite."""
    if all(math.isinf(v) for v in limits):
        return None
    upper = np.array([UNLIMITED if math.isinf(v) else v for v in limits])
    return np.stack([-upper, upper], axis=1)


def scalar_inverse_dynamics(dynamics: PlanarDynamics):
    """:meth:`PlanarDynamics.torque <pipeline.model.dynamics.PlanarDynamics.torque>` for one state,
    in scalar arithmetic: ``f(q, dq, ddq)`` with q [rad], dq [rad/s], ddq [rad/s^2] of shape (2,)
    gives the torques [N m], shape (2,).

    toppra's torque constraint calls its inverse dynamics once per gridpoint and term (3 (N + 1)
    calls); ``PlanarDynamics.torque``, written for arrays of states, costs tens of microseconds a
    call there, which made up most of the measured solve time. The same formula on Python floats
    costs about a microsecond, so the solve time measures TOPP-RA rather than array overhead.
    """
    (m00, m01), (m10, m11) = dynamics.m0
    (c00, c01), (c10, c11) = dynamics.mc
    (s00, s01), (s10, s11) = dynamics.ms
    cos, sin = math.cos, math.sin

    def torque(q, dq, ddq) -> np.ndarray:
        q2 = float(q[1])
        d1, d2, a1, a2 = float(dq[0]), float(dq[1]), float(ddq[0]), float(ddq[1])
        c, s = cos(q2), sin(q2)
        h = 0.5 * (-c00 * s + s00 * c)
        return np.array(
            [
                (m00 + c00 * c + s00 * s) * a1 + (m01 + c01 * c + s01 * s) * a2 + h * (2.0 * d1 * d2 + d2 * d2),
                (m10 + c10 * c + s10 * s) * a1 + (m11 + c11 * c + s11 * s) * a2 - h * d1 * d1,
            ]
        )

    return torque


def _constraints(limits: ArmLimits, dynamics: PlanarDynamics) -> list:
    import toppra.constraint as constraint

    interpolation = constraint.DiscretizationType.Interpolation
    found = []
    if not all(math.isinf(v) for v in limits.velocity_rad_s):
        # toppra's speed bound handles an infinite limit itself (x <= (v / |q'|)^2 = inf).
        velocity = np.array(limits.velocity_rad_s)
        found.append(constraint.JointVelocityConstraint(np.stack([-velocity, velocity], axis=1)))
    acceleration = _bounds(limits.acceleration_rad_s2)
    if acceleration is not None:
        found.append(constraint.JointAccelerationConstraint(acceleration, discretization_scheme=interpolation))
    effort = _bounds(limits.effort_n_m)
    if effort is not None:
        found.append(
            constraint.JointTorqueConstraint(
                scalar_inverse_dynamics(dynamics), effort, np.zeros(2), discretization_scheme=interpolation
            )
        )
    return found


def toppra_path_speeds(
    trajectory: JointTrajectory,
    limits: ArmLimits,
    dynamics: PlanarDynamics,
    settings: ToppraSettings | None = None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """TOPP-RA's parameterization of ``trajectory``'s path under ``limits``.

    Returns:
        (s, x, solve_s): the gridpoints s_k [s of path time], shape (N + 1,); the squared path
        speeds x_k = s'^2 [1] at them (x_0 = x_N = 0); the wall time [s] of the toppra call.

    Raises:
        ToppraPeerError: no finite speed, acceleration or torque limit (nothing bounds the path
            speed), or toppra failed to parameterize the path.
    """
    import toppra

    settings = ToppraSettings() if settings is None else settings
    gridpoints = np.linspace(0.0, trajectory.duration_s, settings.gridpoints)
    path = sinusoid_path(trajectory)
    start = time.perf_counter()
    constraints = _constraints(limits, dynamics)
    if not constraints:
        raise ToppraPeerError("no finite speed, acceleration or torque limit: the time-optimal timing is instantaneous")
    algorithm = toppra.algorithm.TOPPRA(constraints, path, gridpoints=gridpoints, solver_wrapper="seidel")
    _, path_speed, _ = algorithm.compute_parameterization(0.0, 0.0)
    solve_s = time.perf_counter() - start
    if path_speed is None or not np.all(np.isfinite(path_speed)):
        raise ToppraPeerError(f"toppra could not parameterize the path ({algorithm.problem_data.return_code})")
    return gridpoints, np.asarray(path_speed, dtype=float) ** 2, solve_s


def _segment_times(s: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Durations [s] of the segments of a parameterization with constant path acceleration per segment."""
    speed = np.sqrt(x)
    return 2.0 * np.diff(s) / (speed[:-1] + speed[1:])


def toppra_timing(
    trajectory: JointTrajectory,
    limits: ArmLimits,
    dynamics: PlanarDynamics,
    settings: ToppraSettings | None = None,
) -> ToppraResult:
    """TOPP-RA's time-optimal timing of ``trajectory``'s path under ``limits``, and its sampled check.

    Args:
        trajectory: The path (its sinusoids over the path time [0, T]).
        limits: Speed, acceleration and effort limits per joint (inf: none); positions and any
            jerk limits are not used.
        dynamics: The arm's closed-form inverse dynamics (torques [N m]).
        settings: Gridpoints and oversampling (default :class:`ToppraSettings`).

    Raises:
        ToppraPeerError: as :func:`toppra_path_speeds`, or a parameterization that stops inside the
            path (two consecutive zero path speeds: infinite duration).
    """
    settings = ToppraSettings() if settings is None else settings
    s, x, solve_s = toppra_path_speeds(trajectory, limits, dynamics, settings)
    x = np.maximum(x, 0.0)
    segment_s = _segment_times(s, x)
    if not np.all(np.isfinite(segment_s)):
        raise ToppraPeerError("the parameterization stops inside the path (zero path speed at consecutive gridpoints)")
    node_t = np.concatenate([[0.0], np.cumsum(segment_s)])
    duration_s = float(node_t[-1])
    path_accel = np.diff(x) / (2.0 * np.diff(s))

    samples = settings.oversample * settings.gridpoints
    t = np.linspace(0.0, duration_s, samples)
    k = np.clip(np.searchsorted(node_t, t, side="right") - 1, 0, len(segment_s) - 1)
    tau = t - node_t[k]
    speed_k, u = np.sqrt(x[k]), path_accel[k]
    position = np.clip(s[k] + speed_k * tau + 0.5 * u * tau**2, s[k], s[k + 1])
    speed = np.maximum(speed_k + u * tau, 0.0)[:, None]

    parameters = np.asarray(trajectory.parameters, dtype=float)
    theta_d = joint_velocities(parameters, position)
    q = joint_angles(parameters, position)
    dq = theta_d * speed
    ddq = joint_accelerations(parameters, position) * speed**2 + theta_d * u[:, None]
    torque = dynamics.torque(q, dq, ddq)

    maxima = [tuple(float(v) for v in np.max(np.abs(values), axis=0)) for values in (dq, ddq, torque)]
    bounds = (limits.velocity_rad_s, limits.acceleration_rad_s2, limits.effort_n_m)
    excess = tuple(
        max([0.0, *(value / limit - 1.0 for value, limit in zip(peak, bound, strict=True) if math.isfinite(limit))])
        for peak, bound in zip(maxima, bounds, strict=True)
    )
    return ToppraResult(
        duration_s=duration_s,
        gridpoints=settings.gridpoints,
        solve_s=solve_s,
        samples=samples,
        max_speed_rad_s=maxima[0],
        max_acceleration_rad_s2=maxima[1],
        max_torque_n_m=maxima[2],
        excess=excess,
    )
