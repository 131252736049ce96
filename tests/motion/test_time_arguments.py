"""The time argument of every trajectory's q, dq, ddq (and jerk, states): real numbers and arrays of
them are evaluated; strings, bytes, None, complex numbers, booleans and object or text arrays are
refused with an InvalidParameterError naming the value and what a time must be
(pipeline.motion.trajectory.time_array, used by JointTrajectory and TimedTrajectory)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pipeline.exceptions import InvalidParameterError
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import PAPER_TIMING, RestToRestTiming
from pipeline.motion.trajectory import TIMES_EXPECTED, JointTrajectory, time_array

# A trajectory of the paper's family (any valid one would do).
PARAMETERS = (1.1, 0.45, -0.2, 0.3, 0.9, 0.7, 0.1, 1.2)
DURATION_S = 3.748


def trajectories() -> dict[str, object]:
    """One trajectory of each kind, each over its own [0, T] (T' for the timed ones)."""
    path = JointTrajectory(PARAMETERS, DURATION_S)
    return {
        "path": path,
        "paper-timing": TimedTrajectory(path, PAPER_TIMING),
        "rest-to-rest": TimedTrajectory(path, RestToRestTiming(DURATION_S, 0.5, 0.4)),
    }


def methods(trajectory: object) -> list:
    """The public evaluations that take times."""
    names = ["q", "dq", "ddq"] + (["jerk", "states"] if isinstance(trajectory, TimedTrajectory) else [])
    return [getattr(trajectory, name) for name in names]


SCALARS_REFUSED = ["1.2", b"1.2", None, 1.2 + 0j, np.complex128(0.5), True, np.bool_(False), {"t": 1.0}]
ARRAYS_REFUSED = [
    (np.array(["0.5"]), "<U3"),
    (np.array([0.1, None]), "object"),
    (np.array(0.5, dtype=object), "object"),
    (np.array([True, False]), "bool"),
    (np.array([0.5 + 0j]), "complex128"),
    (["0.5", "1.0"], "<U3"),
]


@pytest.mark.parametrize("kind", ["path", "paper-timing", "rest-to-rest"])
@pytest.mark.parametrize("value", SCALARS_REFUSED, ids=repr)
def test_a_scalar_that_is_not_a_real_number_is_refused_by_name(kind: str, value: object) -> None:
    trajectory = trajectories()[kind]
    for method in methods(trajectory):
        with pytest.raises(InvalidParameterError) as info:
            method(value)
        error = info.value
        assert error.name == "t_s" and error.value is value and error.expected == TIMES_EXPECTED, method
        assert str(error) == f"t_s = {value!r} is invalid: expected a time [s] or an array of times"


@pytest.mark.parametrize("kind", ["path", "paper-timing", "rest-to-rest"])
@pytest.mark.parametrize(("value", "dtype"), ARRAYS_REFUSED, ids=lambda v: str(v).replace("\n", " "))
def test_an_array_of_no_real_dtype_is_refused_by_its_dtype(kind: str, value: object, dtype: str) -> None:
    trajectory = trajectories()[kind]
    for method in methods(trajectory):
        with pytest.raises(InvalidParameterError) as info:
            method(value)
        assert info.value.name == "t_s.dtype" and info.value.value == dtype, method
        assert "expected a time [s] or an array of times" in str(info.value) and "\n" not in str(info.value)


def test_a_ragged_list_and_an_integer_beyond_floats_are_refused_in_one_line() -> None:
    path = trajectories()["path"]
    with pytest.raises(InvalidParameterError, match="of one shape"):
        path.q([[0.1], [0.2, 0.3]])
    with pytest.raises(InvalidParameterError) as info:
        path.q(10**400)
    assert info.value.value == "1.0000e+400" and len(str(info.value)) < 120


@pytest.mark.parametrize("kind", ["path", "paper-timing", "rest-to-rest"])
def test_real_numbers_and_arrays_of_them_are_evaluated_alike(kind: str) -> None:
    """A Python float is the reference; every other real form of the same times gives the same
    values (bit for bit: they are converted to the same float64)."""
    trajectory = trajectories()[kind]
    for method in methods(trajectory)[:3]:
        reference = method(1.0)
        for same in (np.float64(1.0), np.float32(1.0), 1, np.int64(1), np.array(1.0), np.uint8(1)):
            assert_allclose(method(same), reference, rtol=0, atol=0)
        many = method(np.array([0.0, 1.0, 2.0]))
        assert many.shape == (3, 2)
        for same in ([0.0, 1.0, 2.0], (0, 1, 2), range(3), np.arange(3, dtype=np.int32)):
            assert_allclose(method(same), many, rtol=0, atol=0)
        assert_allclose(many[1], reference, rtol=0, atol=0)


def test_time_array_keeps_a_float_array_and_makes_a_0d_array_of_a_scalar() -> None:
    times = np.linspace(0.0, 1.0, 5)
    assert time_array(times) is times  # no copy on the hot path
    scalar = time_array(0.25)
    assert scalar.ndim == 0 and scalar.dtype == np.float64 and float(scalar) == 0.25
    assert time_array(np.arange(3)).dtype == np.float64


def test_times_are_still_checked_against_the_duration() -> None:
    """The type check comes first; a real time outside [0, T] is refused as before, NaN too."""
    path = trajectories()["path"]
    with pytest.raises(InvalidParameterError, match=r"times in \[0, T = 3.748 s\]"):
        path.q(4.0)
    with pytest.raises(InvalidParameterError, match="not NaN"):
        path.q(float("nan"), outside="clamp")
    assert_allclose(path.q(4.0, outside="clamp"), path.q(DURATION_S), rtol=0, atol=0)
