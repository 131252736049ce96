"""The exact-endpoints family: the tip is pinned to P1 at t = 0 and to P5 at t = T by construction.

With theta_s, theta_e the joint angles of P1 and P5 (analytic IK, one elbow branch), joint 1
keeps (w1, phi1) free and

    A1 = (theta1_e - theta1_s) / D,  D = sin(w1 T + phi1) - sin(phi1),
    gamma1 = theta1_s - A1 sin(phi1).

Joint 2 keeps (A2, w2) free; phi2 and gamma2 follow from theta2(0) = theta2_s and
theta2(T) = theta2_e. The first gives gamma2 = theta2_s - A2 sin(phi2); with it the second reads

    A2 (sin(w2 T + phi2) - sin(phi2)) = 2 A2 sin(w2 T / 2) cos(phi2 + w2 T / 2) = theta2_e - theta2_s,

so cos(phi2 + w2 T / 2) = r with r = (theta2_e - theta2_s) / (2 A2 sin(w2 T / 2)), and

    phi2 = arccos(r) - w2 T / 2.

With the obstacle centred on the y axis P1 and P5 are mirror images, theta2_s = theta2_e,
r = 0, and this is phi2 = (pi - w2 T) / 2 (so that sin(w2 T + phi2) = sin(phi2)): where
theta2_s == theta2_e exactly, :meth:`ExactEndpointsFamily.expand` evaluates that form. Of the
two solutions phi2 + w2 T / 2 = +-arccos(r), the family takes the one continuous with it.
Joint 2 then moves as A2 sin(w2 (t - T/2) + arccos(r)) + const.

Where |D| < :data:`MIN_DENOMINATOR` (w1 T + phi1 and phi1 have almost the same sine), A1 would
blow up; D is clamped to that size with its sign, A1 stays bounded, and joint 1 no longer
reaches theta1_e. Where |r| > 1 (|A2 sin(w2 T / 2)| is smaller than half the change of theta2),
r is clamped to +-1 and joint 2 ends as near theta2_e as its amplitude allows.
:meth:`ExactEndpointsFamily.endpoints_exact` reports either clamp as not exact, and the
generator warns when it returns such parameters.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.motion.families.base import EndpointContext, TrajectoryFamily
from pipeline.motion.trajectory import canonicalize

#: Smallest |sin(w1 T + phi1) - sin(phi1)| used before A1 is clamped (A1 would blow up).
MIN_DENOMINATOR = 1e-3


def _require(context: EndpointContext | None) -> EndpointContext:
    if context is None:
        raise InvalidParameterError("context", None, "an EndpointContext for the exact-endpoints family")
    return context


def _denominator(w1: np.ndarray, phi1: np.ndarray, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(D, clamped) with D = sin(w1 T + phi1) - sin(phi1), clamped to |D| >= MIN_DENOMINATOR."""
    raw = np.sin(w1 * duration_s + phi1) - np.sin(phi1)
    clamped = np.abs(raw) < MIN_DENOMINATOR
    return np.where(clamped, np.copysign(MIN_DENOMINATOR, raw), raw), clamped


