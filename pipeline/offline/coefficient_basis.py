"""SLSQP over a quadratic fit's coefficients in normalised variables.

A fit's coefficients are stored in the raw basis of :func:`pipeline.offline.variables.quadratic_design`
(1, v_i, v_i v_j with v in metres). Over a narrow range far from zero that basis is nearly
collinear: the obstacle's far edge d lies in [0.55, 0.57] m, so the columns 1, d and d^2 differ by
a few percent, and the design over (L, W, x, d) has a condition number near 6e4. SLSQP's
quasi-Newton model inherits that conditioning and creeps: over (L, W, x, d) the endpoint-constrained
fit ran its 1,000 iterations without converging.

The same quadratic written in u = (v - c) / h, with c the centre and h the half-width of the fitted
range per variable, has a design whose condition number is about 5. The change of basis is linear:
``quadratic_design(v) @ A == quadratic_design(u)`` for the (m, m) matrix A of :func:`basis_change`,
since 1 = 1, u_i = (v_i - c_i) / h_i and u_i u_j = (v_i v_j - c_j v_i - c_i v_j + c_i c_j) / (h_i h_j).
A coefficient matrix G in u is B = A G in v. :class:`CoefficientBasis` runs SLSQP on G and returns B:
the objective and every constraint are still written in B, their gradients chained by A (exact, no
finite differences). Nothing downstream changes: the result is a quadratic in the raw variables.
Fits over (L, W) alone stay in the raw basis (:func:`normalised_basis` gives None), where SLSQP
converges and the published coefficients keep their floats.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.offline.variables import Variables

#: Parameters per basis row of a coefficient matrix (the paper family's 8).
_COLUMNS = 8

Objective = Callable[[np.ndarray], tuple[float, np.ndarray]]
Constraint = tuple[Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], np.ndarray]]


def basis_change(centre: np.ndarray, half_width: np.ndarray) -> np.ndarray:
    """A (m, m) with ``quadratic_design(v) @ A == quadratic_design((v - centre) / half_width)``.

    Args:
        centre: c per variable (k,) [m].
        half_width: h per variable (k,) [m], each > 0.

    Raises:
        InvalidParameterError: shapes that differ, or a half-width that is not positive and finite.
    """
    c, h = np.asarray(centre, dtype=float), np.asarray(half_width, dtype=float)
    if c.ndim != 1 or c.shape != h.shape:
        raise InvalidParameterError("half_width", h.shape, f"one value per variable, as centre {c.shape}")
    if not (np.all(np.isfinite(h)) and np.all(h > 0.0) and np.all(np.isfinite(c))):
        raise InvalidParameterError("half_width", h.tolist(), "finite half-widths > 0 [m] and a finite centre")
    k = c.size
    m = 1 + k + k * (k + 1) // 2
    A = np.zeros((m, m))
    A[0, 0] = 1.0
    for i in range(k):  # u_i = (v_i - c_i) / h_i
        A[0, 1 + i] = -c[i] / h[i]
        A[1 + i, 1 + i] = 1.0 / h[i]
    pairs = [(i, j) for i in range(k) for j in range(i, k)]
    for n, (i, j) in enumerate(pairs):  # u_i u_j = (v_i v_j - c_j v_i - c_i v_j + c_i c_j) / (h_i h_j)
        column, scale = 1 + k + n, 1.0 / (h[i] * h[j])
        A[1 + k + n, column] = scale
        A[1 + i, column] -= c[j] * scale
        A[1 + j, column] -= c[i] * scale
        A[0, column] = c[i] * c[j] * scale
    return A


@dataclass(frozen=True, eq=False)
class CoefficientBasis:
    """The normalised basis of a fit over the box spanned by some points (module docstring).

    Attributes:
        matrix: A (m, m): raw coefficients B = A G for coefficients G in the normalised basis.
    """

    matrix: np.ndarray

    @classmethod
    def spanning(cls, points: np.ndarray) -> CoefficientBasis:
        """The basis normalised to the box of ``points`` (n, k) [m] (a grid over the fitted range
        spans it exactly)."""
        P = np.asarray(points, dtype=float)
        lo, hi = P.min(0), P.max(0)
        return cls(basis_change(0.5 * (lo + hi), 0.5 * (hi - lo)))

    def to_raw(self, g: np.ndarray) -> np.ndarray:
        """Raw coefficients b (m 8,), row-major, of normalised ones ``g`` (m 8,)."""
        m = self.matrix.shape[0]
        return (self.matrix @ np.reshape(g, (m, _COLUMNS))).ravel()

    def from_raw(self, b: np.ndarray) -> np.ndarray:
        """Normalised coefficients g of raw ones ``b`` (both (m 8,), row-major)."""
        m = self.matrix.shape[0]
        return np.linalg.solve(self.matrix, np.reshape(b, (m, _COLUMNS))).ravel()

    def _chain(self, gradient: np.ndarray) -> np.ndarray:
        """d/dg of rows of d/db (..., m 8): each row's (m, 8) block times A on the left, transposed."""
        m = self.matrix.shape[0]
        G = np.reshape(gradient, (*np.shape(gradient)[:-1], m, _COLUMNS))
        return np.einsum("...ip,ij->...jp", G, self.matrix).reshape(np.shape(gradient))

    def minimize(self, objective: Objective, start: np.ndarray, constraints: Sequence[Constraint], options: dict):
        """SLSQP on the normalised coefficients; ``objective`` (value and gradient) and each
        ``constraints`` (fun, jac) >= 0 are functions of the raw coefficients. Returns SciPy's
        result (``scipy.optimize.OptimizeResult``) with ``x`` the raw coefficients."""
        from scipy.optimize import minimize  # SciPy only where a fit runs: loading coefficients needs NumPy alone

        def in_g(g: np.ndarray) -> tuple[float, np.ndarray]:
            value, gradient = objective(self.to_raw(g))
            return value, self._chain(gradient)

        wrapped = [
            {
                "type": "ineq",
                "fun": lambda g, f=fun: f(self.to_raw(g)),
                "jac": lambda g, j=jac: self._chain(j(self.to_raw(g))),
            }
            for fun, jac in constraints
        ]
        result = minimize(in_g, self.from_raw(start), jac=True, method="SLSQP", constraints=wrapped, options=options)
        result.x = self.to_raw(result.x)
        return result


def normalised_basis(variables: Variables, points: np.ndarray) -> CoefficientBasis | None:
    """The basis normalised to the box of ``points`` (n, k) over ``variables``; None over (L, W)
    (module docstring)."""
    return None if variables.is_size_only else CoefficientBasis.spanning(points)


def solve_coefficients(
    objective: Objective,
    start: np.ndarray,
    constraints: Sequence[Constraint],
    options: dict,
    basis: CoefficientBasis | None,
):
    """SLSQP from the raw coefficients ``start``: in ``basis`` (:meth:`CoefficientBasis.minimize`),
    or in the raw basis where it is None. Returns SciPy's result, ``x`` raw."""
    if basis is not None:
        return basis.minimize(objective, start, constraints, options)
    from scipy.optimize import minimize  # SciPy only where a fit runs: loading coefficients needs NumPy alone

    wrapped = [{"type": "ineq", "fun": fun, "jac": jac} for fun, jac in constraints]
    return minimize(objective, start, jac=True, method="SLSQP", constraints=wrapped, options=options)
