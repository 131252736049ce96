"""Columns of short decimals stored as an int32 mantissa and an int8 exponent, bit for bit.

A float64 that is the nearest double to a decimal of at most 9 significant digits, m 10^e with
|m| < 2^31 and |e| <= 22 (the region map's execution bounds, rounded outward to 7 digits, are),
is stored in 5 bytes instead of 8 and read back exactly: m and 10^|e| are both exact doubles, so
m * 10^e (e >= 0) and m / 10^-e (e < 0) are each one correctly rounded operation, the nearest
double to the decimal, which is the value written. Infinities and NaN take reserved exponents.

:func:`decimal_parts` returns the parts only when the round trip gives every value back bit for
bit (checked, not assumed), and None otherwise: a column of other doubles stays float64.
:class:`FloatColumns` reads such columns of a table when they are first asked for, not before.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import numpy as np

__all__ = ["FloatColumns", "decimal_parts", "from_decimal_parts"]

#: Largest |e|: 10^22 is the largest power of ten that is an exact double.
_EXACT_POWERS = 22
#: 10^0 .. 10^22, each an exact double.
_POWERS = 10.0 ** np.arange(_EXACT_POWERS + 1)
#: Reserved exponents of the non-finite values.
_PLUS_INF, _MINUS_INF, _NAN = 127, 126, -128
#: Significant digits a value is read at.
_DIGITS = 9


def from_decimal_parts(mantissa: np.ndarray, exponent: np.ndarray) -> np.ndarray:
    """The float64 values of ``mantissa`` (int) and ``exponent`` (int8) arrays, with the reserved
    exponents read as +inf, -inf and NaN."""
    m = np.asarray(mantissa, dtype=np.float64)
    e = np.asarray(exponent, dtype=np.int8)
    powers = _POWERS[np.minimum(np.abs(e.astype(np.int16)), _EXACT_POWERS)]
    values = np.where(e >= 0, m * powers, m / powers)
    special = e.astype(np.int16) >= _MINUS_INF
    special |= e == _NAN
    if special.any():
        values[e == _PLUS_INF] = np.inf
        values[e == _MINUS_INF] = -np.inf
        values[e == _NAN] = np.nan
    return values


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """True if the two float64 arrays hold the same values bit for bit (any NaN equal to any NaN)."""
    nan_a, nan_b = np.isnan(a), np.isnan(b)
    return bool(np.array_equal(nan_a, nan_b) and np.array_equal(a[~nan_a].view(np.int64), b[~nan_b].view(np.int64)))


def decimal_parts(values: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The (int32 mantissa, int8 exponent) of float64 ``values`` that :func:`from_decimal_parts`
    turns back into them bit for bit, or None where some value is no such short decimal.

    Each value's decimal is read at :data:`_DIGITS` significant digits (a short decimal's double
    is within 1e-16 of it relatively, far from a rounding boundary at 9 digits), its trailing
    zeros dropped so that its exponent is as large as it can be; the round trip is then checked."""
    values = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(values)
    magnitude = np.abs(np.where(finite & (values != 0.0), values, 1.0))
    exponent = np.floor(np.log10(magnitude)).astype(np.int64) - (_DIGITS - 1)
    with np.errstate(over="ignore", invalid="ignore"):  # beyond the doubles' range: refused below
        powers = 10.0 ** np.abs(exponent).astype(np.float64)
        mantissa = np.rint(np.where(finite, np.where(exponent >= 0, values / powers, values * powers), 0.0))
    if np.any(np.abs(mantissa) >= 2**31):
        return None
    mantissa = mantissa.astype(np.int64)
    for _ in range(_DIGITS):  # drop trailing zeros
        zero = (mantissa % 10 == 0) & (mantissa != 0)
        mantissa = np.where(zero, mantissa // 10, mantissa)
        exponent = np.where(zero, exponent + 1, exponent)
    exponent = np.where(mantissa == 0, 0, exponent)
    if np.any(np.abs(exponent[finite]) > _EXACT_POWERS):
        return None
    special = np.where(np.isnan(values), _NAN, np.where(values > 0, _PLUS_INF, _MINUS_INF))
    parts = mantissa.astype(np.int32), np.where(finite, exponent, special).astype(np.int8)
    return parts if _same_bits(from_decimal_parts(*parts), values) else None


class FloatColumns(Mapping):
    """Float64 columns of one length read from their stored form when first asked for: name ->
    a float64 array, or a (mantissa, exponent) pair (:func:`from_decimal_parts`); each column is
    read once and kept, read-only. So a map whose execution bounds are not asked for never
    decodes them."""

    def __init__(self, stored: Mapping[str, np.ndarray | tuple[np.ndarray, np.ndarray]]) -> None:
        self._stored = dict(stored)
        self._read: dict[str, np.ndarray] = {}
        lengths = {np.shape(v[0] if isinstance(v, tuple) else v) for v in self._stored.values()}
        if len(lengths) > 1 or any(len(shape) != 1 for shape in lengths):
            raise ValueError(f"columns of one length expected, got shapes {sorted(lengths)}")
        self.size = next(iter(lengths))[0] if lengths else 0

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self._read:
            stored = self._stored[name]
            values = from_decimal_parts(*stored) if isinstance(stored, tuple) else np.asarray(stored, dtype=float)
            values.setflags(write=False)
            self._read[name] = values
        return self._read[name]

    def __contains__(self, name: object) -> bool:
        return name in self._stored

    def __iter__(self) -> Iterator[str]:
        return iter(self._stored)

    def __len__(self) -> int:
        return len(self._stored)