def _joint2_phase(
    a2: np.ndarray, w2: np.ndarray, context: EndpointContext
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(phi2, r, clamped): joint 2's phase, r = cos(phi2 + w2 T / 2) and where r was clamped to
    [-1, 1] (module docstring). theta2_s == theta2_e gives (pi - w2 T) / 2 and r = 0 exactly."""
    t_end = context.duration_s
    change = context.theta_end_rad[1] - context.theta_start_rad[1]
    if change == 0.0:
        return (np.pi - w2 * t_end) / 2.0, np.zeros_like(w2), np.zeros(np.shape(w2), dtype=bool)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):  # A2 sin(w2 T / 2) ~ 0: r = +-inf, clamped
        raw = change / (2.0 * a2 * np.sin(w2 * t_end / 2.0))
    clamped = ~(np.abs(raw) <= 1.0)
    r = np.clip(raw, -1.0, 1.0)
    return np.arccos(r) - w2 * t_end / 2.0, r, clamped


@dataclass(frozen=True)
class ExactEndpointsFamily(TrajectoryFamily):
    """Free (w1, phi1, A2, w2); A1, gamma1, phi2, gamma2 follow from P1, P5 and T."""

    name: ClassVar[str] = "exact-endpoints"
    free_parameter_names: ClassVar[tuple[str, ...]] = ("w1", "phi1", "A2", "w2")
    pins_endpoints: ClassVar[bool] = True
    uses_endpoint_context: ClassVar[bool] = True

    def expand(self, free: np.ndarray, context: EndpointContext | None) -> np.ndarray:
        context = _require(context)
        free = np.asarray(free, dtype=float)
        w1, phi1, a2, w2 = np.moveaxis(free, -1, 0)
        t_end = context.duration_s
        th_s, th_e = context.theta_start_rad, context.theta_end_rad
        denominator, _ = _denominator(w1, phi1, t_end)
        a1 = (th_e[0] - th_s[0]) / denominator
        gamma1 = th_s[0] - a1 * np.sin(phi1)
        phi2, _, _ = _joint2_phase(a2, w2, context)
        gamma2 = th_s[1] - a2 * np.sin(phi2)
        return np.stack([a1, w1, phi1, gamma1, a2, w2, phi2, gamma2], -1)

    def canonical_free(self, free: np.ndarray) -> np.ndarray:
        """(w1, phi1) get w1 >= 0 and phi1 in [-pi/2, pi/2) (A1 follows from them, so it flips
        by itself); w2 -> |w2|, since joint 2 moves as A2 sin(w2 (t - T/2) + arccos(r)) + const
        with r odd in w2 (arccos(-r) = pi - arccos(r)), which is even in w2 (for r = 0,
        A2 cos(w2 (t - T/2)) + const); A2 keeps its sign, which matters."""
        free = np.asarray(free, dtype=float)
        out = free.copy()
        ones, zeros = np.ones_like(free[..., 0]), np.zeros_like(free[..., 0])
        joint1 = np.stack([ones, free[..., 0], free[..., 1], zeros], -1)
        joint1 = canonicalize(np.concatenate([joint1, joint1], -1))[..., :4]
        out[..., 0], out[..., 1] = joint1[..., 1], joint1[..., 2]
        out[..., 3] = np.abs(free[..., 3])
        return out

    def expand_jacobians(self, free: np.ndarray, context: EndpointContext | None) -> tuple[np.ndarray, np.ndarray]:
        """Analytic derivatives of :meth:`expand` (where D or r is clamped, it is constant).

        phi2 = arccos(r) - w2 T / 2 is differentiated as such also where theta2_s == theta2_e
        (r = 0): its derivatives in theta2_s and theta2_e are then -+1 / (2 A2 sin(w2 T / 2)),
        which cancel along any change that keeps theta2_s = theta2_e. Where A2 sin(w2 T / 2) = 0,
        r is taken as constant."""
        context = _require(context)
        free = np.asarray(free, dtype=float)
        w1, phi1, a2, w2 = np.moveaxis(free, -1, 0)
        t_end = context.duration_s
        th_s, th_e = context.theta_start_rad, context.theta_end_rad
        denominator, clamped = _denominator(w1, phi1, t_end)
        live = ~clamped
        cos_end, cos_start = np.cos(w1 * t_end + phi1), np.cos(phi1)
        # dD/d(w1, phi1, T); zero where D is clamped.
        d_w1, d_phi1, d_t = (np.where(live, v, 0.0) for v in (cos_end * t_end, cos_end - cos_start, cos_end * w1))
        span = th_e[0] - th_s[0]
        a1 = span / denominator
        da1_dd = -span / denominator**2
        sin_phi1 = np.sin(phi1)
        phi2, r, clamped2 = _joint2_phase(a2, w2, context)
        sin_phi2, cos_phi2 = np.sin(phi2), np.cos(phi2)
        # d phi2 = -dr / sqrt(1 - r^2) - (T dw2 + w2 dT) / 2, r = (th2_e - th2_s) / (2 A2 sin(w2 T / 2)).
        half = w2 * t_end / 2.0
        scale = 2.0 * a2 * np.sin(half)
        live2 = ~clamped2 & (scale != 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            d_r = -1.0 / np.sqrt(1.0 - r * r)  # d arccos(r) / dr
            by_r = {  # d arccos(r) / d(A2, w2, T, th2_s, th2_e)
                "a2": d_r * (-r / a2),
                "w2": d_r * (-r / np.tan(half) * t_end / 2.0),
                "t": d_r * (-r / np.tan(half) * w2 / 2.0),
                "th2_s": d_r * (-1.0 / scale),
                "th2_e": d_r * (1.0 / scale),
            }
        by_r = {key: np.where(live2, value, 0.0) for key, value in by_r.items()}

        j_free = np.zeros((*w1.shape, 8, 4))
        j_ctx = np.zeros((*w1.shape, 8, 5))
        # A1 = span / D
        j_free[..., 0, 0] = da1_dd * d_w1
        j_free[..., 0, 1] = da1_dd * d_phi1
        j_ctx[..., 0, 0] = -1.0 / denominator
        j_ctx[..., 0, 2] = 1.0 / denominator
        j_ctx[..., 0, 4] = da1_dd * d_t
        # w1, phi1, A2, w2 are free.
        j_free[..., 1, 0] = 1.0
        j_free[..., 2, 1] = 1.0
        j_free[..., 4, 2] = 1.0
        j_free[..., 5, 3] = 1.0
        # gamma1 = theta1_s - A1 sin(phi1)
        j_free[..., 3, 0] = -sin_phi1 * j_free[..., 0, 0]
        j_free[..., 3, 1] = -sin_phi1 * j_free[..., 0, 1] - a1 * cos_start
        j_ctx[..., 3, :] = -sin_phi1[..., None] * j_ctx[..., 0, :]
        j_ctx[..., 3, 0] += 1.0
        # phi2 = arccos(r) - w2 T / 2
        j_free[..., 6, 2] = by_r["a2"]
        j_free[..., 6, 3] = by_r["w2"] - t_end / 2.0
        j_ctx[..., 6, 1] = by_r["th2_s"]
        j_ctx[..., 6, 3] = by_r["th2_e"]
        j_ctx[..., 6, 4] = by_r["t"] - w2 / 2.0
        # gamma2 = theta2_s - A2 sin(phi2)
        j_free[..., 7, 2] = -sin_phi2 - a2 * cos_phi2 * j_free[..., 6, 2]
        j_free[..., 7, 3] = -a2 * cos_phi2 * j_free[..., 6, 3]
        j_ctx[..., 7, :] = -(a2 * cos_phi2)[..., None] * j_ctx[..., 6, :]
        j_ctx[..., 7, 1] += 1.0
        return j_free, j_ctx

    def endpoints_exact(self, free: np.ndarray, context: EndpointContext | None) -> np.ndarray:
        """True where neither D nor r is clamped (then theta(0), theta(T) are the IK of P1, P5 up
        to rounding)."""
        context = _require(context)
        free = np.asarray(free, dtype=float)
        _, clamped = _denominator(free[..., 0], free[..., 1], context.duration_s)
        _, _, clamped2 = _joint2_phase(free[..., 2], free[..., 3], context)
        return ~(clamped | clamped2)


EXACT_ENDPOINTS = ExactEndpointsFamily()
