"""A PNG of one trajectory's joint angles, speeds, accelerations and torques against time, with the
arm's limits and the execution certificate's bounds drawn (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np

from pipeline.io.jsonio import write_bytes_atomic
from pipeline.model.arm import PlanarArm
from pipeline.model.dynamics import rnea_torques

__all__ = ["plot_joint_states"]

_COLOURS = ("tab:blue", "tab:green")


def plot_joint_states(executed, arm: PlanarArm, execution, path: Path, *, samples: int = 2001, title: str = "") -> Path:
    """Draw q, dq, ddq and tau (Pinocchio's RNEA) of ``executed`` (a timed trajectory) on
    ``samples`` instants, the limits of ``execution`` (dashed) and its certified bounds (dotted),
    and write the PNG atomically to ``path``."""
    t = np.linspace(0.0, executed.duration_s, samples)
    q, dq, ddq = executed.states(t)
    tau = rnea_torques(arm, q, dq, ddq)
    certificate, limits = execution.certificate, execution.limits
    rows = (
        ("q [rad]", q, [b for b in certificate.angle_range_rad], [lim for lim in limits.position_rad]),
        ("dq [rad/s]", dq, certificate.speed_bound_rad_s, limits.velocity_rad_s),
        ("ddq [rad/s²]", ddq, certificate.acceleration_bound_rad_s2, limits.acceleration_rad_s2),
        ("τ [N m]", tau, certificate.torque_bound_n_m, limits.effort_n_m),
    )
    figure, axes = plt.subplots(4, 1, figsize=(8, 10), sharex=True)
    for ax, (label, values, bounds, limit) in zip(axes, rows, strict=True):
        for joint in (0, 1):
            colour = _COLOURS[joint]
            ax.plot(t, values[:, joint], color=colour, label=f"joint {joint + 1}")
            if label.startswith("q "):
                low, high = bounds[joint]
                limit_low, limit_high = limit[joint]
                levels, limit_levels = (low, high), (limit_low, limit_high)
            else:
                levels, limit_levels = (-bounds[joint], bounds[joint]), (-limit[joint], limit[joint])
            for level in levels:
                ax.axhline(level, color=colour, linestyle=":", linewidth=1)
            for level in limit_levels:
                if np.isfinite(level):
                    ax.axhline(level, color=colour, linestyle="--", linewidth=1, alpha=0.6)
        spread = max(float(np.abs(values).max()), 1e-9)
        ax.set_ylim(-1.3 * spread if not label.startswith("q ") else values.min() - 0.3 * spread, 1.3 * spread)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel(f"t [s] ({certificate.timing_name} timing, T' = {executed.duration_s:.3f} s)")
    figure.suptitle(title or "joint states: dotted the certified bounds, dashed the limits (where in view)")
    figure.tight_layout()
    import io

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=110)
    plt.close(figure)
    write_bytes_atomic(path, buffer.getvalue())
    return Path(path)
