"""Checks of scalar inputs shared by the configuration dataclasses."""

from __future__ import annotations

import math

from pipeline.exceptions import InvalidParameterError


def check_positive(name: str, value: float) -> float:
    """Return ``value`` as float if it is finite and > 0, else raise InvalidParameterError."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidParameterError(name, value, "a positive finite number") from None
    if not math.isfinite(number) or number <= 0.0:
        raise InvalidParameterError(name, value, "a positive finite number")
    return number


def check_non_negative(name: str, value: float) -> float:
    """Return ``value`` as float if it is finite and >= 0, else raise InvalidParameterError."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidParameterError(name, value, "a non-negative finite number") from None
    if not math.isfinite(number) or number < 0.0:
        raise InvalidParameterError(name, value, "a non-negative finite number")
    return number


def check_finite(name: str, value: float) -> float:
    """Return ``value`` as float if it is finite, else raise InvalidParameterError."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidParameterError(name, value, "a finite number") from None
    if not math.isfinite(number):
        raise InvalidParameterError(name, value, "a finite number")
    return number


def check_positive_int(name: str, value: int, minimum: int = 1) -> int:
    """Return ``value`` if it is an integer >= ``minimum``, else raise InvalidParameterError."""
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise InvalidParameterError(name, value, f"an integer >= {minimum}")
    return value


def check_bool(name: str, value: bool) -> bool:
    """Return ``value`` if it is True or False, else raise InvalidParameterError."""
    if not isinstance(value, bool):
        raise InvalidParameterError(name, value, "True or False")
    return value
