"""A joint trajectory under a timing: ``q(tau) = theta(sigma(tau))`` (:mod:`pipeline.motion.timing`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.motion.timing import PaperTiming, Timing
from pipeline.motion.trajectory import (
    JointTrajectory,
    checked_times,
    joint_accelerations,
    joint_angles,
    joint_jerks,
    joint_velocities,
    time_array,
)

__all__ = ["TimedTrajectory"]


@dataclass(frozen=True)
class TimedTrajectory:
    """The paper's joint path ``trajectory`` executed with ``timing``.

    Attributes:
        trajectory: The sinusoids of Eq. 1 over the path time [0, T].
        timing: Maps the executed time [0, T'] onto [0, T]; its T must be the trajectory's.
    """

    trajectory: JointTrajectory
    timing: Timing

    def __post_init__(self) -> None:
        if not isinstance(self.timing, Timing):
            raise InvalidParameterError(
                "timing", type(self.timing).__name__, "a Timing (PaperTiming, RestToRestTiming)"
            )
        timing = self.timing
        if isinstance(timing, PaperTiming) and timing.path_duration_s is None:
            object.__setattr__(self, "timing", timing.for_path(self.trajectory.duration_s))
        elif abs(self.timing.path_duration_s - self.trajectory.duration_s) > 1e-12 * self.trajectory.duration_s:
            raise InvalidParameterError(
                "timing", self.timing.path_duration_s, f"a timing of the path's T = {self.trajectory.duration_s!r} s"
            )

    @property
    def duration_s(self) -> float:
        """T' [s]."""
        return self.timing.duration_s

    @property
    def parameters(self) -> tuple[float, ...]:
        """The eight sinusoid parameters of the path."""
        return self.trajectory.parameters

    @property
    def parameter_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The parameters as a degenerate box (lower = upper), as the certificates read them."""
        p = np.asarray(self.trajectory.parameters, dtype=float)
        return p, p

    @property
    def mean_value(self) -> None:
        """One path has no mean-value form (the certificates read None)."""
        return None

    def as_dict(self) -> dict[str, float]:
        """The parameters by name."""
        return self.trajectory.as_dict()

    def times(self, t_s, outside: str = "error") -> np.ndarray:
        """Executed times [s] checked to lie in [0, T'] (or clamped into it): :func:`checked_times`."""
        return checked_times(t_s, self.duration_s, outside, "T'")

    def _states(self, t_s, outside: str):
        t = self.times(t_s, outside)
        flat = np.atleast_1d(t)
        return t, flat, np.clip(self.timing.sigma(flat), 0.0, self.trajectory.duration_s)

    def q(self, t_s, *, outside: str = "error") -> np.ndarray:
        """Joint angles [rad] at executed times [s]: (2,) for a scalar, (m, 2) for m times."""
        t, _, s = self._states(t_s, outside)
        out = joint_angles(self.parameters, s)
        return out[0] if t.ndim == 0 else out

    def dq(self, t_s, *, outside: str = "error") -> np.ndarray:
        """Joint speeds [rad/s]: theta'(sigma) sigma'."""
        t, flat, s = self._states(t_s, outside)
        out = joint_velocities(self.parameters, s) * self.timing.dsigma(flat)[:, None]
        return out[0] if t.ndim == 0 else out

    def ddq(self, t_s, *, outside: str = "error") -> np.ndarray:
        """Joint accelerations [rad/s^2]: theta''(sigma) sigma'^2 + theta'(sigma) sigma''."""
        t, flat, s = self._states(t_s, outside)
        d1, d2 = self.timing.dsigma(flat)[:, None], self.timing.ddsigma(flat)[:, None]
        out = joint_accelerations(self.parameters, s) * d1 * d1 + joint_velocities(self.parameters, s) * d2
        return out[0] if t.ndim == 0 else out

    def jerk(self, t_s, *, outside: str = "error") -> np.ndarray:
        """Joint jerks [rad/s^3]: theta''' sigma'^3 + 3 theta'' sigma' sigma'' + theta' sigma'''."""
        t, flat, s = self._states(t_s, outside)
        d1, d2, d3 = (f(flat)[:, None] for f in (self.timing.dsigma, self.timing.ddsigma, self.timing.dddsigma))
        p = self.parameters
        out = joint_jerks(p, s) * d1**3 + 3.0 * joint_accelerations(p, s) * d1 * d2 + joint_velocities(p, s) * d3
        return out[0] if t.ndim == 0 else out

    def states(self, t_s, *, outside: str = "error") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, dq, ddq) at m executed times, each (m, 2), with sigma and its derivatives evaluated
        once (the same values as :meth:`q`, :meth:`dq`, :meth:`ddq`)."""
        _, flat, s = self._states(np.atleast_1d(time_array(t_s)), outside)
        d1, d2 = self.timing.dsigma(flat)[:, None], self.timing.ddsigma(flat)[:, None]
        speed = joint_velocities(self.parameters, s)
        return (
            joint_angles(self.parameters, s),
            speed * d1,
            joint_accelerations(self.parameters, s) * d1 * d1 + speed * d2,
        )
