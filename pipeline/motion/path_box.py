"""Every path of a box of obstacles at once, in normalised path time, and its motion under one timing.

Over a box of obstacles (a cell of the fitted range) the regression's sinusoid parameters and
the path duration T lie in intervals (:mod:`pipeline.certify.execution_range`). In the
normalised path time u = s / T in [0, 1] every path of the box reads

    theta_i(u) = A_i sin(Omega_i u + phi_i) + gamma_i,   Omega_i = w_i T,

so one timing u = sigma(tau) of [0, T'] onto [0, 1] serves them all: an obstacle with duration T
executes ``q(tau) = theta(T sigma(tau))``, the timing ``T sigma`` of its own path. A
:class:`PathBox` holds the intervals of (A, Omega, phi, gamma) and one path of the box (its
centre, normalised, for the samples the certificates take); a :class:`TimedPathBox` is that box
under a timing. The execution certificate (:func:`pipeline.motion.execution_certificate.certify_execution`)
and the path constraints (:func:`pipeline.motion.path_constraints.enclose_path`) read the box's
intervals (``parameter_bounds``) where they read one path's parameters, so their bounds hold for
every path of the box; their samples are the centre's, values one path of the box takes.

**Rounding.** Omega's interval is the interval product [w] [T] widened like every enclosure
(:func:`pipeline.motion.interval_arithmetic.widen`); a path's own ``w * T`` rounds within it. A
query executing ``T sigma`` evaluates ``w (T sigma)`` where the certificate enclosed
``(w T) sigma``: the two differ by a few ulps of the phase, far below the certificates' slack.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.motion.interval_arithmetic import MeanValueForm, mul, widen
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import Timing
from pipeline.motion.trajectory import JointTrajectory

__all__ = ["PathBox", "TimedPathBox", "normalised_mean_value", "normalised_parameters"]

#: Positions of w in the eight parameters (A, w, phi, gamma per joint).
_FREQUENCIES = (1, 5)


def normalised_parameters(parameters, duration_s: float) -> np.ndarray:
    """A path's parameters in normalised path time: each w replaced by w T [rad]."""
    p = np.array(parameters, dtype=float)
    p[list(_FREQUENCIES)] *= duration_s
    return p


def normalised_mean_value(
    point: tuple[np.ndarray, np.ndarray],
    gradient: tuple[np.ndarray, np.ndarray],
    duration: tuple[tuple[float, float], tuple[float, float]],
    duration_gradient: tuple[np.ndarray, np.ndarray],
    parameters: tuple[np.ndarray, np.ndarray],
    radius: np.ndarray,
) -> MeanValueForm:
    """The mean-value form of the normalised parameters (Omega = w T) from the parameters' own.

    Args:
        point: (lower, upper) (8,) enclosure of the parameters at the box's centre.
        gradient: (lower, upper) (8, k) enclosures of their gradients over the box.
        duration: ((lo, hi) of T at the centre, (lo, hi) of T over the box) [s].
        duration_gradient: (lower, upper) (k,) enclosure of T's gradient over the box [s/m].
        parameters: (lower, upper) (8,) enclosures of the parameters over the box.
        radius: (k,) the box's half widths [m].

    Omega's gradient is ``dw/dv T + w dT/dv`` over the box, its centre value ``w(c) T(c)``, both in
    interval arithmetic and widened.
    """
    point_lo, point_hi = (np.array(v, dtype=float) for v in point)
    grad_lo, grad_hi = (np.array(v, dtype=float) for v in gradient)
    (t_c_lo, t_c_hi), (t_lo, t_hi) = duration
    for k in _FREQUENCIES:
        point_lo[k], point_hi[k] = (float(v) for v in widen(*mul(point_lo[k], point_hi[k], t_c_lo, t_c_hi)))
        w_lo, w_hi = parameters[0][k], parameters[1][k]
        first = mul(grad_lo[k], grad_hi[k], t_lo, t_hi)
        second = mul(w_lo, w_hi, *duration_gradient)
        grad_lo[k], grad_hi[k] = widen(first[0] + second[0], first[1] + second[1])
    return MeanValueForm(point_lo, point_hi, grad_lo, grad_hi, np.asarray(radius, dtype=float))


