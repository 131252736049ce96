"""What the range certificate knows about one coefficients file: the family's parameter map
v -> the 8 sinusoid parameters over the coefficients' axes v (their scene variables: (L, W), or
(L, W) with the obstacle's centre x and / or its far edge y d, ``pipeline.offline.variables``),
the duration T, the arm and the scene, and the interval jets of the joint angles over boxes of
(v, s), s = t / T in [0, 1].

theta_i(v, s) = A_i(v) sin(w_i(v) s T(L, W) + phi_i(v)) + gamma_i(v).

* ``paper`` family: all 8 parameters are the regression's quadratics in v, for (L, W)
  p(L, W) = b0 + b1 L + b2 W + b3 L^2 + b4 L W + b5 W^2 (the basis of
  :class:`pipeline.offline.variables.Variables`).
* Offsets: an interval evaluation of a quadratic in its raw basis loses the cancellation
  between terms that share a variable (b_L [L] + b_Ld [L] [d] encloses (b_L + b_Ld d) L with
  the width of |b_L| + |b_Ld d| instead of |b_L + b_Ld d|); where a variable's range lies far
  from 0 relative to its width, as d in [0.55, 0.57], that widens every enclosure downstream.
  So the quadratics are evaluated in the offsets u_i = v_i - o_i of the extra axes from the
  scene's own values o (the obstacle's displacement: o_x = ``centre_x_m``, 0 in every
  coefficients file, so x is evaluated as it is; o_d = ``top_y_m``), L and W as they are. The
  coefficients are re-expanded once: p = c0 + sum_i c_i u_i + sum_{i <= j} b_ij u_i u_j with
  c0 = b0 + sum_i b_i o_i + sum_{i <= j} b_ij o_i o_j and c_i = b_i + sum_j b_ij o_j (2 b_ii o_i
  for j = i), the quadratic terms unchanged. The re-expansion rounds: each c is a sum of m
  products of up to three factors, off by at most (m + 1) eps (1 + O(eps)) sum |terms|
  (eps = 2^-53; 2 (m + 3) eps sum |terms| is taken); so the free parameters' jets are widened by
  that bound of c0 plus sum_i (that of c_i) max |u_i| in value and by that of c_i in the
  derivative along u_i (= along v_i): they enclose the quadratics as written in the file (the
  offsets u = v - o themselves are formed like every other operation, see
  ``pipeline.certify.interval``). Axes with o = 0 (L, W, x) are evaluated exactly as without
  offsets, to the bit.
* T depends on neither x nor d: P1..P5 keep their offsets from the obstacle, so moving the
  obstacle by (x, d - d_scene) translates the five points and their quartic by that vector, which
  keeps its arc length. For d this needs y1 = d (``Scene.start_y_m`` None, the paper's scene):
  with a fixed y1, P1 and P5 stay put while P2..P4 move, the path changes shape and T depends on
  d, so an axis d is refused in that scene. The jets of T carry a zero derivative along x and d.
* ``exact-endpoints`` family: (w1, phi1, A2, w2) are quadratics; A1, gamma1, phi2, gamma2
  follow from the inverse kinematics of P1, P5 and from T (``pipeline.motion.families.exact_endpoints``):
  A1 = (th1_e - th1_s) / (sin(w1 T + phi1) - sin(phi1)), gamma1 = th1_s - A1 sin(phi1),
  phi2 = (pi - w2 T) / 2, gamma2 = th2_s - A2 sin(phi2), with th2 = elbow * acos(c),
  c = (|P|^2 - l1^2 - l2^2) / (2 l1 l2), th1 = atan2(P) - atan2(l2 sin th2, l1 + l2 cos th2).
  The jets follow the same formulas; a box whose A1 denominator interval reaches below the
  family's clamp (1e-3 in absolute value) is not certified (its jets are unbounded). This
  family has jets over (L, W) only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from pipeline.certify.duration import DurationModel
from pipeline.certify.interval import Interval, Jet
from pipeline.exceptions import InvalidParameterError
from pipeline.model.scene import Scene
from pipeline.motion.families import TrajectoryFamily
from pipeline.motion.families.exact_endpoints import MIN_DENOMINATOR, ExactEndpointsFamily
from pipeline.motion.families.paper import PaperFamily
from pipeline.offline.coefficients import Coefficients
from pipeline.offline.variables import DEFAULT_VARIABLES, Variables

#: Unit roundoff of double precision.
_EPS = 2.0**-53
#: Axes the range certificate covers (the scene variables whose effect on the path, the obstacle
#: and T the jets follow); d only where y1 = d (module docstring, :func:`axes_refusal`).
CERTIFIABLE_AXES = ("L", "W", "x", "d")


def axes_refusal(axes: Variables, scene: Scene) -> str | None:
    """What the range certificate takes instead of ``axes`` in ``scene`` (the ``expected`` of the
    InvalidParameterError :class:`RangeModel` raises), or None where it covers them: axes among
    :data:`CERTIFIABLE_AXES`, and d only where y1 = d (``scene.start_y_m`` None; with a fixed y1
    the path is no translate of the paper's and T depends on d, module docstring)."""
    if any(name not in CERTIFIABLE_AXES for name in axes.names):
        return f"axes among {', '.join(CERTIFIABLE_AXES)}"
    if "d" in axes.names and scene.start_y_m is not None:
        return (
            f"d only where y1 = d (start_y_m None, here {scene.start_y_m!r} m: P1 and P5 stay put while "
            "the obstacle moves with d)"
        )
    return None


@dataclass(frozen=True, eq=False)
class RangeModel:
    """The closed-form map (L, W, s) -> joint angles of one coefficients file.

    Attributes:
        family: The trajectory family (``pipeline.motion.families``); its parameter map is
            followed by the jets of :data:`JET_EXPANSIONS`.
        coefficients: Free parameter -> (b0..b5), in the family's order, shape (k, 6).
        scene: The scene.
        link_lengths_m: (l1, l2) [m].
        link_radii_m: (r1, r2) capsule radii [m].
        elbow: Elbow branch (+1 / -1).
        length_range_m, width_range_m: The fitted range [m].
        source_sha256: sha256 of the coefficients file.
        axes: The scene variables of the coefficients: the box's axes, in order; the jets'
            variables are these, then s.
        extra_ranges_m: The fitted range of each axis beyond L and W [m], in ``axes`` order.
        duration: Enclosures of T over the range.
        origin_m: The reference o of each axis (module docstring, "Offsets") [m]: 0 for L and W,
            the scene's value of each extra axis.
    """

    family: TrajectoryFamily
    coefficients: np.ndarray
    scene: Scene
    link_lengths_m: tuple[float, float]
    link_radii_m: tuple[float, float]
    elbow: int
    length_range_m: tuple[float, float]
    width_range_m: tuple[float, float]
    source_sha256: str = ""
    axes: Variables = DEFAULT_VARIABLES
    extra_ranges_m: tuple[tuple[float, float], ...] = ()
    duration: DurationModel = field(init=False, repr=False)
    origin_m: tuple[float, ...] = field(init=False, repr=False)
    _offset_rows: np.ndarray = field(init=False, repr=False)
    _offset_error: tuple[np.ndarray, np.ndarray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if type(self.family) not in JET_EXPANSIONS:
            raise InvalidParameterError("family", self.family, f"a family with jets, one of {list(JET_EXPANSIONS)}")
        axes = Variables.of(self.axes)
        object.__setattr__(self, "axes", axes)
        refusal = axes_refusal(axes, self.scene)
        if refusal is not None:
            raise InvalidParameterError("axes", axes.names, refusal)
        if axes.extra and type(self.family) is not PaperFamily:
            raise InvalidParameterError(
                "family", self.family.name, f"the paper family for axes {', '.join(axes.names)}"
            )
        extra = tuple(tuple(float(v) for v in pair) for pair in self.extra_ranges_m)
        if len(extra) != len(axes.extra) or any(not (lo < hi) for lo, hi in extra):
            raise InvalidParameterError("extra_ranges_m", self.extra_ranges_m, f"(lo < hi) per axis of {axes.extra}")
        object.__setattr__(self, "extra_ranges_m", extra)
        coefficients = np.array(self.coefficients, dtype=float)
        if coefficients.shape != (self.family.free_count, axes.basis_size) or not np.all(np.isfinite(coefficients)):
            raise InvalidParameterError(
                "coefficients", coefficients.shape, f"finite, one row of {axes.basis_size} per free parameter"
            )
        coefficients.setflags(write=False)
        object.__setattr__(self, "coefficients", coefficients)
        origin = (0.0, 0.0, *axes.values_of(self.scene).values())
        object.__setattr__(self, "origin_m", origin)
        rows, error = _offset_coefficients(coefficients, axes.pairs, origin)
        object.__setattr__(self, "_offset_rows", rows)
        object.__setattr__(self, "_offset_error", error)
        if self.elbow not in (1, -1):
            raise InvalidParameterError("elbow", self.elbow, "+1 or -1")
        if min(self.link_lengths_m) <= 0 or min(self.link_radii_m) < 0:
            raise InvalidParameterError("link_lengths_m", self.link_lengths_m, "positive lengths, radii >= 0")
        object.__setattr__(
            self, "duration", DurationModel(self.scene, tuple(self.length_range_m), tuple(self.width_range_m))
        )

    @classmethod
    def from_coefficients(cls, coefficients: Coefficients) -> RangeModel:
        """The model of a loaded coefficients file."""
        names = coefficients.family.free_parameter_names
        axes = coefficients.variables
        return cls(
            family=coefficients.family,
            coefficients=np.array([coefficients.parameters[n] for n in names]),
            scene=coefficients.scene,
            link_lengths_m=tuple(coefficients.link_lengths_m),
            link_radii_m=tuple(coefficients.link_radii_m),
            elbow=coefficients.elbow,
            length_range_m=tuple(coefficients.fitted_range_m["L"]),
            width_range_m=tuple(coefficients.fitted_range_m["W"]),
            source_sha256=coefficients.source_sha256,
            axes=axes,
            extra_ranges_m=tuple(tuple(coefficients.fitted_range_m[name]) for name in axes.extra),
        )

    @property
    def k(self) -> int:
        """Number of axes (2 for (L, W)); the jets have k + 1 variables (the axes, then s)."""
        return self.axes.k

    @property
    def ranges_m(self) -> tuple[tuple[float, float], ...]:
        """The fitted range (lo, hi) of every axis, in ``axes`` order [m]."""
        return (tuple(self.length_range_m), tuple(self.width_range_m), *self.extra_ranges_m)

    @property
    def range_lo(self) -> np.ndarray:
        """Lower corner of the fitted box, one entry per axis [m]."""
        return np.array([self.length_range_m[0], self.width_range_m[0], *(lo for lo, _ in self.extra_ranges_m)])

    @property
    def range_size(self) -> np.ndarray:
        """Side of the fitted box per axis [m]."""
        hi = np.array([self.length_range_m[1], self.width_range_m[1], *(hi for _, hi in self.extra_ranges_m)])
        return hi - self.range_lo

    def variables(self, center: np.ndarray, radius: np.ndarray, order: int = 1) -> tuple[Jet, ...]:
        """Jets of the axes, then s, over boxes (centres and half widths (N, k + 1)), of ``order`` 1 or 2."""
        n = self.k + 1
        return tuple(Jet.variable(center[:, i], radius[:, i], i, n, order) for i in range(n))

    def column(self, name: str) -> int | None:
        """Column of the axis ``name`` among the axes, or None if the coefficients do not vary it."""
        return self.axes.names.index(name) if name in self.axes.names else None

    @property
    def x_column(self) -> int | None:
        """Column of the obstacle's centre x among the axes (None without an x axis: the
        obstacle stays at the scene's x = 0)."""
        return self.column("x")

    @property
    def d_column(self) -> int | None:
        """Column of the obstacle's far edge y, d, among the axes (None without a d axis: the
        obstacle's far edge stays at the scene's ``top_y_m``, and P1, P5 at its ``y1_m``)."""
        return self.column("d")

    def obstacle_moves(self, points_m: np.ndarray) -> dict[str, np.ndarray | None]:
        """The obstacle's centre x and far edge d [m] at ``points_m`` (n, k) of the axes, as the
        keywords ``centre_x_m`` and ``top_y_m`` of ``pipeline.certify.end_pose_room`` (None where
        the coefficients do not vary them: the scene's)."""
        x, d = self.x_column, self.d_column
        return {
            "centre_x_m": None if x is None else points_m[:, x],
            "top_y_m": None if d is None else points_m[:, d],
        }

    def free_jets(self, *axes: Jet) -> list[Jet]:
        """Jets of the family's free parameters (quadratics in the axes, the basis of
        :class:`pipeline.offline.variables.Variables`; for (L, W): 1, L, W, L^2, L W, W^2),
        evaluated in the axes' offsets from :attr:`origin_m` (module docstring, "Offsets")."""
        offsets = [axis if o == 0.0 else axis - o for axis, o in zip(axes, self.origin_m, strict=False)]
        squares = [offsets[i].square() if i == j else offsets[i] * offsets[j] for i, j in self.axes.pairs]
        basis = (*offsets, *squares)
        out = []
        for row in self._offset_rows:
            jet = basis[0] * row[1] + row[0]
            for term, b in zip(basis[1:], row[2:], strict=True):
                jet = jet + term * b
            out.append(jet)
        constant, linear = self._offset_error
        if np.any(constant) or np.any(linear):  # the re-expansion's rounding (module docstring)
            reach = np.stack([offset.value.mag() for offset in offsets], -1)  # max |u_i| per box
            for n, jet in enumerate(out):
                value = constant[n] + reach @ linear[n]
                spread = np.zeros(jet.grad.shape)
                spread[..., : len(offsets)] = linear[n]
                out[n] = Jet(  # constant and linear in the offsets: the Hessian is the jet's
                    Interval(jet.value.lo - value, jet.value.hi + value),
                    Interval(jet.grad.lo - spread, jet.grad.hi + spread),
                    jet.hess,
                )
        return out

    def parameter_jets(self, axes: tuple[Jet, ...], T: Jet) -> list[Jet]:
        """Jets of the 8 parameters (A1, w1, phi1, gamma1, A2, w2, phi2, gamma2) from the jets of
        the k axes and of T."""
        axes = tuple(axes[: self.k])
        return JET_EXPANSIONS[type(self.family)](self, self.free_jets(*axes), axes[0], axes[1], T)

    def _exact_endpoints_jets(self, free: list[Jet], L: Jet, W: Jet, T: Jet) -> list[Jet]:
        """Jets of ``ExactEndpointsFamily.expand`` (module docstring)."""
        w1, phi1, a2, w2 = free
        start, end = self._ik_jets(L, W, 1.0), self._ik_jets(L, W, -1.0)
        denominator = (w1 * T + phi1).sin() - phi1.sin()
        small = (denominator.value.lo <= MIN_DENOMINATOR) & (denominator.value.hi >= -MIN_DENOMINATOR)
        a1 = (end[0] - start[0]) / _unbounded_where(denominator, small)
        gamma1 = start[0] - a1 * phi1.sin()
        phi2 = (w2 * T) * (-0.5) + math.pi / 2
        gamma2 = start[1] - a2 * phi2.sin()
        return [a1, w1, phi1, gamma1, a2, w2, phi2, gamma2]

    def endpoints_pinned(self, center: np.ndarray, radius: np.ndarray) -> np.ndarray:
        """True per (L, W) box (centres, half widths (N, >= 2)) where the family pins the tip to
        P1 and P5 exactly for every (L, W) of the box.

        For exact-endpoints, theta(0) = theta_s and theta(T) = theta_e hold algebraically
        (gamma1 + A1 sin(phi1) = th1_s, A1 D = th1_e - th1_s, sin(w2 T + phi2) = sin(phi2) and
        th2_s = th2_e) wherever A1 = (th1_e - th1_s) / D is not clamped, i.e. where the interval
        of D over the box excludes [-1e-3, 1e-3]; the tip is then FK(IK(P)) = P up to rounding.
        """
        n = center.shape[0]
        if not self.family.pins_endpoints:
            return np.zeros(n, dtype=bool)
        c3 = np.column_stack([center[:, :2], np.zeros(n)])
        r3 = np.column_stack([radius[:, :2], np.zeros(n)])
        L, W, _ = self.variables(c3, r3)
        w1, phi1 = self.free_jets(L, W)[:2]
        T = self.duration.jet(c3, r3)
        d = ((w1 * T + phi1).sin() - phi1.sin()).value
        return (d.lo > MIN_DENOMINATOR) | (d.hi < -MIN_DENOMINATOR)

    def _ik_jets(self, L: Jet, W: Jet, side: float) -> tuple[Jet, Jet]:
        """Joint angles (th1, th2) of P1 (side +1) or P5 (side -1) on the elbow branch, as jets."""
        l1, l2 = self.link_lengths_m
        x = (L * 0.5 + self.scene.start_dx_m) * side
        y = self.scene.y1_m
        r2 = x.square() + y * y
        c = (r2 - (l1 * l1 + l2 * l2)) / (2 * l1 * l2)
        th2 = _acos(c) * float(self.elbow)
        base = _atan2_const_y(y, x)
        sin2, cos2 = th2.sin(), th2.cos()
        th1 = base - _atan2(sin2 * l2, cos2 * l2 + l1)
        return th1, th2

    def joint_jets(self, center: np.ndarray, radius: np.ndarray, order: int = 1) -> tuple[Jet, Jet]:
        """Jets of (theta1, theta2) [rad] over boxes of (axes, s) with centres/half widths (N, k + 1),
        of ``order`` 1 or 2 (2: with Hessians, where the family's expansion keeps them)."""
        jets = self.variables(center, radius, order)
        s = jets[-1]
        T = self.duration.jet(center, radius, k=self.k + 1, order=order)
        p = self.parameter_jets(jets, T)
        sT = s * T
        theta1 = (p[1] * sT + p[2]).sin() * p[0] + p[3]
        theta2 = (p[5] * sT + p[6]).sin() * p[4] + p[7]
        return theta1, theta2


def _offset_coefficients(
    rows: np.ndarray, pairs: tuple[tuple[int, int], ...], origin: tuple[float, ...]
) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """The quadratics' rows (n, basis) re-expanded in the offsets u = v - ``origin`` (module
    docstring, "Offsets"), and bounds on the re-expansion's rounding: per row, of the constant
    (n,) and of each linear coefficient (n, k). ``rows`` itself and zero bounds where the origin is 0."""
    k = len(origin)
    n = rows.shape[0]
    if not any(origin):
        return rows, (np.zeros(n), np.zeros((n, k)))
    o = np.array(origin)
    out = np.array(rows, dtype=float)
    constant = [rows[:, 0]]  # the terms summed into each new coefficient
    linear = [[rows[:, 1 + i]] for i in range(k)]
    for b, (i, j) in zip(rows[:, 1 + k :].T, pairs, strict=True):
        constant.append(b * (o[i] * o[j]))
        if i == j:
            linear[i].append(2.0 * o[i] * b)
        else:
            linear[i].append(o[j] * b)
            linear[j].append(o[i] * b)
    for i in range(k):
        constant.append(rows[:, 1 + i] * o[i])
    out[:, 0] = np.sum(constant, axis=0)
    for i in range(k):
        out[:, 1 + i] = np.sum(linear[i], axis=0)
    out.setflags(write=False)

    def rounding(terms: list[np.ndarray]) -> np.ndarray:
        # m terms, each a product of up to three factors (two roundings), then m - 1 additions:
        # off by at most (m + 1) eps (1 + O(eps)) sum |terms|; twice (m + 3) eps is generous.
        return 2.0 * (len(terms) + 3) * _EPS * np.sum(np.abs(terms), axis=0)

    return out, (rounding(constant), np.stack([rounding(terms) for terms in linear], -1))


def _paper_jets(model: RangeModel, free: list[Jet], L: Jet, W: Jet, T: Jet) -> list[Jet]:
    """The paper family: the 8 parameters are the free ones."""
    return free


#: Jet version of each family's ``expand``: (model, free jets, L, W, T) -> 8 parameter jets.
JET_EXPANSIONS = MappingProxyType(
    {
        PaperFamily: _paper_jets,
        ExactEndpointsFamily: lambda model, free, L, W, T: model._exact_endpoints_jets(free, L, W, T),
    }
)


def _unbounded_where(jet: Jet, mask: np.ndarray) -> Jet:
    """The jet with value and gradient replaced by (-inf, inf) where ``mask`` (never certified there)."""
    if not np.any(mask):
        return jet
    inf = np.where(mask, np.inf, 0.0)
    value = Interval(np.where(mask, -np.inf, jet.value.lo), np.where(mask, np.inf, jet.value.hi))
    grad = Interval(jet.grad.lo - inf[..., None], jet.grad.hi + inf[..., None])
    return Jet(value, grad)


def _acos(c: Jet) -> Jet:
    """acos of a jet whose value lies in (-1, 1)."""
    lo, hi = np.clip(c.value.lo, -1.0, 1.0), np.clip(c.value.hi, -1.0, 1.0)
    value = Interval(np.arccos(hi), np.arccos(lo))
    one_minus = 1.0 - c.value.square()
    inside = Interval(np.maximum(one_minus.lo, 0.0), np.maximum(one_minus.hi, 0.0))
    derivative = -inside.sqrt().reciprocal()
    return Jet(value, Interval(derivative.lo[..., None], derivative.hi[..., None]) * c.grad)


def _atan_ratio(num: Jet, den: Jet) -> Jet:
    """atan(num / den) for den > 0 over the box, with derivative (den num' - num den') / (num^2 + den^2)."""
    ratio = num.value / den.value
    value = Interval(np.arctan(ratio.lo), np.arctan(ratio.hi))
    inv = (num.value.square() + den.value.square()).reciprocal()
    grad = (num.grad * Interval(den.value.lo[..., None], den.value.hi[..., None])) - (
        den.grad * Interval(num.value.lo[..., None], num.value.hi[..., None])
    )
    return Jet(value, grad * Interval(inv.lo[..., None], inv.hi[..., None]))


def _atan2(y: Jet, x: Jet) -> Jet:
    """atan2(y, x) for x > 0 over the box (else unbounded)."""
    bad = x.value.lo <= 0.0
    return _unbounded_where(_atan_ratio(y, x), bad)


def _atan2_const_y(y: float, x: Jet) -> Jet:
    """atan2(y, x) for a constant y > 0 and x of one sign over the box."""
    k = x.k
    y_jet = Jet.constant(np.full(x.value.shape, y), k)
    # atan2(y, x) = pi/2 - atan(x / y) for y > 0 (any sign of x).
    if y <= 0:
        raise InvalidParameterError("y1_m", y, "> 0 (start and goal above the base)")
    return _atan_ratio(x, y_jet) * (-1.0) + math.pi / 2
