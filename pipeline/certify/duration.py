"""Rigorous enclosures of the path duration T(L, W) and its gradient over (L, W) boxes.

Derivation
==========

The path is the quartic through P1..P5 (``pipeline.path``). P1..P5 are symmetric about the
y axis, so the quartic is even: y(x) = c0 + c2 x^2 + c4 x^4 with c0 = d - W - a3 (P3).
Write X1 = L/2 + dx1 (x of P1), X2 = L/2 + dx2 (x of P2), and substitute x = X1 xi:
y(X1 xi) - c0 = alpha xi^2 + beta xi^4 with

    alpha + beta = H := y1 - c0 = y1 - d + W + a3,     alpha u + beta u^2 = K := a3 - a2,
    u = (X2 / X1)^2   =>   beta = (K - H u) / (u^2 - u),   alpha = H - beta.

(a2, a3: the scene's approach_dy and apex_dy; dx1, dx2: start_dx and approach_dx.) The arc
length is S = 2 int_0^X1 sqrt(1 + y'(x)^2) dx = 2 int_0^1 F(xi) dxi with
F = sqrt(X1^2 + g(xi)^2), g = 2 alpha xi + 4 beta xi^3, and T = S / v. F is smooth in
(xi, L, W); alpha, beta and X1 are rational in (L, W), so T and its derivatives are integrals
of closed-form integrands, evaluated here with interval jets (``pipeline.certify.interval``).
With y1 = d (``Scene.start_y_m`` None) H = W + a3: T depends on neither the obstacle's far edge d
nor its centre x, so one table serves coefficients over (L, W, x, d) too (``range_model``).

1. **T and grad T at a point c** by composite Gauss-Legendre (P panels of n nodes on [0, 1])
   applied to F and to its (L, W) derivatives (forward-mode jets at the point). The
   quadrature error of an n-node rule on a panel of width h is
   h^(2n+1) (n!)^4 / ((2n+1) ((2n)!)^3) f^(2n)(eta). The integrands are analytic: for complex
   xi with |xi - x| <= rho, x real in [0, 1], |Im g(xi)| <= G1 rho with
   G1 = sup |g'| = 2|alpha| + 12|beta| (1 + rho)^2, so choosing G1 rho <= X1 / 2 keeps
   Re(X1^2 + g^2) >= 3 X1^2 / 4 > 0: F is analytic there, |F| >= (sqrt 3 / 2) X1 and
   |F| <= sqrt(X1^2 + gmax^2), gmax = 2|alpha| (1 + rho) + 4|beta| (1 + rho)^3. Cauchy's
   estimate |f^(2n)| <= (2n)! M / rho^(2n) (M = sup |f| on the disc) bounds the total error by
   C_n (h / rho)^(2n) M with C_n = (n!)^4 / ((2n+1) ((2n)!)^2); the derivative integrands
   dF/dL = (X1 X1_L + g (2 xi alpha_L + 4 xi^3 beta_L)) / F (and the same for W) get their M
   from the same bounds. With n = 10, P = 24 the bound is below 1e-13 s over the paper's range; it is added anyway.
2. **The Hessian of T over a box** X by interval jets of order 2 evaluated on xi panels x X and
   summed (a Riemann enclosure: int_panel f in width * [f over panel]). Interval jets of the
   rational alpha, beta overestimate fast with the box size, so the fitted range is cut once
   into a table of small sub-boxes (:class:`DurationModel`) and a box takes the largest |H| of
   the sub-boxes it meets.
3. **Taylor form over the box**: for x in X, with r the box's half widths,
   grad T(x) in grad T(c) + H(X) [-r, r] and
   T(x) in T(c) + grad T(c) . [-r, r] + 1/2 sum_ij |H_ij(X)| r_i r_j (Lagrange remainder).
   Both enclosures have widths O(|r|) resp. O(|r|) around exact first-order terms, so the
   certificate that uses them tightens quadratically.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pipeline.certify.interval import Interval, Jet
from pipeline.exceptions import InvalidParameterError
from pipeline.model.scene import Scene
from pipeline.validation import check_positive_int

_NODES = 10
_PANELS = 24
_HESSIAN_PANELS = 128
_C_N = math.factorial(_NODES) ** 4 / ((2 * _NODES + 1) * math.factorial(2 * _NODES) ** 2)
_GL_X, _GL_W = np.polynomial.legendre.leggauss(_NODES)
_XI = ((np.arange(_PANELS)[:, None] + (_GL_X[None, :] + 1.0) / 2.0) / _PANELS).ravel()
_WEIGHTS = np.tile(_GL_W / (2.0 * _PANELS), _PANELS)
_RHO_MAX = 0.25


def _shape(L: Jet, W: Jet, scene: Scene) -> tuple[Jet, Jet, Jet]:
    """(X1, alpha, beta) of the module docstring as jets in (L, W)."""
    x1 = L * 0.5 + scene.start_dx_m
    x2 = L * 0.5 + scene.approach_dx_m
    u = (x2 / x1).square()
    h = W + (scene.y1_m - scene.top_y_m + scene.apex_dy_m)
    k = scene.apex_dy_m - scene.approach_dy_m
    beta = (k - h * u) / (u * u - u)
    alpha = h - beta
    return x1, alpha, beta


def _integrand(xi, x1: Jet, alpha: Jet, beta: Jet) -> Jet:
    """F = sqrt(X1^2 + g^2), g = 2 alpha xi + 4 beta xi^3; xi an array or an Interval."""
    if isinstance(xi, Interval):
        xi3 = xi * xi.square()
    else:
        xi3 = xi**3
    g = alpha * (2.0 * xi) + beta * (4.0 * xi3)
    return (x1.square() + g.square()).sqrt()


def _shape_point(length_m: np.ndarray, width_m: np.ndarray, scene: Scene) -> tuple[np.ndarray, ...]:
    """X1, alpha, beta and their (L, W) derivatives at points, in plain floating point."""
    x1 = length_m / 2 + scene.start_dx_m
    x2 = length_m / 2 + scene.approach_dx_m
    ratio = x2 / x1
    u = ratio * ratio
    u_l = 2.0 * ratio * (x1 - x2) / (2.0 * x1 * x1)
    h = width_m + (scene.y1_m - scene.top_y_m + scene.apex_dy_m)
    k = scene.apex_dy_m - scene.approach_dy_m
    den = u * u - u
    beta = (k - h * u) / den
    beta_l = (-h * u_l * den - (k - h * u) * (2.0 * u - 1.0) * u_l) / (den * den)
    beta_w = -u / den
    return x1, h - beta, beta, -beta_l, 1.0 - beta_w, beta_l, beta_w


def duration_at(length_m: np.ndarray, width_m: np.ndarray, scene: Scene) -> tuple[Interval, Interval]:
    """Enclosures of T [s] and of (dT/dL, dT/dW) [s/m] at points (L, W) [m] (shapes (N,), (N, 2)).

    Gauss-Legendre with the error bound of the module docstring (step 1), in floating point.
    """
    Lc = np.atleast_1d(np.asarray(length_m, dtype=float))
    Wc = np.atleast_1d(np.asarray(width_m, dtype=float))
    x1, alpha, beta, alpha_l, alpha_w, beta_l, beta_w = (v[:, None] for v in _shape_point(Lc, Wc, scene))
    xi, xi3 = _XI, _XI**3
    g = 2.0 * alpha * xi + 4.0 * beta * xi3
    f = np.sqrt(x1 * x1 + g * g)
    f_l = (0.5 * x1 + g * (2.0 * xi * alpha_l + 4.0 * xi3 * beta_l)) / f
    f_w = g * (2.0 * xi * alpha_w + 4.0 * xi3 * beta_w) / f
    v = scene.speed_m_s
    # Row sums, not a matrix product: BLAS may round a row differently with its position in the
    # batch, and T at a node must not depend on which other nodes share its batch.
    s = 2.0 * np.sum(f * _WEIGHTS, axis=1)
    grad = 2.0 * np.stack([np.sum(f_l * _WEIGHTS, axis=1), np.sum(f_w * _WEIGHTS, axis=1)], -1)
    err_value, err_grad = _quadrature_error(x1[:, 0], alpha[:, 0], beta[:, 0], alpha_l, alpha_w, beta_l, beta_w)
    value = Interval.around(s / v, 2.0 * err_value / v)
    return value, Interval.around(grad / v, 2.0 * err_grad / v)


def _quadrature_error(x1, alpha, beta, alpha_l, alpha_w, beta_l, beta_w) -> tuple[np.ndarray, np.ndarray]:
    """Bounds on the Gauss-Legendre error of int_0^1 F and of int_0^1 dF/d(L, W) (module docstring, step 1)."""
    a, b = np.abs(alpha), np.abs(beta)
    a_g = np.abs(np.concatenate([alpha_l, alpha_w], axis=1))
    b_g = np.abs(np.concatenate([beta_l, beta_w], axis=1))
    x_g = np.array([0.5, 0.0])
    radius = 1.0 + _RHO_MAX
    g1 = 2.0 * a + 12.0 * b * radius**2
    rho = np.minimum(_RHO_MAX, x1 / (2.0 * g1))
    gmax = 2.0 * a * radius + 4.0 * b * radius**3
    f_min = math.sqrt(3.0) / 2.0 * x1
    m_value = np.sqrt(x1 * x1 + gmax * gmax)
    m_grad = (x1[:, None] * x_g + gmax[:, None] * (2.0 * radius * a_g + 4.0 * radius**3 * b_g)) / f_min[:, None]
    factor = _C_N * (1.0 / (_PANELS * rho)) ** (2 * _NODES)
    return factor * m_value, factor[:, None] * m_grad


def duration_hessian(length: Interval, width: Interval, scene: Scene) -> Interval:
    """Enclosure (N, 2, 2) [s/m^2] of the Hessian of T over boxes L x W (intervals of shape (N,))."""
    k = 2
    L = Jet.variable(length.mid[:, None], length.rad[:, None], 0, k, order=2)
    W = Jet.variable(width.mid[:, None], width.rad[:, None], 1, k, order=2)
    x1, alpha, beta = _shape(L, W, scene)
    edges = np.linspace(0.0, 1.0, _HESSIAN_PANELS + 1)
    xi = Interval(edges[:-1], edges[1:])
    f = _integrand(xi, x1, alpha, beta)
    hess = f.hess.sum(axis=1)
    return hess * (2.0 / (_HESSIAN_PANELS * scene.speed_m_s))


@dataclass(frozen=True, eq=False)
class DurationModel:
    """T(L, W) over a fitted range, with a table of Hessian enclosures for the Taylor form.

    The range (enlarged by 1 % on each side against rounding) is cut into ``grid`` x ``grid``
    sub-boxes; the Hessian of T is enclosed once per sub-box (module docstring, step 2) and
    max-pooled into a pyramid, so a box of any size finds an enclosure of |H| over itself by
    looking up at most 2 x 2 entries of the level where it spans at most two sub-boxes per axis.

    Attributes:
        scene: The scene.
        length_range_m: (lo, hi) of L [m].
        width_range_m: (lo, hi) of W [m].
        grid: Sub-boxes per axis (a power of two).
    """

    scene: Scene
    length_range_m: tuple[float, float]
    width_range_m: tuple[float, float]
    grid: int = 64
    _origin: np.ndarray = field(init=False, repr=False)
    _size: np.ndarray = field(init=False, repr=False)
    _pyramid: list = field(init=False, repr=False)

    def __post_init__(self) -> None:
        check_positive_int("grid", self.grid, minimum=1)
        if self.grid & (self.grid - 1):
            raise InvalidParameterError("grid", self.grid, "a power of two")
        lo = np.array([self.length_range_m[0], self.width_range_m[0]], dtype=float)
        hi = np.array([self.length_range_m[1], self.width_range_m[1]], dtype=float)
        if not np.all(np.isfinite(lo)) or not np.all(hi >= lo) or not np.all(lo > 0):
            raise InvalidParameterError("range", (self.length_range_m, self.width_range_m), "0 < lo <= hi")
        pad = 0.01 * np.maximum(hi - lo, 1e-6)
        origin, size = lo - pad, (hi - lo) + 2 * pad
        object.__setattr__(self, "_origin", origin)
        object.__setattr__(self, "_size", size)
        n = self.grid
        step = size / n
        i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
        centers_l = origin[0] + (i.ravel() + 0.5) * step[0]
        centers_w = origin[1] + (j.ravel() + 0.5) * step[1]
        hess = duration_hessian(
            Interval.around(centers_l, step[0] / 2), Interval.around(centers_w, step[1] / 2), self.scene
        )
        table = hess.mag().reshape(n, n, 2, 2)
        pyramid = [table]
        while pyramid[-1].shape[0] > 1:
            t = pyramid[-1]
            m = t.shape[0] // 2
            pyramid.append(t.reshape(m, 2, m, 2, 2, 2).max(axis=(1, 3)))
        object.__setattr__(self, "_pyramid", pyramid[::-1])  # level 0 = whole range

    def hessian_magnitude(self, center_m: np.ndarray, radius_m: np.ndarray) -> np.ndarray:
        """Upper bounds (N, 2, 2) [s/m^2] on |d^2 T / d(L, W)^2| over boxes (centres, half widths (N, 2)).

        Raises:
            InvalidParameterError: a box leaves the (padded) range.
        """
        c = np.asarray(center_m, dtype=float)[:, :2]
        r = np.asarray(radius_m, dtype=float)[:, :2]
        lo = (c - r - self._origin) / self._size
        hi = (c + r - self._origin) / self._size
        if np.any(lo < 0) or np.any(hi > 1):
            raise InvalidParameterError("box", "outside the fitted range", "boxes inside the range T was tabulated on")
        width = np.max(hi - lo, axis=1)
        levels = len(self._pyramid) - 1
        # Finest level whose cells are at least as wide as the box: then it spans <= 2 cells per axis.
        with np.errstate(divide="ignore"):
            level = np.clip(np.floor(-np.log2(np.maximum(width, 1e-300))), 0, levels).astype(int)
        out = np.zeros((c.shape[0], 2, 2))
        for lev in np.unique(level):
            rows = np.flatnonzero(level == lev)
            table = self._pyramid[lev]
            n = table.shape[0]
            i0 = np.clip(np.floor(lo[rows] * n).astype(int), 0, n - 1)
            i1 = np.clip(np.floor(hi[rows] * n).astype(int), 0, n - 1)
            best = np.maximum.reduce(
                [
                    table[i0[:, 0], i0[:, 1]],
                    table[i0[:, 0], i1[:, 1]],
                    table[i1[:, 0], i0[:, 1]],
                    table[i1[:, 0], i1[:, 1]],
                ]
            )
            out[rows] = best
        return out

    def jet(self, center_m: np.ndarray, radius_m: np.ndarray, k: int = 3, order: int = 1) -> Jet:
        """Jet of T over boxes of (L, W[, s]) (module docstring, step 3).

        Args:
            center_m: Box centres (N, >= 2), columns L, W [m] (further columns ignored).
            radius_m: Half widths (N, >= 2) [m]; zeros give the enclosure at the centre.
            k: Number of jet variables (L, W first; T does not depend on the others).
            order: 2 adds the Hessian: [-|H|, |H|] of :meth:`hessian_magnitude` in the (L, W)
                block, zero elsewhere.

        Returns:
            Jet with value (N,) [s] and gradient (N, k) [s/m] enclosing T and grad T over each box
            (and with ``order`` 2 its Hessian (N, k, k) [s/m^2]).
        """
        center = np.asarray(center_m, dtype=float)
        # Boxes of one (L, W) node differ only in s: the quadrature runs once per distinct node.
        nodes, inverse = np.unique(center[:, :2], axis=0, return_inverse=True)
        value_n, grad_n = duration_at(nodes[:, 0], nodes[:, 1], self.scene)
        inverse = inverse.reshape(-1)
        value_c, grad_c = value_n[inverse], grad_n[inverse]
        r = np.asarray(radius_m, dtype=float)[:, :2]
        hmag = self.hessian_magnitude(center, r)
        grad_spread = np.einsum("nij,nj->ni", hmag, r)
        value_spread = np.sum(grad_c.mag() * r, axis=1) + 0.5 * np.einsum("ni,nij,nj->n", r, hmag, r)
        value = Interval(value_c.lo - value_spread, value_c.hi + value_spread)
        lo, hi = np.zeros((r.shape[0], k)), np.zeros((r.shape[0], k))
        lo[:, :2], hi[:, :2] = grad_c.lo - grad_spread, grad_c.hi + grad_spread
        if order == 1:
            return Jet(value, Interval(lo, hi))
        hess = np.zeros((r.shape[0], k, k))
        hess[:, :2, :2] = hmag
        return Jet(value, Interval(lo, hi), Interval(-hess, hess))
