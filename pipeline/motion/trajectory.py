"""The paper's joint trajectory family (Eq. 1): theta_i(t) = A_i sin(w_i t + phi_i) + gamma_i.

Parameters are handled as arrays of shape (..., 8) in the order of :data:`PARAMETER_NAMES`
so that whole swarms evaluate in one NumPy expression. Units: A, phi, gamma in rad,
w in rad/s, t in s.
"""

from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from pipeline.exceptions import InvalidParameterError, format_number
from pipeline.motion.interval_arithmetic import sin_extremes
from pipeline.validation import check_finite, check_positive

PARAMETER_NAMES: tuple[str, ...] = ("A1", "w1", "phi1", "gamma1", "A2", "w2", "phi2", "gamma2")
PARAMETER_UNITS: Mapping[str, str] = MappingProxyType(
    {name: ("rad/s" if name.startswith("w") else "rad") for name in PARAMETER_NAMES}
)
#: What :meth:`JointTrajectory.q` (and dq, ddq) do with times outside [0, T]: refuse them, or clamp them.
OUTSIDE_POLICIES: tuple[str, ...] = ("error", "clamp")
#: What a time argument must be, as the refusal says.
TIMES_EXPECTED = "a time [s] or an array of times"


def _split(params: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(A, w, phi, gamma), each of shape (..., 2), from parameters of shape (..., 8)."""
    p = np.asarray(params, dtype=float).reshape(*np.shape(params)[:-1], 2, 4)
    return p[..., 0], p[..., 1], p[..., 2], p[..., 3]


def joint_angles(params: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """theta(t) [rad] for parameters (..., 8) and times (m,): shape (..., m, 2)."""
    a, w, phi, gamma = _split(params)
    t = np.asarray(t_s, dtype=float)[:, None]
    return a[..., None, :] * np.sin(w[..., None, :] * t + phi[..., None, :]) + gamma[..., None, :]


def joint_velocities(params: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """dtheta/dt [rad/s], shape (..., m, 2)."""
    a, w, phi, _ = _split(params)
    t = np.asarray(t_s, dtype=float)[:, None]
    return (a * w)[..., None, :] * np.cos(w[..., None, :] * t + phi[..., None, :])


def joint_accelerations(params: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """d2theta/dt2 [rad/s^2], shape (..., m, 2)."""
    a, w, phi, _ = _split(params)
    t = np.asarray(t_s, dtype=float)[:, None]
    return -(a * w * w)[..., None, :] * np.sin(w[..., None, :] * t + phi[..., None, :])


def joint_jerks(params: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """d3theta/dt3 [rad/s^3], shape (..., m, 2)."""
    a, w, phi, _ = _split(params)
    t = np.asarray(t_s, dtype=float)[:, None]
    return -(a * w**3)[..., None, :] * np.cos(w[..., None, :] * t + phi[..., None, :])


def canonicalize(params: np.ndarray) -> np.ndarray:
    """Map parameters to the canonical form of Eq. 8, so equal motions get equal parameters.

    A sin(wt + phi) = (-A) sin(-wt - phi) = (-A) sin(wt + phi + pi). The canonical form
    has w >= 0 and phi in [-pi/2, pi/2), A taking whatever sign that leaves. Table 2 of
    the paper is already in this form.
    """
    p = np.array(params, dtype=float, copy=True)
    q = p.reshape(*p.shape[:-1], 2, 4)
    flip = q[..., 1] < 0
    q[..., 0] = np.where(flip, -q[..., 0], q[..., 0])
    q[..., 1] = np.abs(q[..., 1])
    q[..., 2] = np.where(flip, -q[..., 2], q[..., 2])
    half_turns = np.floor((q[..., 2] + np.pi / 2) / np.pi)
    q[..., 2] = q[..., 2] - half_turns * np.pi
    odd = np.mod(half_turns, 2) == 1
    q[..., 0] = np.where(odd, -q[..., 0], q[..., 0])
    # Rounding can leave phi a hair below -pi/2 or at +pi/2: fold once more.
    low, high = q[..., 2] < -np.pi / 2, q[..., 2] >= np.pi / 2
    q[..., 2] = np.where(low, q[..., 2] + np.pi, np.where(high, q[..., 2] - np.pi, q[..., 2]))
    q[..., 0] = np.where(low | high, -q[..., 0], q[..., 0])
    return q.reshape(p.shape)


def _peak_abs(amplitude: float, w: float, phase: float, duration_s: float, offset: float) -> float:
    """max over t in [0, T] of |amplitude * sin(w t + phase + offset)| (closed form)."""
    lo, hi = sorted((phase + offset, w * duration_s + phase + offset))
    # A peak of |sin| sits at pi/2 + k pi; is one inside [lo, hi]?
    k = math.ceil((lo - math.pi / 2) / math.pi)
    if math.pi / 2 + k * math.pi <= hi:
        return abs(amplitude)
    return abs(amplitude) * max(abs(math.sin(lo)), abs(math.sin(hi)))


@dataclass(frozen=True)
class PathPeaks:
    """The closed-form extremes of one trajectory over [0, T] (plain floats), per joint (index 0:
    joint 1): what every closed-form bound of the path's timings is made of.

    Attributes:
        velocity_rad_s: max |dtheta_i/dt| [rad/s].
        acceleration_rad_s2: max |d2theta_i/dt2| [rad/s^2].
        third_rad_s3: |A_i| w_i^3 [rad/s^3], the peak of |d3theta_i/dt3| over all t (a bound over [0, T]).
        angle_ranges_rad: (min, max) of each joint angle [rad].
    """

    velocity_rad_s: tuple[float, float]
    acceleration_rad_s2: tuple[float, float]
    third_rad_s3: tuple[float, float]
    angle_ranges_rad: tuple[tuple[float, float], tuple[float, float]]


def path_peaks(parameters: tuple[float, ...], duration_s: float) -> PathPeaks:
    """:class:`PathPeaks` of the sinusoids ``parameters`` over [0, ``duration_s``], in closed form."""
    p, T = parameters, duration_s
    velocity = tuple(_peak_abs(p[4 * i] * p[4 * i + 1], p[4 * i + 1], p[4 * i + 2], T, math.pi / 2) for i in (0, 1))
    acceleration = tuple(_peak_abs(p[4 * i] * p[4 * i + 1] ** 2, p[4 * i + 1], p[4 * i + 2], T, 0.0) for i in (0, 1))
    third = tuple(abs(p[4 * i]) * abs(p[4 * i + 1]) ** 3 for i in (0, 1))
    ranges = []
    for i in (0, 1):
        amplitude, w, phi, gamma = p[4 * i : 4 * i + 4]
        s_min, s_max = sin_extremes(*sorted((phi, w * T + phi)))
        values = (gamma + amplitude * s_min, gamma + amplitude * s_max)
        ranges.append((min(values), max(values)))
    return PathPeaks(velocity, acceleration, third, (ranges[0], ranges[1]))  # type: ignore[arg-type]


def time_array(t_s: float | np.ndarray) -> np.ndarray:
    """Times [s] as a float array (0-d for a scalar), refusing what is not a real number or an
    array of them: strings and bytes (which NumPy would parse), None, complex numbers, booleans,
    object arrays. Unchecked against any duration (:func:`checked_times` does that).

    Raises:
        InvalidParameterError: naming the value (or, for an array, its dtype) and what was expected.
    """
    # The hot path: a Python or NumPy real scalar (an array skips the slower abstract-class check).
    if isinstance(t_s, float) or (not isinstance(t_s, np.ndarray | bool) and isinstance(t_s, numbers.Real)):
        try:
            return np.asarray(t_s, dtype=float)
        except OverflowError:  # an integer beyond the float range
            raise InvalidParameterError("t_s", format_number(t_s), TIMES_EXPECTED + " within the float range") from None
    try:
        array = np.asarray(t_s)
    except (TypeError, ValueError):  # e.g. a ragged list
        raise InvalidParameterError("t_s", type(t_s).__name__, TIMES_EXPECTED + " of one shape") from None
    if array.dtype.kind in "fiu":
        return array.astype(float, copy=False)
    if array.ndim == 0 and not isinstance(t_s, np.ndarray):
        raise InvalidParameterError("t_s", t_s, TIMES_EXPECTED)
    raise InvalidParameterError("t_s.dtype", str(array.dtype), TIMES_EXPECTED + " (of a real dtype)")


def checked_times(t_s: float | np.ndarray, duration_s: float, outside: str, name: str) -> np.ndarray:
    """Times [s] as a float array, checked to lie in [0, duration] (``outside="error"``) or
    clamped into it (``outside="clamp"``); ``name`` names the duration in messages ("T", "T'").

    Raises:
        InvalidParameterError: not a real number or an array of them (:func:`time_array`), a time
            outside [0, duration] (with "error"), NaN (with either policy), or an unknown policy.
    """
    t = time_array(t_s)
    if outside == "error":
        if t.size and not (t.min() >= 0.0 and t.max() <= duration_s):  # False for NaN too
            bad = t[~((t >= 0.0) & (t <= duration_s))].ravel()
            raise InvalidParameterError(
                "t_s",
                float(bad[0]),
                f"times in [0, {name} = {duration_s!r} s] (outside='clamp' clamps them into it)",
            )
        return t
    if outside == "clamp":
        if np.isnan(t).any():
            raise InvalidParameterError("t_s", float("nan"), "times [s], not NaN")
        return np.clip(t, 0.0, duration_s)
    raise InvalidParameterError("outside", outside, f"one of {OUTSIDE_POLICIES}")


@dataclass(frozen=True)
class JointTrajectory:
    """One joint-space trajectory of the paper's family over [0, T].

    Attributes:
        parameters: The 8 parameters in :data:`PARAMETER_NAMES` order.
        duration_s: T [s].
    """

    parameters: tuple[float, ...]
    duration_s: float

    def __post_init__(self) -> None:
        values = tuple(float(v) for v in np.asarray(self.parameters, dtype=float).ravel())
        if len(values) != 8:
            raise InvalidParameterError("parameters", self.parameters, "8 values " + str(PARAMETER_NAMES))
        for name, value in zip(PARAMETER_NAMES, values, strict=True):
            check_finite(name, value)
        object.__setattr__(self, "parameters", values)
        check_positive("duration_s", self.duration_s)

    @classmethod
    def trusted(cls, parameters: tuple[float, ...], duration_s: float) -> JointTrajectory:
        """Build without re-validating: for callers that have checked already (8 finite Python
        floats and a finite T > 0), e.g. the online generator, which validates once at its entry."""
        trajectory = object.__new__(cls)
        fields = trajectory.__dict__
        fields["parameters"] = parameters
        fields["duration_s"] = duration_s
        return trajectory

    @classmethod
    def from_mapping(cls, parameters: Mapping[str, float], duration_s: float) -> JointTrajectory:
        """Build from a {name: value} mapping with the keys of :data:`PARAMETER_NAMES`."""
        missing = [n for n in PARAMETER_NAMES if n not in parameters]
        if missing:
            raise InvalidParameterError("parameters", dict(parameters), f"keys {PARAMETER_NAMES}, missing {missing}")
        return cls(tuple(float(parameters[n]) for n in PARAMETER_NAMES), duration_s)

    def as_dict(self) -> dict[str, float]:
        """{name: value} of the 8 parameters."""
        return dict(zip(PARAMETER_NAMES, self.parameters, strict=True))

    @property
    def array(self) -> np.ndarray:
        """The parameters as a (8,) array."""
        return np.array(self.parameters)

    def times(self, t_s: float | np.ndarray, outside: str = "error") -> np.ndarray:
        """Times [s] as a float array, checked to lie in [0, T] (``outside="error"``, the default)
        or clamped into it (``outside="clamp"``): :func:`checked_times`."""
        return checked_times(t_s, self.duration_s, outside, "T")

    def q(self, t_s: float | np.ndarray, *, outside: str = "error") -> np.ndarray:
        """Joint angles [rad]: shape (2,) for a scalar t, (m, 2) for m times.

        Args:
            t_s: Time(s) [s] in [0, T].
            outside: "error" (default) refuses times outside [0, T] with InvalidParameterError;
                "clamp" evaluates them at the nearest end. NaN is refused either way.
        """
        t = self.times(t_s, outside)
        out = joint_angles(self.parameters, np.atleast_1d(t))
        return out[0] if t.ndim == 0 else out

    def dq(self, t_s: float | np.ndarray, *, outside: str = "error") -> np.ndarray:
        """Joint velocities [rad/s], shaped like :meth:`q` (same ``outside`` policy)."""
        t = self.times(t_s, outside)
        out = joint_velocities(self.parameters, np.atleast_1d(t))
        return out[0] if t.ndim == 0 else out

    def ddq(self, t_s: float | np.ndarray, *, outside: str = "error") -> np.ndarray:
        """Joint accelerations [rad/s^2], shaped like :meth:`q` (same ``outside`` policy)."""
        t = self.times(t_s, outside)
        out = joint_accelerations(self.parameters, np.atleast_1d(t))
        return out[0] if t.ndim == 0 else out

    def __call__(self, t_s: float | np.ndarray, *, outside: str = "error") -> np.ndarray:
        return self.q(t_s, outside=outside)

    @functools.cached_property
    def peaks(self) -> PathPeaks:
        """The closed-form extremes over [0, T] (:func:`path_peaks`), computed once per trajectory
        (the instance is frozen: the fields they are made of never change)."""
        return path_peaks(self.parameters, self.duration_s)

    def angle_ranges_rad(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """(min, max) over [0, T] of each joint angle [rad], in closed form."""
        return self.peaks.angle_ranges_rad

    def peak_velocity_rad_s(self) -> np.ndarray:
        """max over [0, T] of |dtheta_i/dt| [rad/s] per joint, in closed form."""
        return np.array(self.peaks.velocity_rad_s)

    def peak_acceleration_rad_s2(self) -> np.ndarray:
        """max over [0, T] of |d2theta_i/dt2| [rad/s^2] per joint, in closed form."""
        return np.array(self.peaks.acceleration_rad_s2)
