"""The interval product's bounds, compiled: the hot operation of the range certificate's interval
arithmetic (:mod:`pipeline.certify.interval`).

[a_lo, a_hi] x [b_lo, b_hi] = [min P, max P] over the four products P = {a_lo b_lo, a_lo b_hi,
a_hi b_lo, a_hi b_hi}, a product 0 x inf taken as 0 (interval arithmetic's convention: an
infinite bound stands for "unbounded", and 0 times anything finite is 0). Written with NumPy
that is four products, four NaN tests and selections and two reductions over a stacked copy,
some fourteen passes over the arrays and their temporaries; here it is one pass per bound,
as NumPy ufuncs (broadcasting, any shape).

Each bound is taken with the same operations in the same order as the NumPy form
(``np.minimum`` / ``np.maximum`` of the four products in the order above, a tie going to the
later one, as NumPy's does), so the doubles are the same, signed zeros and infinities
included; the suite checks it bit for bit.
"""

from __future__ import annotations

import numba

__all__ = ["product_hi", "product_lo"]


@numba.njit(cache=True, nogil=True, inline="always")
def _times(a: float, b: float) -> float:
    """a b, with 0 x inf (NaN) taken as 0 (the inputs are NaN-free)."""
    p = a * b
    return 0.0 if p != p else p


@numba.vectorize(cache=True, nopython=True)
def product_lo(a_lo, a_hi, b_lo, b_hi):
    """Lower bound of [a_lo, a_hi] x [b_lo, b_hi]."""
    m = _times(a_lo, b_lo)
    p = _times(a_lo, b_hi)
    m = m if m < p else p
    p = _times(a_hi, b_lo)
    m = m if m < p else p
    p = _times(a_hi, b_hi)
    return m if m < p else p


@numba.vectorize(cache=True, nopython=True)
def product_hi(a_lo, a_hi, b_lo, b_hi):
    """Upper bound of [a_lo, a_hi] x [b_lo, b_hi]."""
    m = _times(a_lo, b_lo)
    p = _times(a_lo, b_hi)
    m = m if m > p else p
    p = _times(a_hi, b_lo)
    m = m if m > p else p
    p = _times(a_hi, b_hi)
    return m if m > p else p
