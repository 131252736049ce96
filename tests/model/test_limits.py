"""Arm limits: the jerk limit is a field like the others (absent: none), and the servo defaults fill
in only what was not given, per joint."""

from __future__ import annotations

import math

import pytest

from pipeline.exceptions import InvalidParameterError
from pipeline.model.limits import DEFAULT_ACCELERATION_RAD_S2, SHORTEST_ACCELERATION_RISE_S, ArmLimits

INF = math.inf


def test_no_jerk_limit_unless_given(arm) -> None:
    assert ArmLimits().jerk_rad_s3 == (INF, INF)
    assert ArmLimits.from_arm(arm, (5.0, 5.0)).jerk_rad_s3 == (INF, INF)
    assert ArmLimits.from_arm(arm, (5.0, 5.0), (80.0, 90.0)).jerk_rad_s3 == (80.0, 90.0)


@pytest.mark.parametrize("value", [(0.0, 1.0), (-1.0, 1.0), (math.nan, 1.0), (1.0,), "fast"])
def test_a_bad_jerk_limit_is_refused(value) -> None:
    with pytest.raises(InvalidParameterError, match="jerk_rad_s3"):
        ArmLimits(jerk_rad_s3=value)


def test_servo_defaults_fill_only_what_is_missing() -> None:
    filled = ArmLimits().with_servo_defaults()
    assert filled.acceleration_rad_s2 == (DEFAULT_ACCELERATION_RAD_S2, DEFAULT_ACCELERATION_RAD_S2) == (10.0, 10.0)
    assert filled.jerk_rad_s3 == (10.0 / SHORTEST_ACCELERATION_RISE_S,) * 2 == (200.0, 200.0)
    partial = ArmLimits(acceleration_rad_s2=(5.0, INF), jerk_rad_s3=(INF, 30.0)).with_servo_defaults()
    assert partial.acceleration_rad_s2 == (5.0, 10.0)
    assert partial.jerk_rad_s3 == (100.0, 30.0)  # joint 1 from its own 5 rad/s^2; joint 2 as given
    given = ArmLimits(acceleration_rad_s2=(2.0, 3.0), jerk_rad_s3=(7.0, 8.0))
    assert given.with_servo_defaults() == given
