"""The arm's limits: joint positions, speeds and efforts from the URDF, accelerations and jerks given.

URDF carries no acceleration or jerk limit; they come from the caller (a command-line option, or
the build's configuration, which stores the acceleration limit in the coefficients). An absent
limit is infinite.

**Servo defaults.** A motion sent to a real controller needs both. Where none is given,
:meth:`ArmLimits.with_servo_defaults` uses :data:`DEFAULT_ACCELERATION_RAD_S2` = 10 rad/s^2 per
joint (below 10 % of what the shipped arm's 10 N m effort limit allows at rest, so the torque
limit does not bind first) and a jerk limit of the acceleration limit divided by
:data:`SHORTEST_ACCELERATION_RISE_S` = 50 ms: the acceleration takes at least 50 ms to rise from
zero to its limit (and 100 ms to swing from one limit to the other), a change that a position-
or velocity-controlled servo tracks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from pipeline.exceptions import InvalidParameterError

__all__ = [
    "ACCELERATION_LIMITS_KEY",
    "DEFAULT_ACCELERATION_RAD_S2",
    "SHORTEST_ACCELERATION_RISE_S",
    "ArmLimits",
]

_INF = math.inf
#: Key of the acceleration limits [rad/s^2] in a coefficients file's provenance (absent: none given).
ACCELERATION_LIMITS_KEY = "acceleration_limits_rad_s2"
#: Acceleration limit [rad/s^2] per joint where none is given (module docstring).
DEFAULT_ACCELERATION_RAD_S2 = 10.0
#: Shortest time [s] for the acceleration to rise from zero to its limit: the default jerk limit
#: is the acceleration limit divided by it (module docstring).
SHORTEST_ACCELERATION_RISE_S = 0.05


def _pair(name: str, value: object) -> tuple[float, float]:
    try:
        first, second = (float(v) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise InvalidParameterError(name, value, "two numbers, one per joint") from None
    for v in (first, second):
        if math.isnan(v) or v <= 0.0:
            raise InvalidParameterError(name, value, "two positive limits (inf: none)")
    return first, second


@dataclass(frozen=True)
class ArmLimits:
    """Limits per joint (index 0: joint 1, 1: joint 2).

    Attributes:
        position_rad: ((lo1, hi1), (lo2, hi2)) [rad] (infinite: none).
        velocity_rad_s: |dq_i| limits [rad/s].
        acceleration_rad_s2: |ddq_i| limits [rad/s^2] (default none).
        effort_n_m: |tau_i| limits [N m].
        jerk_rad_s3: |d3q_i/dt3| limits [rad/s^3] (default none).
    """

    position_rad: tuple[tuple[float, float], tuple[float, float]] = ((-_INF, _INF), (-_INF, _INF))
    velocity_rad_s: tuple[float, float] = (_INF, _INF)
    acceleration_rad_s2: tuple[float, float] = (_INF, _INF)
    effort_n_m: tuple[float, float] = (_INF, _INF)
    jerk_rad_s3: tuple[float, float] = (_INF, _INF)

    def __post_init__(self) -> None:
        for name in ("velocity_rad_s", "acceleration_rad_s2", "effort_n_m", "jerk_rad_s3"):
            object.__setattr__(self, name, _pair(name, getattr(self, name)))
        try:
            (lo1, hi1), (lo2, hi2) = ((float(a), float(b)) for a, b in self.position_rad)
        except (TypeError, ValueError):
            raise InvalidParameterError("position_rad", self.position_rad, "((lo1, hi1), (lo2, hi2)) [rad]") from None
        for lo, hi in ((lo1, hi1), (lo2, hi2)):
            if math.isnan(lo) or math.isnan(hi) or not lo < hi:
                raise InvalidParameterError("position_rad", self.position_rad, "lo < hi for each joint [rad]")
        object.__setattr__(self, "position_rad", ((lo1, hi1), (lo2, hi2)))

    def with_servo_defaults(self) -> ArmLimits:
        """These limits with the servo defaults (module docstring) where no acceleration or jerk
        limit is given: 10 rad/s^2, and the acceleration limit / 50 ms [rad/s^3]."""
        acceleration = tuple(DEFAULT_ACCELERATION_RAD_S2 if math.isinf(a) else a for a in self.acceleration_rad_s2)
        jerk = tuple(
            a / SHORTEST_ACCELERATION_RISE_S if math.isinf(j) else j
            for a, j in zip(acceleration, self.jerk_rad_s3, strict=True)
        )
        return replace(self, acceleration_rad_s2=acceleration, jerk_rad_s3=jerk)

    @classmethod
    def recorded(cls, arm, provenance: dict) -> ArmLimits:
        """The URDF's limits of ``arm`` and the acceleration limits a build recorded in
        ``provenance`` (a coefficients file's; none if it records none)."""
        recorded = provenance.get(ACCELERATION_LIMITS_KEY)
        return cls.from_arm(arm, None if recorded is None else tuple(recorded))

    @classmethod
    def from_arm(
        cls,
        arm,
        acceleration_rad_s2: tuple[float, float] | None = None,
        jerk_rad_s3: tuple[float, float] | None = None,
    ) -> ArmLimits:
        """The URDF's position, velocity and effort limits of ``arm`` (a :class:`pipeline.model.arm.PlanarArm`),
        and the given acceleration [rad/s^2] and jerk [rad/s^3] limits (None: none)."""
        effort = tuple(float(v) for v in arm.model.effortLimit[:2])
        return cls(
            position_rad=arm.position_limits_rad,
            velocity_rad_s=arm.velocity_limits_rad_s,
            acceleration_rad_s2=(_INF, _INF) if acceleration_rad_s2 is None else acceleration_rad_s2,
            effort_n_m=effort,
            jerk_rad_s3=(_INF, _INF) if jerk_rad_s3 is None else jerk_rad_s3,
        )