@dataclass(frozen=True, eq=False)
class PathBox:
    """The paths of a box of obstacles in normalised path time (module docstring).

    Attributes:
        lower, upper: (8,) bounds of (A, Omega, phi, gamma) per joint [rad, rad, rad, rad].
        centre: One path of the box, normalised (duration 1, its w the Omega = w T of its own T).
        mean_value: The normalised parameters' mean-value form over the box (their enclosure at
            the box's centre and their gradients' over the box), for tighter enclosures; None:
            the intervals alone.
    """

    lower: np.ndarray
    upper: np.ndarray
    centre: JointTrajectory
    mean_value: MeanValueForm | None = None

    def __post_init__(self) -> None:
        lower, upper = np.asarray(self.lower, dtype=float), np.asarray(self.upper, dtype=float)
        if lower.shape != (8,) or upper.shape != (8,) or not np.all(np.isfinite(lower) & np.isfinite(upper)):
            raise InvalidParameterError("lower, upper", (lower.shape, upper.shape), "finite (8,) bounds")
        if not np.all(lower <= upper):
            raise InvalidParameterError("lower", lower.tolist(), f"at most upper = {upper.tolist()}")
        centre = np.asarray(self.centre.parameters, dtype=float)
        if self.centre.duration_s != 1.0 or not np.all((lower <= centre) & (centre <= upper)):
            raise InvalidParameterError("centre", centre.tolist(), "a normalised path (T = 1) inside the box")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)

    @classmethod
    def of_intervals(
        cls,
        lower,
        upper,
        duration_s: tuple[float, float],
        centre_parameters,
        centre_duration_s: float,
        mean_value: MeanValueForm | None = None,
    ) -> PathBox:
        """The box of parameters in [lower, upper] (w as w, not yet normalised) and durations in
        ``duration_s`` [s], with one path of it (its parameters and T [s]) as the centre, and
        optionally the normalised parameters' mean-value form (:func:`normalised_mean_value`)."""
        try:
            lower, upper = np.array(lower, dtype=float), np.array(upper, dtype=float)
            duration_lo, duration_hi = (float(v) for v in duration_s)
        except (TypeError, ValueError):
            raise InvalidParameterError("lower, upper, duration_s", (lower, upper, duration_s), "numbers") from None
        if lower.shape != (8,) or upper.shape != (8,) or not np.all(lower <= upper):
            raise InvalidParameterError("lower", lower.tolist(), f"(8,) bounds at most upper = {upper.tolist()}")
        if not (0.0 < duration_lo <= duration_hi < math.inf):
            raise InvalidParameterError("duration_s", duration_s, "0 < lo <= hi < inf [s]")
        for k in _FREQUENCIES:
            lower[k], upper[k] = (float(v) for v in widen(*mul(lower[k], upper[k], duration_lo, duration_hi)))
        centre = JointTrajectory(tuple(normalised_parameters(centre_parameters, centre_duration_s)), 1.0)
        return cls(lower, upper, centre, mean_value)

    def timed(self, timing: Timing) -> TimedPathBox:
        """The box under ``timing`` (of [0, T'] onto the normalised path time [0, 1])."""
        return TimedPathBox(self, timing)


@dataclass(frozen=True, eq=False)
class TimedPathBox:
    """Every path of a box under one timing of the normalised path time (module docstring).

    Attributes:
        box: The paths.
        timing: Maps the executed time [0, T'] onto [0, 1].
    """

    box: PathBox
    timing: Timing

    def __post_init__(self) -> None:
        object.__setattr__(self, "_centre", TimedTrajectory(self.box.centre, self.timing))

    @property
    def duration_s(self) -> float:
        """T' [s]."""
        return self.timing.duration_s

    @property
    def parameter_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The box's bounds of the normalised parameters, as the certificates read them."""
        return self.box.lower, self.box.upper

    @property
    def mean_value(self) -> MeanValueForm | None:
        """The box's mean-value form, as the certificates read it."""
        return self.box.mean_value

    def states(self, t_s, *, outside: str = "error") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, dq, ddq of the box's centre path at executed times ``t_s`` [s]."""
        return self._centre.states(t_s, outside=outside)

    def jerk(self, t_s, *, outside: str = "error") -> np.ndarray:
        """The jerk of the box's centre path at executed times ``t_s`` [s]."""
        return self._centre.jerk(t_s, outside=outside)
