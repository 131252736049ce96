"""Execution bounds over the range: per leaf of the region map, what every trajectory of the leaf
does to the arm's limits, proven for every (L, W) of the leaf and all of [0, T].

**Kinematic bounds (arm-independent).** Over a leaf X (an (L, W) box), the range model
(:class:`pipeline.certify.range_model.RangeModel`) encloses each sinusoid parameter p(L, W) by
its mean-value form intersected with its natural interval (interval jets), and the path duration
T(L, W) by :class:`pipeline.certify.duration.DurationModel`. The path time t = s T, s in [0, 1],
is cut into :data:`TIME_PIECES` pieces [s_k, s_k+1]; on each, the phase w t + phi lies in the
interval w [s_k T_lo, s_k+1 T_hi] + phi (t >= 0), and the exact ranges of sin and cos over it
give, in interval arithmetic (each result encloses every value taken):

* theta_i = A_i sin(.) + gamma_i: the angle range of the leaf, the hull over the pieces;
* theta_i' = A_i w_i cos(.): its largest magnitude V_i, the paper timing's peak |dq_i|;
* theta_i'' = -A_i w_i^2 sin(.): its largest magnitude Acc_i, the paper timing's peak |ddq_i|.

The interval products lose the dependence between A, w and phi inside the leaf, so the bounds
exceed the true maxima by about the parameters' variation over the leaf (small: the leaves are
the range certificate's, down to 1/1024 of the range per side); at a maximum the range of cos
(or sin) over a phase interval is exactly 1, so the time cut costs nothing there.

**Limit bounds (for one arm).** With the arm's closed-form dynamics
(:class:`pipeline.model.dynamics.PlanarDynamics`) and limits (:class:`pipeline.model.limits.ArmLimits`):

* the paper timing's torque bound ``sum_j Mmax_ij Acc_j + Hmax Q_i`` (Q_1 = 2 V_1 V_2 + V_2^2,
  Q_2 = V_1^2; :func:`pipeline.motion.rest_to_rest.rest_to_rest_bounds` with c = 1 and no ramp);
* the rest-to-rest timing (c, r) of :func:`pipeline.motion.rest_to_rest.rest_to_rest_scales`
  computed from (T_lo, V, Acc): its closed-form bounds hold for every path of the leaf, since
  each has peaks <= (V, Acc) and duration T >= T_lo >= c r (the ramps fit). A query of the leaf
  runs ``RestToRestTiming(T, c, r)``, of duration T' = T / c + r <= T_hi / c + r.

**Rounding.** The stored columns are rounded outward (:mod:`pipeline.certify.execution_bounds`).
Before that, every enclosure is widened by the execution certificate's slack
(:data:`pipeline.motion.execution_certificate.FLOAT_SLACK_RELATIVE` of its magnitude plus
:data:`pipeline.motion.execution_certificate.FLOAT_SLACK_ABSOLUTE`); the chain is a few dozen
operations on values of order 1, each off by an ulp, far below it. T's enclosure carries its
own quadrature and rounding bounds.
"""

from __future__ import annotations

import numpy as np

from pipeline.certify.execution_bounds import ROUNDED_DOWN, ExecutionBounds, outward
from pipeline.certify.interval import Interval
from pipeline.certify.range_model import RangeModel
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.execution_certificate import FLOAT_SLACK_ABSOLUTE, FLOAT_SLACK_RELATIVE
from pipeline.motion.rest_to_rest import rest_to_rest_scales

__all__ = ["TIME_PIECES", "execution_bounds", "kinematic_bounds"]

#: Pieces of the path time [0, T] per leaf.
TIME_PIECES = 64
#: Leaves per vectorised chunk (memory: about 60 arrays of leaves x TIME_PIECES floats).
_CHUNK = 2048


def _widen(interval: Interval) -> Interval:
    slack = FLOAT_SLACK_RELATIVE * np.maximum(np.abs(interval.lo), np.abs(interval.hi)) + FLOAT_SLACK_ABSOLUTE
    return Interval(interval.lo - slack, interval.hi + slack)


def _leaf_parameters(model: RangeModel, centre_m: np.ndarray, half_m: np.ndarray) -> tuple[list[Interval], Interval]:
    """Enclosures of the 8 sinusoid parameters and of T over each (L, W) box: mean-value form at
    the centre intersected with the natural enclosure."""
    n = centre_m.shape[0]
    c3 = np.column_stack([centre_m, np.zeros(n)])
    r3 = np.column_stack([half_m, np.zeros(n)])
    zero = np.zeros_like(r3)
    T_box = model.duration.jet(c3, r3)
    T_point = model.duration.jet(c3, zero)
    box = model.parameter_jets(*model.variables(c3, r3)[:2], T_box)
    point = model.parameter_jets(*model.variables(c3, zero)[:2], T_point)
    out = []
    for p_box, p_point in zip(box, point, strict=True):
        spread = np.sum(p_box.grad.mag() * r3, axis=-1)
        with np.errstate(invalid="ignore"):
            lo = np.maximum(p_point.value.lo - spread, p_box.value.lo)
            hi = np.minimum(p_point.value.hi + spread, p_box.value.hi)
        bad = ~(np.isfinite(lo) & np.isfinite(hi))
        out.append(Interval(np.where(bad, -np.inf, lo), np.where(bad, np.inf, hi)))
    return out, T_box.value


