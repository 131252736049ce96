"""A PNG of one trajectory's joint angles, speeds, accelerations, torques and jerks against time, with
the arm's limits and the execution certificate's bounds drawn (matplotlib, Agg backend).

Every axis spans its curves, the certified bounds and the limits (each finite one is in view, however
far from the curves); an infinite limit or bound (none given, or a timing whose jerk is not bounded)
draws no line."""

from __future__ import annotations

import io
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np

from pipeline.io.jsonio import write_bytes_atomic
from pipeline.model.arm import PlanarArm
from pipeline.model.dynamics import rnea_torques

__all__ = ["axis_range", "plot_joint_states"]

_COLOURS = ("tab:blue", "tab:green")
#: Share of an axis's span left free above and below what it shows.
_PAD = 0.08


def _pairs(values, symmetric: bool) -> list[tuple[float, float]]:
    """Per joint (low, high) levels: ``values[j]`` itself for a (lo, hi) pair, else (-v, v)."""
    return [(-float(v), float(v)) if symmetric else (float(v[0]), float(v[1])) for v in values]


def axis_range(values: np.ndarray, levels: list[float]) -> tuple[float, float]:
    """The (bottom, top) of an axis that shows ``values`` and every finite level of ``levels`` (the
    bounds and limits drawn), padded by :data:`_PAD` of the span."""
    finite = [float(v) for v in np.ravel(values) if math.isfinite(v)] + [v for v in levels if math.isfinite(v)]
    low, high = (min(finite), max(finite)) if finite else (-1.0, 1.0)
    span = high - low
    pad = _PAD * span if span > 0.0 else max(abs(high), 1e-9)
    return low - pad, high + pad


def plot_joint_states(executed, arm: PlanarArm, execution, path: Path, *, samples: int = 2001, title: str = "") -> Path:
    """Draw q, dq, ddq, tau (Pinocchio's RNEA) and the jerk of ``executed`` (a timed trajectory) on
    ``samples`` instants, the limits of ``execution`` (dashed) and its certified bounds (dotted), each
    axis spanning all of them (:func:`axis_range`), and write the PNG atomically to ``path``."""
    t = np.linspace(0.0, executed.duration_s, samples)
    q, dq, ddq = executed.states(t)
    tau = rnea_torques(arm, q, dq, ddq)
    jerk = executed.jerk(t)
    certificate, limits = execution.certificate, execution.limits
    rows = (
        ("q [rad]", q, _pairs(certificate.angle_range_rad, False), _pairs(limits.position_rad, False)),
        ("dq [rad/s]", dq, _pairs(certificate.speed_bound_rad_s, True), _pairs(limits.velocity_rad_s, True)),
        (
            "ddq [rad/s²]",
            ddq,
            _pairs(certificate.acceleration_bound_rad_s2, True),
            _pairs(limits.acceleration_rad_s2, True),
        ),
        ("τ [N m]", tau, _pairs(certificate.torque_bound_n_m, True), _pairs(limits.effort_n_m, True)),
        ("jerk [rad/s³]", jerk, _pairs(certificate.jerk_bound_rad_s3, True), _pairs(limits.jerk_rad_s3, True)),
    )
    figure, axes = plt.subplots(len(rows), 1, figsize=(8, 12), sharex=True)
    for ax, (label, values, bounds, limit) in zip(axes, rows, strict=True):
        drawn: list[float] = []
        for joint in (0, 1):
            colour = _COLOURS[joint]
            ax.plot(t, values[:, joint], color=colour, label=f"joint {joint + 1}")
            for level in bounds[joint]:
                if math.isfinite(level):
                    ax.axhline(level, color=colour, linestyle=":", linewidth=1)
                    drawn.append(level)
            for level in limit[joint]:
                if math.isfinite(level):
                    ax.axhline(level, color=colour, linestyle="--", linewidth=1, alpha=0.6)
                    drawn.append(level)
        ax.set_ylim(*axis_range(values, drawn))
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel(f"t [s] ({certificate.timing_name} timing, T' = {executed.duration_s:.3f} s)")
    figure.suptitle(title or "joint states: dotted the certified bounds, dashed the limits")
    figure.tight_layout()
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=110)
    plt.close(figure)
    write_bytes_atomic(path, buffer.getvalue())
    return Path(path)
