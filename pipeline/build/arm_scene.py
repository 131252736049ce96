"""The obstacle's far edge d for a build's own arm: :func:`scene_for_arm` (a
:class:`pipeline.build.config.BuildConfig` -> the same with d chosen, and a note saying so).

The paper's d = 0.56 m suits the paper's arm; for another arm the build's pre-checks refuse it
as a rule (P1 out of reach, or the end poses inside the obstacle). :func:`window_for_build`
asks :func:`pipeline.offline.scene_window.scene_window` for the window of d over the build's
own range (L, W and, when the build varies it, x, on the same grids as its pre-check), and
:func:`scene_for_arm` puts the recommended value into the configuration and runs the build's
own pre-check (``pipeline.build.doe_fit.check_before_work``) on the result, so a
configuration it returns passes it. ``python -m pipeline.build --urdf FILE`` without
``--top-y`` or ``--scene`` calls it; ``python -m pipeline.scene`` prints the window.
"""

from __future__ import annotations

import math
from dataclasses import replace

from pipeline.build.config import BuildConfig
from pipeline.build.doe_fit import EXTRA_GRID_POINTS, check_before_work
from pipeline.exceptions import InvalidParameterError
from pipeline.model.arm import PlanarArm
from pipeline.offline.convergence import GRID_POINTS
from pipeline.offline.scene_window import SceneWindow, WindowSettings, scene_window

__all__ = ["config_at", "d_range_for_arm", "scene_for_arm", "window_for_build", "window_note"]


def _x_range(config: BuildConfig) -> tuple[float, float] | None:
    """The range of the obstacle's centre x the build varies [m], or None."""
    ranges = config.design.scaled_design().ranges_m
    return tuple(ranges["x"]) if "x" in ranges else None


def window_for_build(
    arm: PlanarArm, config: BuildConfig, shrink: bool = True, end_pose_clearance_m: float | None = None
) -> SceneWindow:
    """The window of d [m] over ``config``'s range for ``arm`` (its scene, family and objective
    settings; the pre-check's grids).

    Args:
        arm: The arm.
        config: The build; its scene's d is ignored.
        shrink: Try shrunk L, then W ranges when no d fits the build's.
        end_pose_clearance_m: Clearance the end poses keep [m]; None: the scene's margin.

    Raises:
        InvalidParameterError: the build varies d itself (``--vary d``): no single d to choose.
        NoSceneWindowError: no d fits (nor a shrunk range, with ``shrink``).
    """
    if "d" in config.variables.names:
        raise InvalidParameterError("--vary", "d", "no d among the varied variables to choose a single d")
    settings = WindowSettings(
        end_pose_clearance_m=end_pose_clearance_m,
        grid_points=GRID_POINTS,
        centre_x_points=EXTRA_GRID_POINTS,
        shrink=shrink,
    )
    return scene_window(
        arm,
        config.scene,
        config.design.length_range_m,
        config.design.width_range_m,
        _x_range(config),
        fitness=config.solver().fitness,
        family=config.family,
        settings=settings,
    )


def config_at(config: BuildConfig, window: SceneWindow) -> BuildConfig:
    """``config`` with the window's recommended d and the (L, W) range it holds over."""
    return config.with_settings(
        scene=replace(config.scene, top_y_m=window.recommended_m),
        length_range_m=window.length_range_m,
        width_range_m=window.width_range_m,
    )


def window_note(window: SceneWindow) -> str:
    """One line: the d chosen, the window and, if shrunk, the range it holds over."""
    note = (
        f"--top-y {window.recommended_m:.3f} chosen for this arm: the middle of the window "
        f"[{window.low_m:.4f}, {window.high_m:.4f}] m of d (python -m pipeline.scene explains it)"
    )
    if window.shrunk:
        (l0, l1), (w0, w1) = window.length_range_m, window.width_range_m
        why = "no d fits the range asked for" if window.requested_window_m is None else "its window is narrower"
        note += f"; {why}, so the range is shrunk to L {l0:.3f} {l1:.3f}, W {w0:.3f} {w1:.3f} [m]"
    if window.narrow:
        note += f"; caution: the window is only {window.width_m * 1e3:.1f} mm wide, the build may not converge"
    return note


def scene_for_arm(arm: PlanarArm, config: BuildConfig, shrink: bool = True) -> tuple[BuildConfig, str]:
    """``config`` with the recommended d of :func:`window_for_build` (and its shrunk range, if
    it had to shrink), checked by the build's own pre-check, and a one-line note saying so.

    Raises:
        InvalidParameterError: the build varies d itself.
        NoSceneWindowError: no d fits (the message names the constraints that close the window).
        UnreachableObstacleError, InfeasibleSceneError: the build's pre-check refuses the
            chosen configuration (not expected: the window holds on the same grids).
    """
    window = window_for_build(arm, config, shrink)
    chosen = config_at(config, window)
    check_before_work(chosen, arm)
    return chosen, window_note(window)


def d_range_for_arm(arm: PlanarArm, config: BuildConfig) -> tuple[BuildConfig, str]:
    """``config`` varying d over the window of :func:`window_for_build` (``--vary d`` without a
    range): every obstacle of its (L, W) and x range, at every d of it, has P1..P5 in the arm's
    reach and end poses that keep the margin, so the range is the arm's own. Its edges are the
    window's, rounded inwards to 0.1 mm. Returns the configuration and a one-line note.

    Raises:
        InvalidParameterError: ``config`` varies d already.
        NoSceneWindowError: no d fits the range (the message names the constraints); the range is
            not shrunk.
    """
    window = window_for_build(arm, config, shrink=False)
    low, high = math.ceil(window.low_m * 1e4) / 1e4, math.floor(window.high_m * 1e4) / 1e4
    if not low < high:
        low, high = window.low_m, window.high_m
    chosen = config.with_settings(vary=(*config.design.vary, ("d", low, high)))
    note = (
        f"--vary d {low:.4f} {high:.4f} chosen for this arm: the window of d where every obstacle of the range "
        "is in reach and its end poses keep the margin (python -m pipeline.scene explains its edges)"
    )
    return chosen, note
