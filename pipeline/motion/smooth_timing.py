"""A timing with continuous acceleration: ``sigma`` a C2 piecewise cubic of the executed time.

The timing maps the executed time tau in [0, T'] onto the path time s in [0, T]
(:mod:`pipeline.motion.timing`). Here sigma is a cubic on each segment [tau_j, tau_j+1] of its
breakpoints, with constant third derivative (jerk) ``j_j``, and sigma, sigma', sigma'' continuous
across breakpoints; sigma' = sigma'' = 0 at both ends. So the joint accelerations
``ddq = theta''(sigma) sigma'^2 + theta'(sigma) sigma''`` are continuous everywhere, and the joint
jerk ``theta''' sigma'^3 + 3 theta'' sigma' sigma'' + theta' sigma'''`` is bounded.

**From a profile with steps in acceleration.** A profile of constant path acceleration ``u_k`` on
each of its pieces (:mod:`pipeline.motion.speed_profile`), starting and ending at rest, has
``sigma'' = sum_k du_k H(tau - tau_k)``, a sum of steps ``du_k = u_k - u_k-1`` at the times tau_k
where the pieces meet (u_-1 = u_n = 0: the steps at the start and the end). :func:`smoothed`
replaces every step by a ramp of width ``delta_k`` centred on tau_k. A ramp centred on its step has
the same integral as the step beyond the window (their difference is odd about tau_k), so sigma'
is unchanged outside every window and the end is still at rest: ``sigma'(end) = sum_k du_k (end -
tau_k)``, as before. sigma itself moves by ``du_k delta_k^2 / 24`` per window; the whole timing is
scaled by the one factor that puts its end at exactly T (a factor within 1e-3 of 1, reported).
The motion is lengthened by as much as the ramps reach before the first step and after the last
(half of the first and last ramps' widths, unless a wider one reaches farther); the others do not
lengthen it.

**Ranges over an interval** (for the certificates): within a segment, sigma''' is constant,
sigma'' linear (its range is at the interval's ends), sigma' quadratic (ends and vertex) and sigma
cubic (ends and the roots of sigma'); across segments, the union of the segments' ranges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.motion.timing import Timing

__all__ = ["SmoothTiming", "smoothed"]

#: sigma' down to this fraction of its largest value below 0 is rounding, not a reversal.
_SPEED_ROUNDING = 1e-12


@dataclass(frozen=True, eq=False)
class SmoothTiming(Timing):
    """sigma as a C2 piecewise cubic (module docstring).

    Attributes:
        path_duration_s: T [s].
        breakpoints_s: (m + 1,) increasing executed times, from 0 to T' [s].
        start: (m, 3) sigma [s], sigma' [1], sigma'' [1/s] at each segment's start.
        jerk: (m,) sigma''' on each segment [1/s^2].
        name: The timing's name.
    """

    path_duration_s: float
    breakpoints_s: np.ndarray
    start: np.ndarray
    jerk: np.ndarray
    name: str = "near-optimal"

    def __post_init__(self) -> None:
        knots = np.asarray(self.breakpoints_s, dtype=float)
        if knots.ndim != 1 or knots.size < 2 or knots[0] != 0.0 or not np.all(np.diff(knots) > 0.0):
            raise InvalidParameterError("breakpoints_s", knots.size, "increasing times from 0 [s]")
        if np.shape(self.start) != (knots.size - 1, 3) or np.shape(self.jerk) != (knots.size - 1,):
            raise InvalidParameterError("start", np.shape(self.start), f"({knots.size - 1}, 3) and jerk of that length")

    @property
    def duration_s(self) -> float:
        """T' [s]."""
        return float(self.breakpoints_s[-1])

    def scaled(self, path_duration_s: float) -> SmoothTiming:
        """``T sigma`` for a timing of the normalised path time [0, 1]: the same breakpoints, sigma
        and its derivatives times T = ``path_duration_s`` [s] (built without re-validating: the
        breakpoints are this timing's, checked when it was built)."""
        timing = object.__new__(SmoothTiming)
        fields = timing.__dict__
        fields["path_duration_s"] = path_duration_s
        fields["breakpoints_s"] = self.breakpoints_s
        fields["start"] = path_duration_s * self.start
        fields["jerk"] = path_duration_s * self.jerk
        fields["name"] = self.name
        return timing

    @property
    def knots_s(self) -> np.ndarray:
        """The breakpoints [s]: sigma is one cubic between consecutive knots."""
        return self.breakpoints_s

    def _local(self, tau_s):
        tau = np.clip(np.asarray(tau_s, dtype=float), 0.0, self.duration_s)
        j = np.clip(np.searchsorted(self.breakpoints_s, tau, side="right") - 1, 0, self.jerk.size - 1)
        return j, tau - self.breakpoints_s[j]

    def sigma(self, tau_s):
        j, h = self._local(tau_s)
        c0, c1, c2 = self.start[j, 0], self.start[j, 1], self.start[j, 2]
        value = c0 + h * (c1 + h * (c2 / 2.0 + h * self.jerk[j] / 6.0))
        return np.where(np.asarray(tau_s) >= self.duration_s, self.path_duration_s, value)

    def dsigma(self, tau_s):
        j, h = self._local(tau_s)
        value = self.start[j, 1] + h * (self.start[j, 2] + h * self.jerk[j] / 2.0)
        return np.where(np.asarray(tau_s) >= self.duration_s, 0.0, value)  # at rest at the end, exactly

    def ddsigma(self, tau_s):
        j, h = self._local(tau_s)
        return np.where(np.asarray(tau_s) >= self.duration_s, 0.0, self.start[j, 2] + h * self.jerk[j])

    def dddsigma(self, tau_s):
        """sigma''' [1/s^2] (the right-hand value at a breakpoint; 0 at and after the end)."""
        j, _ = self._local(tau_s)
        return np.where(np.asarray(tau_s) >= self.duration_s, 0.0, self.jerk[j])

    def _segment_ranges(self, j, a, b):
        """Ranges of sigma, sigma', sigma'', sigma''' over local [a, b] of segments j (arrays)."""
        c0, c1, c2, k = self.start[j, 0], self.start[j, 1], self.start[j, 2], self.jerk[j]

        def s0(h):
            return c0 + h * (c1 + h * (c2 / 2.0 + h * k / 6.0))

        def s1(h):
            return c1 + h * (c2 + h * k / 2.0)

        d2 = np.stack([c2 + a * k, c2 + b * k])
        with np.errstate(divide="ignore", invalid="ignore"):
            vertex = np.where(k != 0.0, -c2 / k, a)
            disc = c2 * c2 - 2.0 * k * c1
            root = np.sqrt(np.maximum(disc, 0.0))
            roots = [np.where(k != 0.0, (-c2 + sign * root) / k, np.where(c2 != 0.0, -c1 / c2, a)) for sign in (-1, 1)]
        d1 = np.stack([s1(a), s1(b), s1(np.clip(vertex, a, b))])
        s = np.stack([s0(a), s0(b), *(s0(np.clip(r, a, b)) for r in roots)])
        return s.min(0), s.max(0), d1.min(0), d1.max(0), d2.min(0), d2.max(0), k, k

    def ranges(self, lo_s, hi_s):
        """(sigma_lo, sigma_hi, sigma'_lo, sigma'_hi, sigma''_lo, sigma''_hi) over each [lo, hi]."""
        return self.ranges_with_jerk(lo_s, hi_s)[:6]

    def ranges_with_jerk(self, lo_s, hi_s):
        """As :meth:`ranges`, then sigma'''s (lo, hi): eight arrays."""
        lo, hi = np.atleast_1d(np.asarray(lo_s, dtype=float)), np.atleast_1d(np.asarray(hi_s, dtype=float))
        j_lo, a = self._local(lo)
        j_hi, b_end = self._local(hi)
        same = j_lo == j_hi
        # A right end exactly on a breakpoint belongs to the segment before it.
        at_knot = (~same) & (b_end == 0.0) & (j_hi == j_lo + 1)
        j_hi = np.where(at_knot, j_lo, j_hi)
        same = same | at_knot
        widths = np.diff(self.breakpoints_s)
        b = np.where(at_knot, widths[j_lo], np.where(same, b_end, widths[j_lo]))
        out = [np.array(v, dtype=float) * np.ones_like(lo) for v in self._segment_ranges(j_lo, a, b)]
        for row in np.flatnonzero(~same):  # several segments: the union of their ranges
            last = self._segment_ranges(np.array([j_hi[row]]), np.zeros(1), np.array([b_end[row]]))
            middle = np.arange(j_lo[row] + 1, j_hi[row])
            parts = [last]
            if middle.size:
                parts.append(self._segment_ranges(middle, np.zeros(middle.size), widths[middle]))
            for q in range(8):
                values = np.concatenate([np.atleast_1d(p[q]) for p in parts] + [out[q][row : row + 1]])
                out[q][row] = values.min() if q % 2 == 0 else values.max()
        # At T' itself the timing is exactly at rest at T (the last cubic ends there up to the
        # rounding of its sums): an interval reaching T' holds those values too.
        end = hi >= self.duration_s
        for q, value in enumerate((self.path_duration_s, 0.0, 0.0, 0.0)):
            out[2 * q][end] = np.minimum(out[2 * q][end], value)
            out[2 * q + 1][end] = np.maximum(out[2 * q + 1][end], value)
        return tuple(out)

    def speed_range(self, inner: bool = False) -> tuple[float, float]:
        """The least and largest sigma' over the whole timing (exact: each segment's ends and the
        vertex of its quadratic) [1]. ``inner``: leave out the last segment's end, where sigma' is
        0 by construction (the cubic's own value there is 0 up to the rounding of its sums)."""
        c1, c2, k = self.start[:, 1], self.start[:, 2], self.jerk
        h = np.diff(self.breakpoints_s)
        with np.errstate(divide="ignore", invalid="ignore"):
            vertex = np.clip(np.where(k != 0.0, -c2 / k, 0.0), 0.0, h)
        ends = c1 + h * (c2 + h * k / 2.0)
        vertices = c1 + vertex * (c2 + vertex * k / 2.0)
        if inner:
            ends = ends[:-1]
            vertices = vertices[:-1] if vertex[-1] >= h[-1] else vertices  # a vertex at the end is the end
        values = np.concatenate([c1, ends, vertices])
        return float(values.min()), float(values.max())

    def jerk_ranges(self, lo_s, hi_s):
        """sigma''' (lo, hi) over each [lo, hi]."""
        return self.ranges_with_jerk(lo_s, hi_s)[6:]


def smoothed(
    step_times_s: np.ndarray, steps: np.ndarray, windows_s: np.ndarray, path_duration_s: float
) -> tuple[SmoothTiming, float]:
    """The timing whose sigma'' ramps through every step of a piecewise constant path
    acceleration (module docstring).

    sigma must not decrease (the motion would go back along the path). Ramps of opposite signs
    that overlap where the path speed is low could make sigma' negative (or even end sigma below
    0); then every ramp is given
    the widest width: with one width for all, sigma'' is the unsmoothed sigma'' averaged over a
    sliding window (a box convolution), so sigma' is the unsmoothed one averaged, never negative,
    and sigma ends at T exactly (factor 1).

    Args:
        step_times_s: (n + 1,) the times tau_k of the steps of the unsmoothed profile [s], from 0.
        steps: (n + 1,) du_k, the steps of sigma'' there [1/s] (their sum is 0).
        windows_s: (n + 1,) the ramps' widths delta_k > 0 [s].
        path_duration_s: T [s], where sigma must end.

    Returns:
        (the timing, the factor sigma was scaled by to end at T).
    """
    found = _superposed(step_times_s, steps, windows_s, path_duration_s)
    if found is not None:
        lowest, highest = found[0].speed_range(inner=True)
        if lowest >= -_SPEED_ROUNDING * highest:
            return found
    widest = np.full_like(np.asarray(windows_s, dtype=float), float(np.max(windows_s)))
    found = _superposed(step_times_s, steps, widest, path_duration_s)
    if found is None:
        raise InvalidParameterError("steps", np.abs(np.asarray(steps)).max(), "a profile that moves along the path")
    return found


def _superposed(step_times_s, steps, windows_s, path_duration_s) -> tuple[SmoothTiming, float] | None:
    """:func:`smoothed`'s ramps, superposed and integrated (module docstring); None where sigma
    does not end above 0 (ramps of opposite signs that reverse the motion)."""
    knots, start, jerk = _integrated(
        np.ascontiguousarray(step_times_s, dtype=float),
        np.ascontiguousarray(steps, dtype=float),
        np.ascontiguousarray(windows_s, dtype=float),
    )
    h = knots[-1] - knots[-2]
    c0, c1, c2, k = start[-1, 0], start[-1, 1], start[-1, 2], jerk[-1]
    end = float(c0 + h * (c1 + h * (c2 / 2.0 + h * k / 6.0)))
    if not (math.isfinite(end) and end > 0.0):
        return None
    factor = float(path_duration_s) / end
    timing = SmoothTiming(float(path_duration_s), knots, factor * start, factor * jerk)
    return timing, factor


@numba.njit(cache=True, nogil=True)
def _integrated(step_times, steps, windows):
    """The breakpoints, the (sigma, sigma', sigma'') at each segment's start and the jerk on each,
    before scaling: every step's ramp starts and ends an event of slope +-du/delta; events at one
    time merge; the jerk is their running sum, integrated three times from rest at 0."""
    m = steps.size
    shift = 0.0
    for k in range(m):
        shift = max(shift, 0.5 * windows[k] - step_times[k])  # the earliest ramp starts at 0
    events = np.empty(2 * m)
    change = np.empty(2 * m)
    for k in range(m):
        centre, half, slope = step_times[k] + shift, 0.5 * windows[k], steps[k] / windows[k]
        events[k], change[k] = centre - half, slope
        events[m + k], change[m + k] = centre + half, -slope
    order = np.argsort(events, kind="mergesort")
    knots = np.empty(2 * m)
    rates = np.empty(2 * m)
    count, running = 0, 0.0
    for index in order:
        t = max(events[index], 0.0)
        if count == 0 or t > knots[count - 1]:
            knots[count] = t
            count += 1
            rates[count - 1] = running
        running += change[index]
        rates[count - 1] = running
    knots = knots[:count]
    jerk = rates[: count - 1].copy()
    start = np.zeros((count - 1, 3))
    for j in range(count - 2):
        h, k = knots[j + 1] - knots[j], jerk[j]
        s, v, a = start[j, 0], start[j, 1], start[j, 2]
        start[j + 1, 0] = s + v * h + a * h * h / 2.0 + k * h**3 / 6.0
        start[j + 1, 1] = v + a * h + k * h * h / 2.0
        start[j + 1, 2] = a + k * h
    return knots, start, jerk
