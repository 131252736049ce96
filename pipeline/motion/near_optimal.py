"""The near time-optimal timing of a joint path, smooth and certified in continuous time.

The path's configurations are kept (``q(tau) = theta(sigma(tau))``, :mod:`pipeline.motion.timing`);
only the speed along it is chosen, as fast as the limits allow:

1. **Constraints per piece.** The path time [0, T] is cut into n equal pieces; over each, the
   speed, acceleration and torque limits become linear constraints on (sdot^2, sddot) with
   worst-case coefficients (:mod:`pipeline.motion.path_constraints`), on a share of each limit
   (:class:`NearOptimalSettings`: 98 % of the acceleration and effort limits, 99 % of the speed limits).
2. **Fastest profile.** Reachability passes give the fastest profile with constant path
   acceleration per piece that keeps those constraints over every piece and starts and ends at
   rest (:mod:`pipeline.motion.speed_profile`). Two terms of the joint jerk do not depend on the
   ramps of step 3 and are kept to :data:`JERK_SPEED_SHARE` of the jerk limit here: the path's own
   curvature at speed, ``|theta'''| sdot^3``, by a cap on the path speed; and
   ``3 |theta''| sdot |sddot|``, by a bound on the path acceleration of the pieces where the
   profile exceeds it (the profile rebuilt with that bound, a few rounds).
3. **Smooth.** Its path acceleration steps where pieces meet; each step becomes a ramp centred on
   it (:func:`pipeline.motion.smooth_timing.smoothed`), of width
   ``delta_k = max_i |theta_i'| |du_k| / (jerk_share J_i - background_i)``: the ramp's share of
   joint i's jerk, ``theta_i' sigma'''``, stays within what the jerk limit J_i leaves after the
   other terms ``theta_i''' sigma'^3 + 3 theta_i'' sigma' sigma''`` (estimated from the profile at
   the step); ramps of one sign that overlap are sized for the sum of their steps, and an inner
   ramp is at least as wide as the narrower piece beside it (small steps blend). The joint
   accelerations are then continuous, and zero at both ends with the speeds.
4. **Certified.** The execution certificate (:mod:`pipeline.motion.execution_certificate`)
   bounds the angles, speeds, accelerations, torques and jerks over all of [0, T'] in continuous
   time and decides every limit. If a bound other than the jerk exceeds its limit (the ramps
   moved the profile off the constraints it was built on), the profile is rebuilt on the shares
   lowered by the bounds' excess; if only the jerk does, the ramps are widened by its excess.
   After :attr:`NearOptimalSettings.tries` attempts the timing is refused with the last bounds.

What the user receives is certified; steps 1 to 3 only make it likely to be certified at once and
close to the fastest. A jerk limit is required (a finite one per joint): with none, the ramps
would have no width and the accelerations would step (:meth:`pipeline.model.limits.ArmLimits.with_servo_defaults`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from pipeline.exceptions import InvalidParameterError, TimingRefusedError
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.execution_certificate import ExecutionCertificate, LimitViolation, certify_execution
from pipeline.motion.interval_arithmetic import magnitude
from pipeline.motion.path_box import PathBox, TimedPathBox
from pipeline.motion.path_constraints import compiled_piece_constraints, enclose_path, piece_constraints
from pipeline.motion.smooth_timing import SmoothTiming, smoothed
from pipeline.motion.speed_profile import fastest_profile
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.trajectory import JointTrajectory

#: Share of each jerk limit the path speed may spend on the jerk of the path's own curvature,
#: |theta'''| sdot^3, so that the ramps keep room (module docstring, step 2).
JERK_SPEED_SHARE = 0.5
#: Rounds of bounding the path acceleration where it makes too much jerk at speed, and an
#: absent bound's stand-in.
_JERK_ROUNDS = 3
_NO_BOUND = 1e300
#: Rounds of sizing the ramps for the steps of one sign they overlap.
_WINDOW_ROUNDS = 3

__all__ = [
    "NEAR_OPTIMAL",
    "NearOptimal",
    "NearOptimalSettings",
    "NearOptimalTiming",
    "near_optimal_box_timing",
    "near_optimal_timing",
    "profile_timing",
]


@dataclass(frozen=True)
class NearOptimalSettings:
    """How the near time-optimal timing is built (module docstring).

    Attributes:
        pieces: Pieces of the path (n); more pieces enclose tighter and cost more.
        limit_share: Share of each acceleration and effort limit the profile is built on, in (0, 1].
        speed_share: Share of each speed limit the profile is built on, in (0, 1] (the ramps
            move the speeds less than the accelerations and torques: a larger share).
        jerk_share: Share of each jerk limit the ramps are sized for, in (0, 1].
        tries: Attempts before the timing is refused (>= 1).
        longest_duration_s: A timing that needs longer than this [s] is refused: a limit far below
            what the path needs (a jerk limit of 1e-6 rad/s^3 makes the motion last years).
    """

    pieces: int = 200
    limit_share: float = 0.98
    speed_share: float = 0.99
    jerk_share: float = 0.9
    tries: int = 8
    longest_duration_s: float = 3600.0

    def __post_init__(self) -> None:
        if not (isinstance(self.pieces, int) and not isinstance(self.pieces, bool) and self.pieces >= 2):
            raise InvalidParameterError("pieces", self.pieces, "an integer >= 2")
        for name in ("limit_share", "speed_share", "jerk_share"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and 0.0 < value <= 1.0):
                raise InvalidParameterError(name, value, "a share in (0, 1]")
        if not (isinstance(self.tries, int) and not isinstance(self.tries, bool) and self.tries >= 1):
            raise InvalidParameterError("tries", self.tries, "an integer >= 1")
        if not (isinstance(self.longest_duration_s, int | float) and 0.0 < self.longest_duration_s < math.inf):
            raise InvalidParameterError("longest_duration_s", self.longest_duration_s, "a finite duration > 0 [s]")


@dataclass(frozen=True)
class NearOptimal:
    """Ask for the near time-optimal timing (``generate_certified(..., timing=NEAR_OPTIMAL)``).

    Attributes:
        settings: How it is built.
        from_map: Where the region map's near-optimal cells hold this timing for the answer's
            obstacle, arm and limits (:mod:`pipeline.certify.near_optimal_cells`; only with the
            default settings), read it off them; False: build and certify it per query.
    """

    settings: NearOptimalSettings = NearOptimalSettings()
    name: str = "near-optimal"
    from_map: bool = True


#: The near time-optimal, smooth, certified timing with the default settings.
NEAR_OPTIMAL = NearOptimal()


@dataclass(frozen=True, eq=False)
class NearOptimalTiming:
    """A certified near time-optimal timing of a path.

    Attributes:
        executed: The path with its timing (``q``, ``dq``, ``ddq``, ``jerk`` at executed times).
        certificate: Its bounds over all of [0, T'], decided against the limits.
        limit_share: The share of the acceleration and effort limits the certified profile was built on.
        attempts: Profiles built until one was certified.
        profile: For a box (:func:`near_optimal_box_timing`), the stored profile (x, ramp widths),
            float32, from which :func:`profile_timing` rebuilds the timing; None for one path.
    """

    executed: TimedTrajectory | TimedPathBox
    certificate: ExecutionCertificate
    limit_share: float
    attempts: int
    profile: tuple[np.ndarray, np.ndarray] | None = None


def _check_jerk(limits: ArmLimits) -> None:
    if not all(math.isfinite(j) for j in limits.jerk_rad_s3):
        raise InvalidParameterError(
            "jerk_rad_s3", limits.jerk_rad_s3, "a finite jerk limit per joint (ArmLimits.with_servo_defaults)"
        )


def _windows(peaks: np.ndarray, x, u, times, steps, limits: ArmLimits, jerk_share: float) -> np.ndarray:
    """The ramps' widths delta_k [s] at the n + 1 steps (module docstring, step 3), from the peaks
    (3, n, 2) of |theta'|, |theta''|, |theta'''| on each piece."""
    allowed = jerk_share * np.asarray(limits.jerk_rad_s3, dtype=float)
    gain = _gains(np.ascontiguousarray(peaks), x, u, allowed)
    return _clustered(times, steps, gain, _WINDOW_ROUNDS)


@numba.njit(cache=True, nogil=True)
def _gains(peaks, x, u, allowed):
    """Per step k (where pieces k - 1 and k meet), the width per unit of du [s]: the largest over
    the joints of |theta_i'| / (allowed_i - background_i), the background being the jerk
    |theta_i'''| sdot^3 + 3 |theta_i''| sdot |sddot| at the step (the peaks of the pieces beside
    it), and the room at least a quarter of what is allowed."""
    n = u.size
    gain = np.zeros(n + 1)
    for k in range(n + 1):
        left, right = max(k - 1, 0), min(k, n - 1)
        u_near = max(abs(u[k - 1]) if k > 0 else 0.0, abs(u[k]) if k < n else 0.0)
        root = math.sqrt(x[k])
        for i in range(2):
            speed = max(peaks[0, left, i], peaks[0, right, i])
            second = max(peaks[1, left, i], peaks[1, right, i])
            third = max(peaks[2, left, i], peaks[2, right, i])
            background = third * root**3 + 3.0 * second * root * u_near
            gain[k] = max(gain[k], speed / max(allowed[i] - background, 0.25 * allowed[i]))
    return gain


@numba.njit(cache=True, nogil=True)
def _clustered(times, steps, gain, rounds):
    """Widths gain_k |du_k|, then, for a few rounds, gain_k times the sum S_k of the steps of its
    sign whose ramps overlap its own. Ramps of one sign that overlap add their slopes; every ramp
    covering an instant overlaps every other one covering it, so each one's S is at least the sum
    S_t of the steps covering that instant, and the slopes there add up to at most
    sum |du_j| / (gain S_j) <= 1 / gain: within the jerk the widths were sized for."""
    n = steps.size
    windows = gain * np.abs(steps)
    for _ in range(rounds):
        wider = windows.copy()
        reach = windows.max()  # times are increasing: no ramp farther than this overlaps
        for k in range(n):
            total = 0.0
            for direction in (-1, 1):
                j = k if direction < 0 else k + 1
                while 0 <= j < n and 2.0 * abs(times[j] - times[k]) < reach + windows[k]:
                    same = (steps[j] > 0.0) == (steps[k] > 0.0)
                    if same and 2.0 * abs(times[j] - times[k]) < windows[j] + windows[k]:
                        total += abs(steps[j])
                    j += direction
            wider[k] = max(windows[k], gain[k] * total)
        windows = wider
    return windows


def _steps(x: np.ndarray, u: np.ndarray, ds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A profile's piece durations (n,) [s], the times its path acceleration steps (n + 1,) [s]
    and the steps themselves (n + 1,) [1/s], from x (n + 1,) and u (n,) on pieces of length ds."""
    rates = np.sqrt(x)
    durations = 2.0 * ds / (rates[:-1] + rates[1:])
    times = np.concatenate([[0.0], np.cumsum(durations)])
    return durations, times, np.diff(np.concatenate([[0.0], u, [0.0]]))


def _ramps(edges, peaks, x, u, limits, jerk_share, widen) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The step times, steps and ramp widths of step 3 of the module docstring, (n + 1,) each,
    the ramps widened by ``widen``."""
    durations, times, steps = _steps(x, u, edges[1] - edges[0])
    windows = widen * _windows(peaks, x, u, times, steps, limits, jerk_share)
    # Ramps at least as wide as the pieces beside them: the small steps between pieces then blend
    # into one another (sigma'' close to linear between the pieces' midpoints) instead of short bursts of jerk.
    spacing = np.concatenate([[0.0], np.minimum(durations[:-1], durations[1:]), [0.0]])  # not at the ends
    return times, steps, np.maximum(windows, spacing)


def _smooth_timing(path_duration_s: float, edges, peaks, x, u, limits, jerk_share, widen) -> SmoothTiming:
    """Steps 2 to 3 of the module docstring, the ramps widened by ``widen``."""
    times, steps, windows = _ramps(edges, peaks, x, u, limits, jerk_share, widen)
    keep = np.abs(steps) > 0.0
    timing, _ = smoothed(times[keep], steps[keep], windows[keep], path_duration_s)
    return timing


def profile_timing(x: np.ndarray, windows_s: np.ndarray) -> SmoothTiming:
    """The smooth timing of the normalised path time [0, 1] from a stored profile: ``x`` (n + 1,)
    the squared path speed at the ends of n equal pieces [1/s^2] (0 at both ends), ``windows_s``
    (n + 1,) the ramp widths of its steps [s]; the path acceleration of a piece is
    ``(x_k+1 - x_k) / (2 ds)``. One function, so that a timing stored as (x, windows) and
    certified is the timing rebuilt from them, float for float."""
    x, windows_s = np.asarray(x, dtype=float), np.asarray(windows_s, dtype=float)
    ds = 1.0 / (x.size - 1)
    _, times, steps = _steps(x, np.diff(x) / (2.0 * ds), ds)
    keep = np.abs(steps) > 0.0
    timing, _ = smoothed(times[keep], steps[keep], windows_s[keep], 1.0)
    return timing


def _stored(edges, peaks, x, u, limits, jerk_share, widen) -> tuple[SmoothTiming, np.ndarray, np.ndarray]:
    """The box route's timing: the profile and its ramp widths rounded to float32 (how they are
    stored), and the timing rebuilt from them by :func:`profile_timing`."""
    _, _, windows = _ramps(edges, peaks, x, u, limits, jerk_share, widen)
    x32 = x.astype(np.float32)
    x32[0] = x32[-1] = 0.0
    windows32 = np.maximum(windows, np.finfo(np.float32).tiny).astype(np.float32)
    return profile_timing(x32, windows32), x32, windows32


def _jerk_speed_cap(third: np.ndarray, limits: ArmLimits) -> np.ndarray:
    """The largest x = sdot^2 per piece at which |theta_i'''| sdot^3, the jerk the path's own
    curvature makes at constant path speed, stays within :data:`JERK_SPEED_SHARE` of the jerk
    limit; (n,), from the peaks (n, 2) of |theta'''| on each piece."""
    allowed = JERK_SPEED_SHARE * np.asarray(limits.jerk_rad_s3)
    with np.errstate(divide="ignore"):
        return np.min(np.where(third > 0.0, (allowed / third) ** (2.0 / 3.0), np.inf), axis=1)


def _jerk_aware_profile(rows, cap, peaks, limits: ArmLimits, ds: float) -> tuple[np.ndarray, np.ndarray]:
    """The fastest profile (step 2), rebuilt where the jerk 3 theta'' sdot sddot that the path
    acceleration makes at speed leaves the ramps too little room: there |u| is bounded by
    JERK_SPEED_SHARE J / (3 max|theta''| sdot) at the profile's own sdot, two more rows per piece
    (rebuilt profiles are slower, so the bound stays valid; :data:`_JERK_ROUNDS` rounds)."""
    cu, cx, rhs = rows.cu, rows.cx, rows.rhs
    x, u = fastest_profile(cu, cx, rhs, cap, ds)
    allowed = JERK_SPEED_SHARE * np.asarray(limits.jerk_rad_s3)
    bound = np.full(cap.size, np.inf)
    for _ in range(_JERK_ROUNDS):
        root = np.sqrt(np.maximum(x[:-1], x[1:]))[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.min(np.where(peaks[1] * root > 0.0, allowed / (3.0 * peaks[1] * root), np.inf), axis=1)
        tight = np.abs(u) > room
        if not np.any(tight):
            break
        bound = np.where(tight, np.minimum(bound, room), bound)
        finite = np.where(np.isfinite(bound), bound, _NO_BOUND)[:, None]
        ones, zeros = np.ones_like(finite), np.zeros_like(finite)
        extra_cu, extra_cx = np.hstack([cu, ones, -ones]), np.hstack([cx, zeros, zeros])
        x, u = fastest_profile(extra_cu, extra_cx, np.hstack([rhs, finite, finite]), cap, ds)
    return x, u


def _excess(found: list[LimitViolation], quantities: tuple[str, ...]) -> float:
    return max((v.bound / v.limit for v in found if v.quantity in quantities), default=1.0)


def near_optimal_timing(
    trajectory: JointTrajectory,
    dynamics: PlanarDynamics,
    limits: ArmLimits,
    settings: NearOptimalSettings = NearOptimalSettings(),
) -> NearOptimalTiming:
    """The near time-optimal timing of ``trajectory``'s path within ``limits`` (module docstring).

    Args:
        trajectory: The path (the paper's sinusoids over [0, T]).
        dynamics: The arm's closed-form dynamics.
        limits: The limits to keep; the jerk limits must be finite.
        settings: How the timing is built.

    Returns:
        The timing and its certificate (every bound within ``limits``).

    Raises:
        InvalidParameterError: an infinite jerk limit, or no speed, acceleration or effort limit.
        TimingRefusedError: no certified timing within the attempts (the violations of the last one),
            or the path's angles leave their limits (no timing changes them).
    """
    _check_jerk(limits)
    edges = np.linspace(0.0, trajectory.duration_s, settings.pieces + 1)

    def constraints(share: float, speed_share: float):
        return compiled_piece_constraints(trajectory.parameters, edges, dynamics, limits, share, speed_share)

    def certified(timing: SmoothTiming):
        executed = TimedTrajectory(trajectory, timing)
        return executed, certify_execution(executed, dynamics, limits)

    def timing_of(peaks, x, u, widen):
        return _smooth_timing(trajectory.duration_s, edges, peaks, x, u, limits, settings.jerk_share, widen), None

    return _fastest_certified(constraints, timing_of, certified, edges, limits, settings)


def near_optimal_box_timing(
    box: PathBox,
    dynamics: PlanarDynamics,
    limits: ArmLimits,
    settings: NearOptimalSettings = NearOptimalSettings(),
) -> NearOptimalTiming:
    """One near time-optimal timing of the normalised path time for every path of ``box``
    (:mod:`pipeline.motion.path_box`): the same steps as :func:`near_optimal_timing`, on the
    box's enclosures, certified over the box (the NumPy route of the execution certificate).

    Returns:
        The timing (``executed`` a :class:`pipeline.motion.path_box.TimedPathBox`) and its
        certificate, whose bounds hold for every path of the box.

    Raises:
        As :func:`near_optimal_timing`.
    """
    _check_jerk(limits)
    edges = np.linspace(0.0, 1.0, settings.pieces + 1)
    enclosures = enclose_path((box.lower, box.upper), edges, dynamics, box.mean_value)
    peaks = np.stack([magnitude(d) for d in (enclosures.d1, enclosures.d2, enclosures.d3)])

    def constraints(share: float, speed_share: float):
        return piece_constraints(enclosures, limits, share, speed_share), peaks

    def certified(timing: SmoothTiming):
        executed = box.timed(timing)
        return executed, certify_execution(executed, dynamics, limits, compiled=False)

    def timing_of(peaks, x, u, widen):
        timing, x32, windows32 = _stored(edges, peaks, x, u, limits, settings.jerk_share, widen)
        return timing, (x32, windows32)

    return _fastest_certified(constraints, timing_of, certified, edges, limits, settings)


def _fastest_certified(constraints, timing_of, certified, edges, limits: ArmLimits, settings: NearOptimalSettings):
    """Steps 1 to 4 of the module docstring: ``constraints(share, speed_share)`` gives the rows and
    peaks of the pieces of ``edges``, ``timing_of(peaks, x, u, widen)`` the smooth timing of a
    profile (and what stores it), ``certified(timing)`` the executed motion and its certificate."""
    share, speed_share, widen = settings.limit_share, settings.speed_share, 1.0
    found: list[LimitViolation] = []
    for attempt in range(1, settings.tries + 1):
        rows, peaks = constraints(share, speed_share)
        cap = np.minimum(rows.speed_cap, _jerk_speed_cap(peaks[2], limits))
        x, u = _jerk_aware_profile(rows, cap, peaks, limits, edges[1] - edges[0])
        if not np.all(x[1:-1] > 0.0):
            raise TimingRefusedError(("the limits leave the path no speed: a limit binds at rest",))
        timing, profile = timing_of(peaks, x, u, widen)
        if timing.duration_s > settings.longest_duration_s:
            raise TimingRefusedError(
                (
                    f"the limits need T' = {timing.duration_s:.4g} s, longer than {settings.longest_duration_s:g} s: "
                    "a limit far below what the path needs",
                )
            )
        executed, certificate = certified(timing)
        found = certificate.violations(limits)
        if not found:
            return NearOptimalTiming(executed, certificate, share, attempt, profile)
        if any(v.quantity == "angle" for v in found):
            break
        speed, other = _excess(found, ("speed",)), _excess(found, ("acceleration", "torque"))
        speed_share *= 0.995 / speed if speed > 1.0 else 1.0
        share *= 0.995 / other if other > 1.0 else 1.0
        if max(speed, other) <= 1.0:
            widen *= 1.1 * _excess(found, ("jerk",))
    raise TimingRefusedError(tuple(str(v) for v in found))
