"""Short decimals as (int32 mantissa, int8 exponent) (:mod:`pipeline.io.decimal_columns`): every
decimal of up to 9 significant digits comes back bit for bit, as Python's own parsing of its
text gives it; any other double is refused (None), never changed; infinities and NaN survive."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.io.decimal_columns import FloatColumns, decimal_parts, from_decimal_parts

DECIMALS = st.builds(
    lambda m, e: float(f"{m}e{e}"),
    st.integers(-9_999_999, 9_999_999),
    st.integers(-20, 15),
)


def _bits(values: np.ndarray) -> list:
    return ["nan" if math.isnan(v) else np.float64(v).view(np.int64).item() for v in values]


@settings(max_examples=300, deadline=None)
@given(st.lists(DECIMALS, min_size=1, max_size=40))
def test_decimals_come_back_bit_for_bit(values: list[float]) -> None:
    array = np.array(values)
    parts = decimal_parts(array)
    assert parts is not None and parts[0].dtype == np.int32 and parts[1].dtype == np.int8
    assert _bits(from_decimal_parts(*parts)) == _bits(array)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=1, max_size=40))
def test_any_double_is_kept_or_refused_never_changed(values: list[float]) -> None:
    array = np.array(values)
    parts = decimal_parts(array)
    if parts is not None:
        assert _bits(from_decimal_parts(*parts)) == _bits(array)


def test_non_finite_values_and_zero_survive_and_other_doubles_are_refused() -> None:
    array = np.array([math.inf, -math.inf, math.nan, 0.0, 1.234567, -2.5e-7])
    parts = decimal_parts(array)
    assert parts is not None and _bits(from_decimal_parts(*parts)) == _bits(array)
    assert decimal_parts(np.array([0.1 + 0.2])) is None  # 0.30000000000000004: 17 digits
    assert decimal_parts(np.array([math.pi])) is None
    assert decimal_parts(np.array([1e-300])) is None  # beyond the exact powers of ten
    assert decimal_parts(np.array([-0.0])) is None  # its sign would be lost


def test_float_columns_read_each_column_when_asked_and_once() -> None:
    """FloatColumns gives the stored columns' values (short decimals decoded, float64 as they
    are), decodes nothing before a column is asked for, keeps it read-only, and refuses columns
    of different lengths."""
    decimals = np.array([1.25, -3.5e-4, math.inf, 0.0])
    plain = np.array([math.pi, -math.e, 1e300, math.nan])
    parts = decimal_parts(decimals)
    assert parts is not None
    columns = FloatColumns({"short": parts, "full": plain})
    assert columns.size == 4 and set(columns) == {"short", "full"} and len(columns) == 2
    assert "short" in columns and "other" not in columns and columns._read == {}  # nothing read yet
    np.testing.assert_array_equal(columns["short"], decimals)
    assert list(columns._read) == ["short"]
    assert columns["short"] is columns["short"] and not columns["short"].flags.writeable
    np.testing.assert_array_equal(columns["full"], plain)
    with pytest.raises(ValueError, match="one length"):
        FloatColumns({"short": parts, "full": plain[:3]})
