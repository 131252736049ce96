"""Execution bounds over the range: per leaf of the region map, what every trajectory of the leaf
does to the arm's limits, proven for every point of the leaf (L, W, and x, d where the
coefficients vary them) and all of [0, T].

**Kinematic bounds (arm-independent).** Over a leaf X (a box of the coefficients' axes), the
range model (:class:`pipeline.certify.range_model.RangeModel`) encloses each sinusoid parameter
p(L, W[, x][, d]) by its mean-value form intersected with its natural interval (interval jets),
and the path duration T(L, W) (independent of x and d) by
:class:`pipeline.certify.duration.DurationModel`. The path time t = s T, s in [0, 1], is cut
into :data:`TIME_PIECES` pieces [s_k, s_k+1]; on each, the phase w t + phi lies in the interval
w [s_k T_lo, s_k+1 T_hi] + phi (t >= 0), and the exact ranges of sin and cos over it give, in
interval arithmetic (each result encloses every value taken):

* theta_i = A_i sin(.) + gamma_i: the angle range of the leaf, the hull over the pieces;
* theta_i' = A_i w_i cos(.): its largest magnitude V_i, the paper timing's peak |dq_i|;
* theta_i'' = -A_i w_i^2 sin(.): its largest magnitude Acc_i, the paper timing's peak |ddq_i|.

The interval products lose the dependence between A, w and phi inside the leaf, so the bounds
exceed the true maxima by about the parameters' variation over the leaf (small: the leaves are
the range certificate's, down to 1/1024 of the range per side); at a maximum the range of cos
(or sin) over a phase interval is exactly 1, so the time cut costs nothing there.

**Torque terms (for one arm).** With the arm's closed-form dynamics
(:class:`pipeline.model.dynamics.PlanarDynamics`), a timing sigma gives dq = theta' sigma' and
ddq = theta'' sigma'^2 + theta' sigma'', and since the Coriolis terms are quadratic in dq,

    tau(tau') = sigma'^2 [M theta'' + h Q(theta')] + sigma'' [M theta'],

both brackets evaluated at the path time sigma(tau') (M, h at q2; Q_1 = 2 theta1' theta2' +
theta2'^2, Q_2 = -theta1'^2). On each piece, M and h are enclosed over the piece's range of q2
(exact ranges of cos and sin), and the brackets in interval arithmetic: their largest
magnitudes over the leaf are G_i (the paper timing's torque bound, sigma' = 1, sigma'' = 0) and
K_i. Keeping the brackets whole keeps the correlation between the joints' terms, which bounding
each product separately would lose.

**Limit bounds.** With the arm's limits (:class:`pipeline.model.limits.ArmLimits`), the
rest-to-rest timing (c, r) of :func:`pipeline.motion.rest_to_rest.rest_to_rest_scales` computed
from (T_lo, V, Acc, G, K) has |dq_i| <= c V_i, |ddq_i| <= c^2 Acc_i + 1.5 c V_i / r and
|tau_i| <= c^2 G_i + 1.5 c K_i / r (sigma' <= c, |sigma''| <= 1.5 c / r); these hold for every
path of the leaf, since each has smaller peaks and duration T >= T_lo >= c r (the ramps fit). A
query of the leaf runs ``RestToRestTiming(T, c, r)``, of duration T' = T / c + r <= T_hi / c + r.

**Rounding.** The stored columns are rounded outward (:mod:`pipeline.certify.execution_bounds`).
Before that, every enclosure is widened by the execution certificate's slack
(:data:`pipeline.motion.execution_certificate.FLOAT_SLACK_RELATIVE` of its magnitude plus
:data:`pipeline.motion.execution_certificate.FLOAT_SLACK_ABSOLUTE`); the chain is a few dozen
operations on values of order 1, each off by an ulp, far below it. T's enclosure carries its
own quadrature and rounding bounds.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from pipeline.certify.execution_bounds import ROUNDED_DOWN, ExecutionBounds, outward
from pipeline.certify.interval import Interval
from pipeline.certify.range_model import RangeModel
from pipeline.io.executor import Executor, map_tasks
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.execution_certificate import FLOAT_SLACK_ABSOLUTE, FLOAT_SLACK_RELATIVE
from pipeline.motion.rest_to_rest import rest_to_rest_scales

__all__ = ["TIME_PIECES", "LeafJets", "execution_bounds", "kinematic_bounds", "leaf_jets", "leaf_parameters"]

#: Pieces of the path time [0, T] per leaf.
TIME_PIECES = 64
#: Leaves per vectorised chunk (memory: about 60 arrays of leaves x TIME_PIECES floats).
_CHUNK = 2048


def _widen(interval: Interval) -> Interval:
    slack = FLOAT_SLACK_RELATIVE * np.maximum(np.abs(interval.lo), np.abs(interval.hi)) + FLOAT_SLACK_ABSOLUTE
    return Interval(interval.lo - slack, interval.hi + slack)


def leaf_parameters(model: RangeModel, centre_m: np.ndarray, half_m: np.ndarray) -> tuple[list[Interval], Interval]:
    """Enclosures of the 8 sinusoid parameters and of T over each box of the axes (centres and
    half widths (n, k)): mean-value form at the centre intersected with the natural enclosure."""
    jets = leaf_jets(model, centre_m, half_m)
    return jets.parameters, jets.duration


@dataclass(frozen=True, eq=False)
class LeafJets:
    """The parameters of the boxes of :func:`leaf_jets`, each list entry one parameter, n boxes.

    Attributes:
        parameters: Enclosures over each box (mean-value form intersected with the natural one), (n,).
        duration: T over each box [s], (n,).
        gradients: The parameters' gradients over each box, (n, k) per parameter.
        duration_gradient: T's gradient over each box [s/m], (n, k).
        point: The parameters' enclosures at each box's centre, (n,).
        point_duration: T at each box's centre [s], (n,).
    """

    parameters: list[Interval]
    duration: Interval
    gradients: list[Interval]
    duration_gradient: Interval
    point: list[Interval]
    point_duration: Interval


def leaf_jets(model: RangeModel, centre_m: np.ndarray, half_m: np.ndarray) -> LeafJets:
    """The parameters' and T's enclosures and gradients over each box of the axes (centres and
    half widths (n, k)), and their enclosures at the centres (:class:`LeafJets`)."""
    n, k = centre_m.shape
    c3 = np.column_stack([centre_m, np.zeros(n)])
    r3 = np.column_stack([half_m, np.zeros(n)])
    zero = np.zeros_like(r3)
    T_box = model.duration.jet(c3, r3, k=model.k + 1)
    T_point = model.duration.jet(c3, zero, k=model.k + 1)
    box = model.parameter_jets(model.variables(c3, r3), T_box)
    point = model.parameter_jets(model.variables(c3, zero), T_point)
    out = []
    for p_box, p_point in zip(box, point, strict=True):
        spread = np.sum(p_box.grad.mag() * r3, axis=-1)
        with np.errstate(invalid="ignore"):
            lo = np.maximum(p_point.value.lo - spread, p_box.value.lo)
            hi = np.minimum(p_point.value.hi + spread, p_box.value.hi)
        bad = ~(np.isfinite(lo) & np.isfinite(hi))
        out.append(Interval(np.where(bad, -np.inf, lo), np.where(bad, np.inf, hi)))
    return LeafJets(
        parameters=out,
        duration=T_box.value,
        gradients=[Interval(p.grad.lo[..., :k], p.grad.hi[..., :k]) for p in box],
        duration_gradient=Interval(T_box.grad.lo[..., :k], T_box.grad.hi[..., :k]),
        point=[p.value for p in point],
        point_duration=T_point.value,
    )


def kinematic_bounds(
    model: RangeModel, centre_m: np.ndarray, half_m: np.ndarray, dynamics: PlanarDynamics
) -> dict[str, np.ndarray]:
    """The bounds of the module docstring over boxes of the model's axes, before any limit.

    Args:
        model: The range model of the coefficients.
        centre_m, half_m: Box centres and half widths (n, k), columns the model's axes (L, W[, x][, d]) [m].
        dynamics: The arm's dynamics (for the torque terms G and K).

    Returns:
        The columns ``duration_lo_s`` .. ``ramp_torque2_n_m_s`` of
        :data:`pipeline.certify.execution_bounds.COLUMNS` but c and r, each (n,) (infinite where
        the family's parameters are unbounded over the box).
    """
    centre_m, half_m = np.asarray(centre_m, dtype=float), np.asarray(half_m, dtype=float)
    parts = [
        _kinematic_chunk(model, centre_m[k : k + _CHUNK], half_m[k : k + _CHUNK], dynamics)
        for k in range(0, centre_m.shape[0], _CHUNK)
    ]
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}


def _kinematic_chunk(
    model: RangeModel, centre_m: np.ndarray, half_m: np.ndarray, dynamics: PlanarDynamics
) -> dict[str, np.ndarray]:
    params, T = leaf_parameters(model, centre_m, half_m)
    edges = np.linspace(0.0, 1.0, TIME_PIECES + 1)
    t = Interval(edges[None, :-1] * T.lo[:, None], edges[None, 1:] * T.hi[:, None])  # (n, S), t >= 0
    out = {"duration_lo_s": T.lo.copy(), "duration_hi_s": T.hi.copy()}
    finite = np.isfinite(T.lo) & np.isfinite(T.hi)
    finite &= np.all([np.isfinite(p.lo) & np.isfinite(p.hi) for p in params], 0)
    angle, d1, d2 = [], [], []
    with np.errstate(invalid="ignore", over="ignore"):
        for joint in (0, 1):
            A, w, phi, gamma = (_column(p) for p in params[4 * joint : 4 * joint + 4])
            phase = w * t + phi
            sin = phase.sin()
            angle.append(A * sin + gamma)
            d1.append(A * w * phase.cos())
            d2.append(-(A * w.square() * sin))
        # M(q2) and h(q2) over each piece's range of q2, then the torque terms (module docstring).
        cos2, sin2 = angle[1].cos(), angle[1].sin()
        m0, mc, ms = (np.asarray(m) for m in (dynamics.m0, dynamics.mc, dynamics.ms))
        M = [[cos2 * mc[i, j] + sin2 * ms[i, j] + m0[i, j] for j in (0, 1)] for i in (0, 1)]
        h = (sin2 * (-mc[0, 0]) + cos2 * ms[0, 0]) * 0.5
        G = (
            M[0][0] * d2[0] + M[0][1] * d2[1] + h * (d1[0] * d1[1] * 2.0 + d1[1].square()),
            M[1][0] * d2[0] + M[1][1] * d2[1] - h * d1[0].square(),
        )
        K = (M[0][0] * d1[0] + M[0][1] * d1[1], M[1][0] * d1[0] + M[1][1] * d1[1])
    for joint in (0, 1):
        suffix = str(joint + 1)
        widened = {name: _widen(x[joint]) for name, x in (("angle", angle), ("d1", d1), ("d2", d2), ("G", G), ("K", K))}
        out["angle_lo" + suffix + "_rad"] = np.where(finite, widened["angle"].lo.min(1), -np.inf)
        out["angle_hi" + suffix + "_rad"] = np.where(finite, widened["angle"].hi.max(1), np.inf)
        out["peak_speed" + suffix + "_rad_s"] = np.where(finite, widened["d1"].mag().max(1), np.inf)
        out["peak_acceleration" + suffix + "_rad_s2"] = np.where(finite, widened["d2"].mag().max(1), np.inf)
        out["paper_torque" + suffix + "_n_m"] = np.where(finite, widened["G"].mag().max(1), np.inf)
        out["ramp_torque" + suffix + "_n_m_s"] = np.where(finite, widened["K"].mag().max(1), np.inf)
    return out


def _column(p: Interval) -> Interval:
    """A per-leaf interval as a column (n, 1), finite values only (non-finite leaves are masked)."""
    lo = np.where(np.isfinite(p.lo), p.lo, 0.0)
    hi = np.where(np.isfinite(p.hi), p.hi, 0.0)
    return Interval(lo[:, None], hi[:, None])


def execution_bounds(
    model: RangeModel,
    centre_m: np.ndarray,
    half_m: np.ndarray,
    dynamics: PlanarDynamics,
    limits: ArmLimits,
    executor: int | Executor = 1,
) -> ExecutionBounds:
    """The execution bounds of boxes of the model's axes (a region map's leaves) for one arm (module docstring).

    Args:
        model: The range model of the coefficients.
        centre_m, half_m: Leaf centres and half widths (n, k), columns the model's axes (L, W[, x][, d]) [m].
        dynamics: The arm's dynamics.
        limits: The arm's limits.
        executor: Where the chunks of :data:`_CHUNK` leaves run (:func:`pipeline.io.executor.map_tasks`:
            a number of local processes or an executor); the chunks are fixed and every leaf's
            bounds are its own, so the bounds do not depend on it.
    """
    centre_m, half_m = np.asarray(centre_m, dtype=float), np.asarray(half_m, dtype=float)
    chunks = [(centre_m[k : k + _CHUNK], half_m[k : k + _CHUNK]) for k in range(0, centre_m.shape[0], _CHUNK)]
    task = functools.partial(_bounds_chunk, model, dynamics, limits)
    parts = map_tasks(executor, task, chunks, chunk_size=1)
    columns = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    return ExecutionBounds(limits, dynamics, columns)


def _bounds_chunk(
    model: RangeModel, dynamics: PlanarDynamics, limits: ArmLimits, chunk: tuple[np.ndarray, np.ndarray]
) -> dict[str, np.ndarray]:
    """The stored columns of one chunk of leaves (centres, half widths): the kinematic bounds,
    the rest-to-rest timing (c, r) and the outward rounding (module docstring)."""
    columns = kinematic_bounds(model, chunk[0], chunk[1], dynamics)

    def pair(stem: str) -> np.ndarray:
        return np.stack([columns[stem.format(1)], columns[stem.format(2)]], -1)

    V, acc = pair("peak_speed{}_rad_s"), pair("peak_acceleration{}_rad_s2")
    G, K = pair("paper_torque{}_n_m"), pair("ramp_torque{}_n_m_s")
    finite = np.all(np.isfinite(np.concatenate([V, acc, G, K], 1)), 1) & np.isfinite(columns["duration_lo_s"])
    c, r = np.full(V.shape[0], np.nan), np.full(V.shape[0], np.nan)
    rows = np.flatnonzero(finite)
    if rows.size:
        c[rows], r[rows] = rest_to_rest_scales(
            columns["duration_lo_s"][rows], V[rows], acc[rows], dynamics, limits, torque_terms=(G[rows], K[rows])
        )
    columns["speed_scale"], columns["ramp_s"] = c, r
    columns = {key: outward(values, key in ROUNDED_DOWN) for key, values in columns.items()}
    # Rounding c down and r up only lowers the bounds; the ramps must still fit (r <= T_lo / c).
    fits = columns["ramp_s"] * columns["speed_scale"] <= columns["duration_lo_s"]
    for key in ("speed_scale", "ramp_s"):
        columns[key] = np.where(fits, columns[key], np.nan)
    return columns
