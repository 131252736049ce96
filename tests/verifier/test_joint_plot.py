"""The joint plot (verify.acceptance.joint_plot): five rows (q, dq, ddq, tau, jerk), every axis spans
its curves, the certified bounds and every finite limit, and an infinite limit or bound draws no line."""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
import pytest

from pipeline import NEAR_OPTIMAL, generate_certified, load_coefficients
from pipeline.model.limits import ArmLimits
from pipeline.motion.timing import PAPER_TIMING
from pipeline.online.arm_check import arm_for
from verify.acceptance import joint_plot
from verify.acceptance.joint_plot import axis_range, plot_joint_states


def test_axis_range_takes_in_every_finite_level_and_ignores_infinite_ones() -> None:
    values = np.array([[0.1, -0.2], [0.3, 0.0]])
    low, high = axis_range(values, [-10.0, 10.0, math.inf, -math.inf])
    assert low < -10.0 and high > 10.0 and high - low <= 20.0 * (1 + 2 * joint_plot._PAD) + 1e-9
    low, high = axis_range(values, [math.inf])
    assert low < -0.2 and high > 0.3 and high < 1.0
    low, high = axis_range(np.zeros((3, 2)), [])
    assert low < 0.0 < high


def _figure(monkeypatch: pytest.MonkeyPatch, executed, arm, execution, path) -> plt.Figure:
    """Plot, keeping the figure that ``plot_joint_states`` closes."""
    kept = []
    monkeypatch.setattr(joint_plot.plt, "close", kept.append)
    plot_joint_states(executed, arm, execution, path, samples=301)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    return kept[0]


def _dashed(ax) -> list[float]:
    return [line.get_ydata()[0] for line in ax.get_lines() if line.get_linestyle() == "--"]


def _dotted(ax) -> list[float]:
    return [line.get_ydata()[0] for line in ax.get_lines() if line.get_linestyle() == ":"]


def test_every_finite_limit_is_in_view_and_the_jerk_row_shows_its_limit(monkeypatch, tmp_path) -> None:
    coefficients = load_coefficients("paper")
    arm = arm_for(coefficients)
    limits = ArmLimits.from_arm(arm, (5.0, 5.0)).with_servo_defaults()  # jerk 100 rad/s^3
    answer = generate_certified(coefficients, 0.25, 0.1, arm, timing=NEAR_OPTIMAL, limits=limits)
    figure = _figure(monkeypatch, answer.executed, arm, answer.execution, tmp_path / "near.png")
    axes = figure.axes
    assert [ax.get_ylabel() for ax in axes] == ["q [rad]", "dq [rad/s]", "ddq [rad/s²]", "τ [N m]", "jerk [rad/s³]"]
    expected = (
        [v for pair in limits.position_rad for v in pair],
        [s * v for v in limits.velocity_rad_s for s in (-1, 1)],
        [s * v for v in limits.acceleration_rad_s2 for s in (-1, 1)],
        [s * v for v in limits.effort_n_m for s in (-1, 1)],  # 10 N m, far above the torques
        [s * v for v in limits.jerk_rad_s3 for s in (-1, 1)],
    )
    for ax, levels in zip(axes, expected, strict=True):
        low, high = ax.get_ylim()
        assert sorted(_dashed(ax)) == sorted(levels)
        assert all(low < level < high for level in levels + _dotted(ax)), (ax.get_ylabel(), low, high)
    jerk_bound = answer.execution.certificate.jerk_bound_rad_s3
    assert np.all(np.isfinite(jerk_bound)) and sorted(_dotted(axes[-1])) == sorted(
        [s * v for v in jerk_bound for s in (-1, 1)]
    )
    plt.close(figure)


def test_infinite_limits_draw_no_line(monkeypatch, tmp_path) -> None:
    coefficients = load_coefficients("paper")
    arm = arm_for(coefficients)
    limits = ArmLimits.from_arm(arm)  # no acceleration or jerk limit
    answer = generate_certified(coefficients, 0.25, 0.1, arm, timing=PAPER_TIMING, limits=limits)
    figure = _figure(monkeypatch, answer.executed, arm, answer.execution, tmp_path / "paper.png")
    ddq_axis, jerk_axis = figure.axes[2], figure.axes[4]
    assert _dashed(ddq_axis) == [] and _dashed(jerk_axis) == []
    assert len(_dashed(figure.axes[1])) == 4  # the URDF's speed limits
    if not np.all(np.isfinite(answer.execution.certificate.jerk_bound_rad_s3)):
        assert _dotted(jerk_axis) == []
    low, high = jerk_axis.get_ylim()
    assert math.isfinite(low) and math.isfinite(high)
    plt.close(figure)
