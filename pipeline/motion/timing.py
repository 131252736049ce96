"""Timings of a joint path: when the arm is where along the paper's trajectory.

A timing is a smooth, non-decreasing map ``sigma`` of the executed time ``tau`` in [0, T'] onto the
paper's time ``t`` in [0, T]; the executed motion is ``q(tau) = theta(sigma(tau))``, so every
timing visits exactly the configurations of the paper's timing, in the same order: the
clearance and endpoint certificates, which are statements about those configurations, hold for
every timing unchanged. Speeds and accelerations follow by the chain rule:
``dq = theta'(sigma) sigma'`` and ``ddq = theta''(sigma) sigma'^2 + theta'(sigma) sigma''``.

* :class:`PaperTiming`: ``sigma(tau) = tau``, T' = T (the paper's constant end-effector speed,
  held from t = 0: the arm starts and stops moving, a velocity step at each end).
* :class:`RestToRestTiming`: the paper's constant speed, scaled by ``speed_scale`` c <= 1, in the
  middle, and a smooth ramp of duration ``ramp_s`` r at each end, on which
  ``sigma' = c s(u)`` with ``s(u) = 3 u^2 - 2 u^3`` (u = tau / r on the way in, (T' - tau) / r
  on the way out). s(0) = s'(0) = 0 and s(1) = 1, s'(1) = 0, so sigma' and sigma'' are
  continuous, sigma'(0) = sigma''(0) = 0 and likewise at T': dq and ddq are exactly 0 at both ends.
  On the ramp in, ``sigma = c r (u^3 - u^4 / 2)`` (c r / 2 at u = 1); so
  ``T = c (T' - r)``, i.e. ``T' = T / c + r`` (the ramps must fit: r <= T / c).
  Why this profile: it is the shortest polynomial blend with continuous acceleration that keeps
  the paper's constant path speed in the middle; its bounds are closed-form
  (max sigma' = c, max |sigma''| = 1.5 c / r at u = 1/2), which lets the shortest T' under
  the arm's limits be found from closed-form bounds (:mod:`pipeline.motion.rest_to_rest`). The
  jerk (sigma''' = 6 c / r^2 at the ends) is bounded but not zero.

Both give ``sigma``, ``sigma'``, ``sigma''`` at times and, for the certificates, their exact
ranges over intervals of tau (the candidate points where each piece has its extremes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError

__all__ = ["PAPER_TIMING", "PaperTiming", "RestToRestTiming", "Timing"]


class Timing:
    """Base of the timings: ``sigma`` maps executed time [0, T'] onto the path time [0, T]."""

    name: str = ""

    @property
    def duration_s(self) -> float:  # pragma: no cover - every timing defines it
        raise NotImplementedError

    def sigma(self, tau_s: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def dsigma(self, tau_s: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def ddsigma(self, tau_s: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def dddsigma(self, tau_s: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def ranges(self, lo_s: np.ndarray, hi_s: np.ndarray) -> tuple[np.ndarray, ...]:  # pragma: no cover
        """(sigma_lo, sigma_hi, dsigma_lo, dsigma_hi, ddsigma_lo, ddsigma_hi) over [lo, hi] (arrays)."""
        raise NotImplementedError

    def jerk_ranges(self, lo_s: np.ndarray, hi_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
        """(dddsigma_lo, dddsigma_hi) over [lo, hi] (arrays)."""
        raise NotImplementedError

    def ranges_with_jerk(self, lo_s: np.ndarray, hi_s: np.ndarray) -> tuple[np.ndarray, ...]:
        """:meth:`ranges`, then :meth:`jerk_ranges`: eight arrays."""
        return (*self.ranges(lo_s, hi_s), *self.jerk_ranges(lo_s, hi_s))

    @property
    def knots_s(self) -> np.ndarray:
        """Times [s] the execution certificate's first partition starts from: [0, T'] for the
        paper's and the rest-to-rest timings (bounded in closed form, or bisected from one
        interval); a smooth timing's breakpoints, between which its sigma is one cubic."""
        return np.array([0.0, self.duration_s])


@dataclass(frozen=True)
class PaperTiming(Timing):
    """The paper's timing: sigma(tau) = tau over [0, T].

    Attributes:
        path_duration_s: T [s] (None: the timing of any path, bound to one by :meth:`for_path`).
    """

    path_duration_s: float | None = None
    name: str = "paper"

    def for_path(self, path_duration_s: float) -> PaperTiming:
        """This timing for a path of duration T [s]."""
        return PaperTiming(float(path_duration_s))

    @property
    def duration_s(self) -> float:
        """T' = T [s]."""
        return float(self.path_duration_s)

    def sigma(self, tau_s):
        return np.asarray(tau_s, dtype=float)

    def dsigma(self, tau_s):
        return np.ones_like(np.asarray(tau_s, dtype=float))

    def ddsigma(self, tau_s):
        return np.zeros_like(np.asarray(tau_s, dtype=float))

    def dddsigma(self, tau_s):
        return np.zeros_like(np.asarray(tau_s, dtype=float))

    def ranges(self, lo_s, hi_s):
        lo, hi = np.asarray(lo_s, dtype=float), np.asarray(hi_s, dtype=float)
        one, zero = np.ones_like(lo), np.zeros_like(lo)
        return lo, hi, one, one, zero, zero

    def jerk_ranges(self, lo_s, hi_s):
        zero = np.zeros_like(np.asarray(lo_s, dtype=float))
        return zero, zero


#: The paper's timing (bound to a path's T when used).
PAPER_TIMING = PaperTiming()


def _ramp_s(u):
    """s(u) = 3 u^2 - 2 u^3 for u in [0, 1]."""
    return u * u * (3.0 - 2.0 * u)


@dataclass(frozen=True)
class RestToRestTiming(Timing):
    """Constant scaled speed in the middle, smooth ramps at the ends (module docstring).

    Attributes:
        path_duration_s: T, the paper timing's duration of the path [s].
        speed_scale: c in (0, 1], the path speed in the middle relative to the paper's.
        ramp_s: r > 0, the duration of each ramp [s]; r <= T / c.
    """

    path_duration_s: float
    speed_scale: float
    ramp_s: float
    name: str = "rest-to-rest"

    def __post_init__(self) -> None:
        for field_name in ("path_duration_s", "speed_scale", "ramp_s"):
            value = getattr(self, field_name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
                raise InvalidParameterError(field_name, value, "a positive finite number")
        if self.speed_scale > 1.0:
            raise InvalidParameterError("speed_scale", self.speed_scale, "at most 1 (the paper's path speed)")
        if self.ramp_s > self.path_duration_s / self.speed_scale:
            raise InvalidParameterError(
                "ramp_s", self.ramp_s, f"at most T / c = {self.path_duration_s / self.speed_scale!r} s (ramps fit)"
            )

    @property
    def duration_s(self) -> float:
        """T' = T / c + r [s]."""
        return self.path_duration_s / self.speed_scale + self.ramp_s

    def _parts(self, tau_s):
        tau = np.asarray(tau_s, dtype=float)
        end = self.duration_s
        u_in = np.clip(tau / self.ramp_s, 0.0, 1.0)
        u_out = np.clip((end - tau) / self.ramp_s, 0.0, 1.0)
        return tau, end, u_in, u_out

    def sigma(self, tau_s):
        tau, end, u_in, u_out = self._parts(tau_s)
        c, r, total = self.speed_scale, self.ramp_s, self.path_duration_s
        ramp_in = c * r * (u_in**3 - 0.5 * u_in**4)
        middle = c * r / 2.0 + c * (tau - r)
        ramp_out = total - c * r * (u_out**3 - 0.5 * u_out**4)
        out = np.where(tau < r, ramp_in, np.where(tau > end - r, ramp_out, middle))
        return np.clip(out, 0.0, total)

    def dsigma(self, tau_s):
        tau, end, u_in, u_out = self._parts(tau_s)
        c, r = self.speed_scale, self.ramp_s
        return c * np.where(tau < r, _ramp_s(u_in), np.where(tau > end - r, _ramp_s(u_out), 1.0))

    def ddsigma(self, tau_s):
        tau, end, u_in, u_out = self._parts(tau_s)
        c, r = self.speed_scale, self.ramp_s
        slope_in, slope_out = 6.0 * u_in * (1.0 - u_in), 6.0 * u_out * (1.0 - u_out)
        return (c / r) * np.where(tau < r, slope_in, np.where(tau > end - r, -slope_out, 0.0))

    def dddsigma(self, tau_s):
        """sigma''' [1/s^2]: (c / r^2) 6 (1 - 2 u) on each ramp (u as above), 0 between."""
        tau, end, u_in, u_out = self._parts(tau_s)
        c, r = self.speed_scale, self.ramp_s
        ramp_in, ramp_out = 6.0 * (1.0 - 2.0 * u_in), 6.0 * (1.0 - 2.0 * u_out)
        return (c / r**2) * np.where(tau < r, ramp_in, np.where(tau > end - r, ramp_out, 0.0))

    def jerk_ranges(self, lo_s, hi_s):
        """sigma''' over [lo, hi]: linear in tau on each ramp, 0 between; the union over the parts it meets."""
        lo, hi = np.asarray(lo_s, dtype=float), np.asarray(hi_s, dtype=float)
        c, r, end = self.speed_scale, self.ramp_s, self.duration_s
        k = 6.0 * c / r**2
        low, high = np.full_like(lo, np.inf), np.full_like(lo, -np.inf)
        for a, b, value in (
            (0.0, r, lambda t: k * (1.0 - 2.0 * t / r)),
            (r, end - r, lambda t: np.zeros_like(t)),
            (end - r, end, lambda t: k * (1.0 - 2.0 * (end - t) / r)),
        ):
            meets = (hi >= a) & (lo <= b) & (b >= a)
            ends = np.stack([value(np.clip(lo, a, b)), value(np.clip(hi, a, b))])
            low = np.where(meets, np.minimum(low, ends.min(0)), low)
            high = np.where(meets, np.maximum(high, ends.max(0)), high)
        return low, high

    def ranges(self, lo_s, hi_s):
        """Ranges over [lo, hi] of sigma (monotone: its ends), and of sigma', sigma'' (piecewise
        polynomials whose extremes lie at the interval's ends or at r / 2, r, T' - r, T' - r / 2)."""
        lo, hi = np.asarray(lo_s, dtype=float), np.asarray(hi_s, dtype=float)
        end, r = self.duration_s, self.ramp_s
        candidates = [lo, hi]
        for point in (r / 2.0, r, end - r, end - r / 2.0):
            candidates.append(np.clip(np.full_like(lo, point), lo, hi))
        stack = np.stack(candidates)
        d1, d2 = self.dsigma(stack), self.ddsigma(stack)
        return self.sigma(lo), self.sigma(hi), d1.min(0), d1.max(0), d2.min(0), d2.max(0)
