"""Vectorised interval arithmetic and interval Taylor jets, the engine of the range certificate.

An :class:`Interval` is a pair of NumPy arrays ``lo <= hi`` (any broadcastable shape); every
operation returns an interval that contains every value the operation can take when its
arguments range over their intervals (the *inclusion property*). A :class:`Jet` carries an
interval for a function's value, for its gradient with respect to ``k`` variables (trailing
axis of length k) and optionally for its Hessian (trailing axes k x k), all enclosing the true
value/derivatives for every point of a box of the variables. Jets compose by the chain rule,
each factor an interval, so the enclosures stay valid through any expression.

Floating point: the operations round to nearest instead of outward. Each result is off by at
most a few units in the last place of numbers of magnitude < 1e3, i.e. < 1e-12 absolute; the
range certificate covers all rounding of its whole chain by one slack
(:data:`FLOAT_SLACK_M`, 1e-9 m) on every final bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.certify.interval_products import product_hi, product_lo
from pipeline.exceptions import InvalidParameterError

#: Slack [m] subtracted from (or added to) every final bound for floating-point rounding of the whole chain.
FLOAT_SLACK_M = 1e-9

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, eq=False)
class Interval:
    """Closed intervals [lo, hi], elementwise.

    Attributes:
        lo, hi: Arrays of one broadcastable shape, lo <= hi (NaN-free).
    """

    lo: np.ndarray
    hi: np.ndarray

    def __post_init__(self) -> None:
        lo, hi = np.broadcast_arrays(np.asarray(self.lo, dtype=float), np.asarray(self.hi, dtype=float))
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)

    @classmethod
    def point(cls, value) -> Interval:
        """The degenerate interval [value, value]."""
        v = np.asarray(value, dtype=float)
        return cls(v, v)

    @classmethod
    def around(cls, center, radius) -> Interval:
        """[center - radius, center + radius] (radius >= 0)."""
        c, r = np.asarray(center, dtype=float), np.asarray(radius, dtype=float)
        return cls(c - r, c + r)

    @property
    def shape(self) -> tuple[int, ...]:
        return self.lo.shape

    @property
    def mid(self) -> np.ndarray:
        """Midpoints."""
        return 0.5 * (self.lo + self.hi)

    @property
    def rad(self) -> np.ndarray:
        """Half widths."""
        return 0.5 * (self.hi - self.lo)

    def mag(self) -> np.ndarray:
        """max |x| over the interval."""
        return np.maximum(np.abs(self.lo), np.abs(self.hi))

    def __getitem__(self, index) -> Interval:
        return Interval(self.lo[index], self.hi[index])

    def __neg__(self) -> Interval:
        return Interval(-self.hi, -self.lo)

    def __add__(self, other) -> Interval:
        if isinstance(other, Interval):
            return Interval(self.lo + other.lo, self.hi + other.hi)
        o = np.asarray(other, dtype=float)
        return Interval(self.lo + o, self.hi + o)

    __radd__ = __add__

    def __sub__(self, other) -> Interval:
        return self + (-other if isinstance(other, Interval) else -np.asarray(other, dtype=float))

    def __rsub__(self, other) -> Interval:
        return (-self) + other

    def __mul__(self, other) -> Interval:
        # 0 * inf is taken as 0 (the convention of interval arithmetic: an infinite bound stands
        # for "unbounded", and 0 times anything finite is 0).
        # The four products' min and max, in one compiled pass each (pipeline.certify.interval_products).
        if isinstance(other, Interval):
            lo, hi = other.lo, other.hi
        else:
            lo = hi = np.asarray(other, dtype=float)
        with np.errstate(invalid="ignore"):  # 0 x inf: taken as 0 by the kernels
            return Interval(product_lo(self.lo, self.hi, lo, hi), product_hi(self.lo, self.hi, lo, hi))

    __rmul__ = __mul__

    def reciprocal(self) -> Interval:
        """1 / x; the whole real line where the interval contains 0."""
        straddles = (self.lo <= 0.0) & (self.hi >= 0.0)
        with np.errstate(divide="ignore"):
            lo = np.where(straddles, -np.inf, 1.0 / self.hi)
            hi = np.where(straddles, np.inf, 1.0 / self.lo)
        return Interval(lo, hi)

    def __truediv__(self, other) -> Interval:
        if isinstance(other, Interval):
            return self * other.reciprocal()
        return self * (1.0 / np.asarray(other, dtype=float))

    def __rtruediv__(self, other) -> Interval:
        return self.reciprocal() * other

    def square(self) -> Interval:
        """x^2 (tighter than x * x)."""
        a, b = self.lo * self.lo, self.hi * self.hi
        straddles = (self.lo <= 0.0) & (self.hi >= 0.0)
        return Interval(np.where(straddles, 0.0, np.minimum(a, b)), np.maximum(a, b))

    def sqrt(self) -> Interval:
        """sqrt(x) of a non-negative interval.

        Raises:
            InvalidParameterError: the interval reaches below 0.
        """
        if np.any(self.lo < 0.0):
            raise InvalidParameterError("sqrt argument", float(np.min(self.lo)), "an interval >= 0")
        return Interval(np.sqrt(self.lo), np.sqrt(self.hi))

    def sin(self) -> Interval:
        """sin(x), exact range (a peak or trough inside the interval is found in closed form)."""
        return _sin_range(self.lo, self.hi)

    def cos(self) -> Interval:
        """cos(x) = sin(x + pi/2)."""
        return _sin_range(self.lo + math.pi / 2, self.hi + math.pi / 2)

    def hull(self, other: Interval) -> Interval:
        """Smallest interval containing both."""
        return Interval(np.minimum(self.lo, other.lo), np.maximum(self.hi, other.hi))

    def sum(self, axis: int) -> Interval:
        """Sum along an axis."""
        return Interval(np.sum(self.lo, axis=axis), np.sum(self.hi, axis=axis))


def _sin_range(lo: np.ndarray, hi: np.ndarray) -> Interval:
    s_lo, s_hi = np.sin(lo), np.sin(hi)
    low, high = np.minimum(s_lo, s_hi), np.maximum(s_lo, s_hi)
    peak = math.pi / 2 + _TWO_PI * np.ceil((lo - math.pi / 2) / _TWO_PI)
    trough = -math.pi / 2 + _TWO_PI * np.ceil((lo + math.pi / 2) / _TWO_PI)
    wide = hi - lo >= _TWO_PI
    high = np.where(wide | (peak <= hi), 1.0, high)
    low = np.where(wide | (trough <= hi), -1.0, low)
    return Interval(low, high)


def _outer(a: Interval, b: Interval) -> Interval:
    return a[..., :, None] * b[..., None, :]


def _expand(x: Interval, extra: int) -> Interval:
    index = (Ellipsis,) + (None,) * extra
    return Interval(x.lo[index], x.hi[index])


@dataclass(frozen=True, eq=False)
class Jet:
    """Interval enclosures of a function's value, gradient and (optionally) Hessian over a box.

    Attributes:
        value: Interval, shape S.
        grad: Interval, shape S + (k,).
        hess: Interval, shape S + (k, k), or None for a first-order jet.
    """

    value: Interval
    grad: Interval
    hess: Interval | None = None

    @classmethod
    def variable(cls, center, radius, index: int, k: int, order: int = 1) -> Jet:
        """The independent variable number ``index`` of ``k``, ranging over center +- radius."""
        value = Interval.around(center, radius)
        unit = np.zeros(value.shape + (k,))
        unit[..., index] = 1.0
        hess = Interval.point(np.zeros(value.shape + (k, k))) if order == 2 else None
        return cls(value, Interval.point(unit), hess)

    @classmethod
    def constant(cls, value, k: int, order: int = 1) -> Jet:
        """A constant (point or interval) as a jet with zero derivatives."""
        v = value if isinstance(value, Interval) else Interval.point(value)
        zeros = np.zeros(v.shape + (k,))
        hess = Interval.point(np.zeros(v.shape + (k, k))) if order == 2 else None
        return cls(v, Interval.point(zeros), hess)

    @property
    def k(self) -> int:
        return self.grad.shape[-1]

    def _unary(self, f: Interval, df: Interval, d2f: Interval | None) -> Jet:
        grad = _expand(df, 1) * self.grad
        hess = None
        if self.hess is not None:
            hess = _expand(df, 2) * self.hess + _expand(d2f, 2) * _outer(self.grad, self.grad)
        return Jet(f, grad, hess)

    def __neg__(self) -> Jet:
        return Jet(-self.value, -self.grad, None if self.hess is None else -self.hess)

    def __add__(self, other) -> Jet:
        if isinstance(other, Jet):
            hess = None if self.hess is None or other.hess is None else self.hess + other.hess
            return Jet(self.value + other.value, self.grad + other.grad, hess)
        return Jet(self.value + other, self.grad, self.hess)

    __radd__ = __add__

    def __sub__(self, other) -> Jet:
        return self + (-other)

    def __rsub__(self, other) -> Jet:
        return (-self) + other

    def __mul__(self, other) -> Jet:
        if isinstance(other, Jet):
            value = self.value * other.value
            grad = _expand(self.value, 1) * other.grad + _expand(other.value, 1) * self.grad
            hess = None
            if self.hess is not None and other.hess is not None:
                hess = (
                    _expand(self.value, 2) * other.hess
                    + _expand(other.value, 2) * self.hess
                    + _outer(self.grad, other.grad)
                    + _outer(other.grad, self.grad)
                )
            return Jet(value, grad, hess)
        if isinstance(other, Interval):
            return Jet(
                self.value * other,
                self.grad * _expand(other, 1),
                None if self.hess is None else self.hess * _expand(other, 2),
            )
        o = np.asarray(other, dtype=float)
        o1, o2 = o[..., None], o[..., None, None]
        return Jet(self.value * o, self.grad * o1, None if self.hess is None else self.hess * o2)

    __rmul__ = __mul__

    def reciprocal(self) -> Jet:
        r = self.value.reciprocal()
        r2 = r.square()
        return self._unary(r, -r2, None if self.hess is None else 2.0 * r2 * r)

    def __truediv__(self, other) -> Jet:
        if isinstance(other, Jet):
            return self * other.reciprocal()
        if isinstance(other, Interval):
            return self * other.reciprocal()
        return self * (1.0 / np.asarray(other, dtype=float))

    def __rtruediv__(self, other) -> Jet:
        return self.reciprocal() * other

    def square(self) -> Jet:
        two_v = 2.0 * self.value
        d2 = Interval.point(np.full(self.value.shape, 2.0)) if self.hess is not None else None
        return self._unary(self.value.square(), two_v, d2)

    def sqrt(self) -> Jet:
        root = self.value.sqrt()
        d1 = 0.5 * root.reciprocal()
        d2 = None if self.hess is None else -0.25 * (root * self.value).reciprocal()
        return self._unary(root, d1, d2)

    def sin(self) -> Jet:
        s = self.value.sin()
        return self._unary(s, self.value.cos(), None if self.hess is None else -s)

    def cos(self) -> Jet:
        c = self.value.cos()
        return self._unary(c, -self.value.sin(), None if self.hess is None else -c)


def lower_bound(point: Jet, box: Jet, radius: np.ndarray) -> np.ndarray:
    """Lower bound of a smooth function over a box: the mean-value form, and where ``box`` carries
    a Hessian the tighter of it and the second-order Taylor form.

    Mean-value form: f(x) >= f(c) - sum_i max_box |df/dx_i| r_i, with ``point`` the jet at the
    centre c (its value and gradient intervals enclose f(c) and grad f(c)) and ``box`` the jet over
    the box of half widths ``radius`` (..., k). Second-order form (Taylor with the Lagrange
    remainder, f twice continuously differentiable on the box): f(x) = f(c) + grad f(c).(x - c) +
    1/2 (x - c)^T H(xi) (x - c) with xi in the box, so f(x) >= f(c) - sum_i |df/dx_i(c)| r_i -
    1/2 sum_ij max_box |H_ij| r_i r_j. Both hold everywhere on the box, so their maximum does.
    """
    low = point.value.lo - np.sum(box.grad.mag() * radius, axis=-1)
    if box.hess is None:
        return low
    return np.maximum(low, point.value.lo - _second_order_spread(point, box, radius))


def upper_bound(point: Jet, box: Jet, radius: np.ndarray) -> np.ndarray:
    """Upper bound, the mirror of :func:`lower_bound`."""
    high = point.value.hi + np.sum(box.grad.mag() * radius, axis=-1)
    if box.hess is None:
        return high
    return np.minimum(high, point.value.hi + _second_order_spread(point, box, radius))


def _second_order_spread(point: Jet, box: Jet, radius: np.ndarray) -> np.ndarray:
    """sum_i |df/dx_i(c)| r_i + 1/2 sum_ij max_box |H_ij| r_i r_j (:func:`lower_bound`)."""
    linear = np.sum(point.grad.mag() * radius, axis=-1)
    return linear + 0.5 * np.einsum("ni,nij,nj->n", radius, box.hess.mag(), radius)
