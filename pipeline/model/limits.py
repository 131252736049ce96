"""The arm's limits: joint positions, speeds and efforts from the URDF, accelerations given.

URDF carries no acceleration limit; it comes from the caller (a command-line option, or the
build's configuration, which stores it in the coefficients). An absent limit is infinite.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pipeline.exceptions import InvalidParameterError

__all__ = ["ACCELERATION_LIMITS_KEY", "ArmLimits"]

_INF = math.inf
#: Key of the acceleration limits [rad/s^2] in a coefficients file's provenance (absent: none given).
ACCELERATION_LIMITS_KEY = "acceleration_limits_rad_s2"


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
    """

    position_rad: tuple[tuple[float, float], tuple[float, float]] = ((-_INF, _INF), (-_INF, _INF))
    velocity_rad_s: tuple[float, float] = (_INF, _INF)
    acceleration_rad_s2: tuple[float, float] = (_INF, _INF)
    effort_n_m: tuple[float, float] = (_INF, _INF)

    def __post_init__(self) -> None:
        for name in ("velocity_rad_s", "acceleration_rad_s2", "effort_n_m"):
            object.__setattr__(self, name, _pair(name, getattr(self, name)))
        try:
            (lo1, hi1), (lo2, hi2) = ((float(a), float(b)) for a, b in self.position_rad)
        except (TypeError, ValueError):
            raise InvalidParameterError("position_rad", self.position_rad, "((lo1, hi1), (lo2, hi2)) [rad]") from None
        for lo, hi in ((lo1, hi1), (lo2, hi2)):
            if math.isnan(lo) or math.isnan(hi) or not lo < hi:
                raise InvalidParameterError("position_rad", self.position_rad, "lo < hi for each joint [rad]")
        object.__setattr__(self, "position_rad", ((lo1, hi1), (lo2, hi2)))

    @classmethod
    def recorded(cls, arm, provenance: dict) -> ArmLimits:
        """The URDF's limits of ``arm`` and the acceleration limits a build recorded in
        ``provenance`` (a coefficients file's; none if it records none)."""
        recorded = provenance.get(ACCELERATION_LIMITS_KEY)
        return cls.from_arm(arm, None if recorded is None else tuple(recorded))

    @classmethod
    def from_arm(cls, arm, acceleration_rad_s2: tuple[float, float] | None = None) -> ArmLimits:
        """The URDF's position, velocity and effort limits of ``arm`` (a :class:`pipeline.model.arm.PlanarArm`),
        and the given acceleration limits [rad/s^2] (None: none)."""
        effort = tuple(float(v) for v in arm.model.effortLimit[:2])
        return cls(
            position_rad=arm.position_limits_rad,
            velocity_rad_s=arm.velocity_limits_rad_s,
            acceleration_rad_s2=(_INF, _INF) if acceleration_rad_s2 is None else acceleration_rad_s2,
            effort_n_m=effort,
        )