def kinematic_bounds(model: RangeModel, centre_m: np.ndarray, half_m: np.ndarray) -> dict[str, np.ndarray]:
    """The arm-independent bounds of the module docstring over (L, W) boxes.

    Args:
        model: The range model of the coefficients.
        centre_m, half_m: Box centres and half widths (n, 2), columns L, W [m].

    Returns:
        The columns ``duration_lo_s`` .. ``peak_acceleration2_rad_s2`` of :data:`COLUMNS`, each (n,)
        (infinite where the family's parameters are unbounded over the box).
    """
    centre_m, half_m = np.asarray(centre_m, dtype=float), np.asarray(half_m, dtype=float)
    parts = [
        _kinematic_chunk(model, centre_m[k : k + _CHUNK], half_m[k : k + _CHUNK])
        for k in range(0, centre_m.shape[0], _CHUNK)
    ]
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}


def _kinematic_chunk(model: RangeModel, centre_m: np.ndarray, half_m: np.ndarray) -> dict[str, np.ndarray]:
    params, T = _leaf_parameters(model, centre_m, half_m)
    edges = np.linspace(0.0, 1.0, TIME_PIECES + 1)
    t = Interval(edges[None, :-1] * T.lo[:, None], edges[None, 1:] * T.hi[:, None])  # (n, S), t >= 0
    out = {"duration_lo_s": T.lo.copy(), "duration_hi_s": T.hi.copy()}
    finite_t = np.isfinite(T.lo) & np.isfinite(T.hi)
    for joint in (0, 1):
        A, w, phi, gamma = (_column(p) for p in params[4 * joint : 4 * joint + 4])
        finite = finite_t & np.all(
            [np.isfinite(p.lo) & np.isfinite(p.hi) for p in params[4 * joint : 4 * joint + 4]], 0
        )
        with np.errstate(invalid="ignore", over="ignore"):
            phase = w * t + phi
            sin, cos = phase.sin(), phase.cos()
            angle = _widen(A * sin + gamma)
            speed = _widen(A * w * cos)
            acceleration = _widen(A * w.square() * sin)
        suffix = str(joint + 1)
        out["angle_lo" + suffix + "_rad"] = np.where(finite, angle.lo.min(1), -np.inf)
        out["angle_hi" + suffix + "_rad"] = np.where(finite, angle.hi.max(1), np.inf)
        out["peak_speed" + suffix + "_rad_s"] = np.where(finite, speed.mag().max(1), np.inf)
        out["peak_acceleration" + suffix + "_rad_s2"] = np.where(finite, acceleration.mag().max(1), np.inf)
    return out


def _column(p: Interval) -> Interval:
    """A per-leaf interval as a column (n, 1), finite values only (non-finite leaves are masked)."""
    lo = np.where(np.isfinite(p.lo), p.lo, 0.0)
    hi = np.where(np.isfinite(p.hi), p.hi, 0.0)
    return Interval(lo[:, None], hi[:, None])


def execution_bounds(
    model: RangeModel, centre_m: np.ndarray, half_m: np.ndarray, dynamics: PlanarDynamics, limits: ArmLimits
) -> ExecutionBounds:
    """The execution bounds of (L, W) boxes (a region map's leaves) for one arm (module docstring).

    Args:
        model: The range model of the coefficients.
        centre_m, half_m: Leaf centres and half widths (n, 2), columns L, W [m].
        dynamics: The arm's dynamics.
        limits: The arm's limits.
    """
    columns = kinematic_bounds(model, centre_m, half_m)
    V = np.stack([columns["peak_speed1_rad_s"], columns["peak_speed2_rad_s"]], -1)
    acc = np.stack([columns["peak_acceleration1_rad_s2"], columns["peak_acceleration2_rad_s2"]], -1)
    finite = np.all(np.isfinite(V) & np.isfinite(acc), 1) & np.isfinite(columns["duration_lo_s"])
    c, r = np.full(V.shape[0], np.nan), np.full(V.shape[0], np.nan)
    rows = np.flatnonzero(finite)
    for k in range(0, rows.size, _CHUNK):
        part = rows[k : k + _CHUNK]
        c[part], r[part] = rest_to_rest_scales(columns["duration_lo_s"][part], V[part], acc[part], dynamics, limits)
    columns["speed_scale"], columns["ramp_s"] = c, r
    columns = {key: outward(values, key in ROUNDED_DOWN) for key, values in columns.items()}
    # Rounding c down and r up only lowers the bounds; the ramps must still fit (r <= T_lo / c).
    fits = columns["ramp_s"] * columns["speed_scale"] <= columns["duration_lo_s"]
    for key in ("speed_scale", "ramp_s"):
        columns[key] = np.where(fits, columns[key], np.nan)
    return ExecutionBounds(limits, dynamics, columns)
