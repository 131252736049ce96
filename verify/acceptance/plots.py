"""PNG plots of a sweep (matplotlib, Agg backend): clearance and endpoint error over the (L, W)
plane, the paper's four case studies redone like its Fig. 5 (arm snapshots, obstacle,
desired and actual end-effector paths), and the region map (the range certificate's leaves
coloured by status, shaded by their clearance bound, with the sampled cases over it). A sweep
over more variables than (L, W) (the obstacle's centre x) is also drawn in slices of x: the
map over (L, W) at a few values of x, and the sampled clearance of the cases near each. All
lengths are converted to mm only for display; every file is written atomically.
"""

from __future__ import annotations

import io
import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.cm import ScalarMappable
from matplotlib.collections import PathCollection, PolyCollection
from matplotlib.colors import LinearSegmentedColormap, Normalize, TwoSlopeNorm
from matplotlib.patches import FancyBboxPatch, Patch, Rectangle

from pipeline import load_coefficients
from pipeline.certify.region_map import STATUSES, RegionMap
from pipeline.exceptions import PipelineError
from pipeline.geometry.clearance import link_segments
from pipeline.io.jsonio import write_bytes_atomic
from pipeline.model.arm import PlanarArm, load_planar_arm
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import QuarticPath
from pipeline.motion.trajectory import JointTrajectory
from pipeline.online.generator import generate

from .cases import DOE_L_M, DOE_W_M, SweepRange
from .map_leaves import STATUS_SHADES, leaf_drawing, leaves_in_slice
from .results import CaseResult

if TYPE_CHECKING:  # pragma: no cover
    from .run import SweepRun

_DPI = 120
#: Where a slices figure cuts the first extra variable's range, as fractions (lo, mid, hi).
SLICE_FRACTIONS = (0.0, 0.5, 1.0)


def save_figure(fig: plt.Figure, path: Path) -> Path:
    """Write ``fig`` as a PNG to ``path`` atomically (temporary file and rename), then close it."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=_DPI)
    plt.close(fig)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(path, buffer.getvalue())
    return path


@dataclass(frozen=True)
class CaseStudy:
    """One case study: its measured result and what is needed to draw it.

    Attributes:
        result: The measured case.
        trajectory: The generated joint trajectory.
        path: The desired path.
        obstacle: The obstacle.
    """

    result: CaseResult
    trajectory: JointTrajectory
    path: QuarticPath
    obstacle: Obstacle


def _range_box(ax: plt.Axes, fitted: SweepRange) -> None:
    ax.add_patch(
        Rectangle(
            (fitted.L_m[0] * 1e3, fitted.W_m[0] * 1e3),
            (fitted.L_m[1] - fitted.L_m[0]) * 1e3,
            (fitted.W_m[1] - fitted.W_m[0]) * 1e3,
            fill=False,
            linestyle="--",
            edgecolor="0.3",
            label="fitted range",
        )
    )


def plot_map(
    cases: Sequence[CaseResult],
    value: Callable[[CaseResult], float | None],
    path: Path,
    *,
    title: str,
    colorbar_label: str,
    fitted: SweepRange | None = None,
    center_mm: float | None = None,
    doe_grid: tuple[Sequence[float], Sequence[float]] | None = None,
    case_studies: Sequence[CaseResult] = (),
    cmap: str = "viridis",
) -> Path:
    """Scatter of a per-case value [m] (shown in mm) over the (L, W) plane; failing cases ringed red.

    Args:
        cases: The sweep's cases.
        value: Which number to colour by [m] (None: the case has no value, drawn as a grey cross).
        path: PNG file to write.
        title, colorbar_label: Texts.
        fitted: The fitted range, drawn as a dashed rectangle.
        center_mm: If given, a diverging colour scale centred on this value [mm].
        doe_grid: (L levels, W levels) [m] of the DOE grid, drawn as black plus signs.
        case_studies: Case studies, drawn as stars.
        cmap: Matplotlib colour map.
    """
    fig, ax = plt.subplots(figsize=(7.0, 5.2))
    good = [c for c in cases if value(c) is not None]
    missing = [c for c in cases if value(c) is None]
    if good:
        lw = np.array([[c.L_m, c.W_m] for c in good]) * 1e3
        values = np.array([value(c) for c in good]) * 1e3
        lo, hi = float(values.min()), float(values.max())
        if center_mm is not None and lo < center_mm < hi:
            norm: Normalize = TwoSlopeNorm(vcenter=center_mm, vmin=lo, vmax=hi)
        else:
            norm = Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1e-9)
        points = ax.scatter(lw[:, 0], lw[:, 1], c=values, cmap=cmap, norm=norm, s=14, linewidths=0)
        fig.colorbar(points, ax=ax, label=colorbar_label)
        failing = np.array([not c.passed for c in good])
        if np.any(failing):
            ax.scatter(
                lw[failing, 0],
                lw[failing, 1],
                s=40,
                facecolors="none",
                edgecolors="red",
                linewidths=0.8,
                label=f"failing ({int(failing.sum())})",
            )
    if missing:
        m = np.array([[c.L_m, c.W_m] for c in missing]) * 1e3
        ax.scatter(m[:, 0], m[:, 1], marker="x", color="0.5", s=20, label=f"not generated ({len(missing)})")
    if fitted is not None:
        _range_box(ax, fitted)
    if doe_grid is not None:
        grid = np.array([[a, b] for a in doe_grid[0] for b in doe_grid[1]]) * 1e3
        ax.scatter(grid[:, 0], grid[:, 1], marker="+", color="black", s=60, label="DOE grid")
    if case_studies:
        cs = np.array([[c.L_m, c.W_m] for c in case_studies]) * 1e3
        ax.scatter(cs[:, 0], cs[:, 1], marker="*", color="magenta", s=90, edgecolors="black", label="case studies")
    ax.set_xlabel("obstacle length L [mm]")
    ax.set_ylabel("obstacle width W [mm]")
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=8, framealpha=0.8)
    fig.tight_layout()
    return save_figure(fig, path)


def _status_colorbars(
    fig: plt.Figure, slots: Sequence[plt.Axes], ranges: dict[str, tuple[float, float] | None]
) -> None:
    """One horizontal colour bar per status present, in ``slots``: its shade against its
    clearance bound [mm]; unused slots are hidden."""
    present = [name for name in STATUSES if ranges.get(name) is not None]
    for slot, name in zip(slots, present, strict=False):
        lo, hi = (v * 1e3 for v in ranges[name])
        cmap = LinearSegmentedColormap.from_list(name, list(STATUS_SHADES[name]))
        bar = fig.colorbar(
            ScalarMappable(Normalize(lo, hi if hi > lo else lo + 1e-9), cmap), cax=slot, orientation="horizontal"
        )
        bar.ax.set_title(f"{name.replace('_', '-')}: clearance bound [mm]", fontsize=8)
        bar.ax.tick_params(labelsize=7)
    for slot in slots[len(present) :]:
        slot.axis("off")


#: The map's zoom panel is drawn when the leaves below the margin fit in this fraction of the area.
ZOOM_AREA_FRACTION = 0.3


def _map_figure(bars: int, zoom: bool) -> tuple[plt.Figure, list[plt.Axes], plt.Axes, list[plt.Axes]]:
    """The map's figure: the (L, W) axes on the left (and a zoom panel under them if ``zoom``);
    on the right a legend panel above ``bars`` colour-bar slots."""
    fig = plt.figure(figsize=(10.5, 8.0 if zoom else 5.6))
    outer = fig.add_gridspec(1, 2, width_ratios=(3.2, 1.0), wspace=0.1)
    left = outer[0].subgridspec(2, 1, height_ratios=(4.0, 2.2), hspace=0.3) if zoom else None
    axes = [fig.add_subplot(left[0]), fig.add_subplot(left[1])] if left is not None else [fig.add_subplot(outer[0])]
    right = outer[1].subgridspec(2 * bars + 1, 1, height_ratios=(4.0, *([0.35, 1.0] * bars)))
    legend_panel = fig.add_subplot(right[0])
    legend_panel.axis("off")
    slots = [fig.add_subplot(right[2 * k + 1]) for k in range(bars)]
    return fig, axes, legend_panel, slots


def _zoom_box_mm(region_map: RegionMap, rectangles_mm: np.ndarray) -> tuple[float, float, float, float] | None:
    """(L lo, L hi, W lo, W hi) [mm] around the leaves not certified to keep the margin, padded by
    a tenth of its size, if that box covers at most :data:`ZOOM_AREA_FRACTION` of the range."""
    below = region_map.status != STATUSES.index("margin")
    if not below.any():
        return None
    r = rectangles_mm[below]
    box = np.array([r[:, 0].min(), r[:, 1].max(), r[:, 2].min(), r[:, 3].max()])
    full = np.array([*region_map.range_of("L"), *region_map.range_of("W")]) * 1e3
    if (box[1] - box[0]) * (box[3] - box[2]) > ZOOM_AREA_FRACTION * (full[1] - full[0]) * (full[3] - full[2]):
        return None
    pad_l, pad_w = 0.1 * (box[1] - box[0]), 0.1 * (box[3] - box[2])
    box += [-pad_l, pad_l, -pad_w, pad_w]
    return (max(box[0], full[0]), min(box[1], full[1]), max(box[2], full[2]), min(box[3], full[3]))


def _draw_leaves_and_cases(
    ax: plt.Axes, region_map: RegionMap, quads_mm: np.ndarray, rgb: np.ndarray, cases_mm: np.ndarray, bad_mm: np.ndarray
) -> list:
    """Leaves, cases, contradicting cases and the worst leaf on ``ax``; returns the legend handles."""
    ax.add_collection(PolyCollection(quads_mm, facecolors=rgb, edgecolors="face", linewidths=0.2))
    handles = [ax.scatter(cases_mm[:, 0], cases_mm[:, 1], s=4, color="black", linewidths=0)]
    handles[0].set_label(f"sampled cases ({len(cases_mm)})")
    if len(bad_mm):
        handles.append(ax.scatter(bad_mm[:, 0], bad_mm[:, 1], marker="x", s=50, color="red"))
        handles[-1].set_label(f"contradict the map ({len(bad_mm)})")
    worst = region_map.cell(int(np.argmin(region_map.clearance_bound_m)))
    (l0, l1), (w0, w1) = np.array(worst.range_of("L")) * 1e3, np.array(worst.range_of("W")) * 1e3
    handles.append(ax.add_patch(Rectangle((l0, w0), l1 - l0, w1 - w0, fill=False, edgecolor="magenta", linewidth=2.0)))
    handles[-1].set_label(f"worst cell ({worst.clearance_bound_m * 1e3:.2f} mm)")
    ax.annotate(
        f"worst cell: clearance bound {worst.clearance_bound_m * 1e3:.2f} mm",
        xy=((l0 + l1) / 2, (w0 + w1) / 2),
        xytext=(0.3, 0.55),
        textcoords="axes fraction",
        fontsize=8,
        ha="center",
        bbox={"boxstyle": "round", "facecolor": "white", "alpha": 0.85},
        arrowprops={"arrowstyle": "->", "color": "magenta", "lw": 1.5},
    )
    ax.set_xlabel("obstacle length L [mm]")
    ax.set_ylabel("obstacle width W [mm]")
    return handles


def plot_region_map(
    region_map: RegionMap,
    cases: Sequence[CaseResult],
    path: Path,
    *,
    title: str,
    violations: Sequence[int] = (),
) -> Path:
    """The region map over (L, W) [shown in mm]: each leaf a rectangle coloured by its status and
    shaded by its clearance bound (:mod:`verify.acceptance.map_leaves`), the sampled cases as
    dots, the cases that contradict the map (``violations``: case indices) as red crosses, and
    the leaf of smallest clearance bound outlined; the legend gives each status's area fraction.
    If the leaves below the margin lie in a small part of the range, a second panel zooms on them."""
    drawing = leaf_drawing(region_map)
    r = drawing.rectangles_m * 1e3
    quads = np.stack([r[:, [0, 2]], r[:, [1, 2]], r[:, [1, 3]], r[:, [0, 3]]], axis=1)
    zoom = _zoom_box_mm(region_map, r)
    bars = sum(v is not None for v in drawing.bound_range_m.values())
    fig, axes, legend_panel, slots = _map_figure(bars, zoom is not None)
    cases_mm = np.array([[c.L_m, c.W_m] for c in cases]).reshape(-1, 2) * 1e3
    bad = set(violations)
    bad_mm = np.array([[c.L_m, c.W_m] for c in cases if c.index in bad]).reshape(-1, 2) * 1e3
    for ax in axes:
        handles = _draw_leaves_and_cases(ax, region_map, quads, drawing.rgb, cases_mm, bad_mm)
    full = np.array([*region_map.range_of("L"), *region_map.range_of("W")]) * 1e3
    axes[0].set_xlim(full[0], full[1])
    axes[0].set_ylim(full[2], full[3])
    axes[0].set_title(title, fontsize=10)
    if zoom is not None:
        axes[1].set_xlim(zoom[0], zoom[1])
        axes[1].set_ylim(zoom[2], zoom[3])
        axes[1].set_title("zoom on the leaves not certified to keep the margin", fontsize=9)
        axes[0].add_patch(
            Rectangle((zoom[0], zoom[2]), zoom[1] - zoom[0], zoom[3] - zoom[2], fill=False, ls="--", ec="white", lw=1.2)
        )
    area = region_map.area
    statuses = [
        Patch(
            color=STATUS_SHADES[name][0],
            label=f"{name.replace('_', '-')}: {100 * area[region_map.status == k].sum():.2f} %",
        )
        for k, name in enumerate(STATUSES)
    ]
    legend_panel.legend(
        handles=statuses + handles, loc="upper left", fontsize=8, title="area of the fitted range", title_fontsize=8
    )
    _status_colorbars(fig, slots, drawing.bound_range_m)
    fig.subplots_adjust(left=0.07, right=0.97, top=0.95, bottom=0.07)
    return save_figure(fig, path)


def slice_values(sweep_range: SweepRange) -> tuple[float, ...]:
    """The values [m] of the first extra variable of ``sweep_range`` at which a slices figure
    cuts it (:data:`SLICE_FRACTIONS` of its range: lo, mid, hi)."""
    _, (lo, hi) = sweep_range.extra_m[0]
    return tuple(lo + f * (hi - lo) for f in SLICE_FRACTIONS)


def _slabs(values: Sequence[float], lo: float, hi: float) -> list[tuple[float, float]]:
    """Around each slice value, the part of [lo, hi] nearer to it than to its neighbours [m]."""
    cuts = [lo, *(0.5 * (a + b) for a, b in itertools.pairwise(values)), hi]
    return list(itertools.pairwise(cuts))


def _draw_slice_leaves(ax: plt.Axes, region_map: RegionMap, rgb: np.ndarray, at: tuple[float, ...]) -> dict:
    """The leaves of ``region_map`` at the extra axes' values ``at`` [m] on ``ax`` (L, W in mm);
    returns the area fraction of the slice per status."""
    drawing = leaf_drawing(region_map)
    keep = leaves_in_slice(region_map, at)
    r = drawing.rectangles_m[keep] * 1e3
    quads = np.stack([r[:, [0, 2]], r[:, [1, 2]], r[:, [1, 3]], r[:, [0, 3]]], axis=1)
    ax.add_collection(PolyCollection(quads, facecolors=rgb[keep], edgecolors="face", linewidths=0.2))
    area = (r[:, 1] - r[:, 0]) * (r[:, 3] - r[:, 2])
    total = float(area.sum()) or 1.0
    status = region_map.status[keep]
    return {name: float(area[status == k].sum()) / total for k, name in enumerate(STATUSES)}


def plot_slices(
    cases: Sequence[CaseResult],
    sweep_range: SweepRange,
    path: Path,
    *,
    title: str,
    margin_m: float,
    region_map: RegionMap | None = None,
    violations: Sequence[int] = (),
) -> Path:
    """A sweep over (L, W) and more variables, in slices of the first extra one (x): one column
    per value of :func:`slice_values` (lo, mid, hi of its range). Top row, if ``region_map`` is
    given: the map's leaves at that value over (L, W) [mm], coloured by status and shaded by
    clearance bound as in :func:`plot_region_map` (the other extra axes at their range's
    midpoint), with the sampled cases of the slab nearest that value as dots. Bottom row: the
    sampled (Coal) clearance [mm] of those cases over (L, W), on one scale centred on
    ``margin_m`` [m]; cases not generated as grey crosses. The cases that contradict the map
    (``violations``: case indices) are red crosses in both rows."""
    name, (lo, hi) = sweep_range.extra_m[0]
    values = slice_values(sweep_range)
    slabs = _slabs(values, lo, hi)
    others = tuple(0.5 * (a + b) for _, (a, b) in sweep_range.extra_m[1:])
    rows = 2 if region_map is not None else 1
    fig, axes = plt.subplots(rows, len(values), figsize=(4.6 * len(values), 4.2 * rows + 0.9), squeeze=False)
    bad = set(violations)
    value_of = np.array([c.extra_values.get(name, np.nan) for c in cases], dtype=float)
    lw_mm = np.array([[c.L_m, c.W_m] for c in cases], dtype=float).reshape(-1, 2) * 1e3
    clearance = np.array([np.nan if c.clearance_m is None else c.clearance_m for c in cases], dtype=float) * 1e3
    centre = margin_m * 1e3
    norm = _clearance_norm(clearance, centre)
    rgb = leaf_drawing(region_map).rgb if region_map is not None else None
    full = np.array([*sweep_range.L_m, *sweep_range.W_m]) * 1e3
    points = None
    for j, (value, (a, b)) in enumerate(zip(values, slabs, strict=True)):
        last = j == len(values) - 1
        near = (value_of >= a) & ((value_of <= b) if last else (value_of < b))
        wrong = np.array([c.index in bad for c in cases], dtype=bool) & near
        if region_map is not None and rgb is not None:
            label = f"{name} = {value * 1e3:.1f} mm"
            _draw_map_slice(axes[0, j], region_map, rgb, (value, *others), lw_mm[near], label)
        slab = f"{name} in [{a * 1e3:.1f}, {b * 1e3:.1f}] mm"
        points = _draw_clearance_slice(axes[rows - 1, j], lw_mm, clearance, near, norm, slab)
        for row in range(rows):
            _finish_slice_axis(axes[row, j], lw_mm[wrong], full)
    fig.suptitle(title, fontsize=10)
    fig.subplots_adjust(
        left=0.06, right=0.9, top=0.9, bottom=0.16 if region_map is not None else 0.12, hspace=0.35, wspace=0.28
    )
    _slice_keys(fig, axes[rows - 1, -1], points, centre, region_map is not None)
    return save_figure(fig, path)


def _clearance_norm(clearance_mm: np.ndarray, centre_mm: float) -> Normalize:
    """The colour scale of the sampled clearances [mm]: centred on ``centre_mm`` (the margin) when it
    lies between their least and largest finite values, else plainly over their range."""
    finite = clearance_mm[np.isfinite(clearance_mm)]
    if finite.size and finite.min() < centre_mm < finite.max():
        return TwoSlopeNorm(vcenter=centre_mm, vmin=float(finite.min()), vmax=float(finite.max()))
    top = float(finite.max()) if finite.size else 1.0
    low = float(finite.min()) if finite.size else 0.0
    return Normalize(vmin=low, vmax=top if top > low else low + 1e-9)


def _draw_map_slice(
    ax: plt.Axes, region_map: RegionMap, rgb: np.ndarray, at: tuple[float, ...], shown_mm: np.ndarray, label: str
) -> None:
    """One top-row panel of :func:`plot_slices`: the map's leaves at the extra axes' values ``at`` [m],
    the slab's cases (L, W) [mm] as dots, and the statuses' area fractions in the title."""
    fractions = _draw_slice_leaves(ax, region_map, rgb, at)
    ax.scatter(shown_mm[:, 0], shown_mm[:, 1], s=3, color="black", linewidths=0)
    text = ", ".join(f"{k.replace('_', '-')} {100 * v:.1f} %" for k, v in fractions.items() if v > 0)
    ax.set_title(f"map at {label}\n{text}", fontsize=8)


def _draw_clearance_slice(
    ax: plt.Axes, lw_mm: np.ndarray, clearance_mm: np.ndarray, near: np.ndarray, norm: Normalize, slab: str
) -> PathCollection:
    """One bottom-row panel of :func:`plot_slices`: the sampled clearance [mm] of the cases ``near``
    the slice over (L, W) [mm], the cases not generated as grey crosses; returns the coloured dots."""
    ok = near & np.isfinite(clearance_mm)
    points = ax.scatter(lw_mm[ok, 0], lw_mm[ok, 1], c=clearance_mm[ok], cmap="RdYlGn", norm=norm, s=10, linewidths=0)
    missing = near & ~np.isfinite(clearance_mm)
    if missing.any():
        ax.scatter(lw_mm[missing, 0], lw_mm[missing, 1], marker="x", color="0.5", s=20, label="not generated")
    ax.set_title(f"sampled clearance, {int(near.sum())} cases with {slab}", fontsize=8)
    return points


def _finish_slice_axis(axis: plt.Axes, wrong_mm: np.ndarray, full_mm: np.ndarray) -> None:
    """A panel of :func:`plot_slices` finished: the cases that contradict the map (L, W) [mm] as red
    crosses, the swept (L, W) box ``full_mm`` (L lo, L hi, W lo, W hi) [mm] as limits, axis labels."""
    if wrong_mm.shape[0]:
        axis.scatter(wrong_mm[:, 0], wrong_mm[:, 1], marker="x", s=50, color="red", label="contradict the map")
    axis.set_xlim(full_mm[0], full_mm[1])
    axis.set_ylim(full_mm[2], full_mm[3])
    axis.set_xlabel("obstacle length L [mm]")
    axis.set_ylabel("obstacle width W [mm]")


def _slice_keys(
    fig: plt.Figure, corner: plt.Axes, points: PathCollection | None, centre_mm: float, with_map: bool
) -> None:
    """The keys of :func:`plot_slices`: the clearance scale beside the bottom row's last panel
    ``corner`` (centred on the ``centre_mm`` margin [mm]) and, ``with_map``, the map statuses' legend."""
    if points is not None:  # the clearance scale beside the bottom row
        box = corner.get_position()
        bar = fig.add_axes((box.x1 + 0.015, box.y0, 0.012, box.height))
        fig.colorbar(points, cax=bar, label=f"sampled clearance [mm] (centre: {centre_mm:g} mm margin)")
    if with_map:
        statuses = [Patch(color=STATUS_SHADES[k][0], label=k.replace("_", "-")) for k in STATUSES]
        fig.legend(
            handles=statuses,
            loc="lower center",
            ncol=len(statuses),
            fontsize=8,
            title="map status (darker = smaller clearance bound)",
            title_fontsize=8,
        )


def draw_case_study(ax: plt.Axes, study: CaseStudy, arm: PlanarArm, *, snapshots: int = 7, title: str = "") -> None:
    """Draw one case like the paper's Fig. 5: obstacle, desired and actual paths, arm snapshots."""
    obstacle, trajectory = study.obstacle, study.trajectory
    r = obstacle.corner_radius_m
    x0, y0 = -obstacle.length_m / 2, obstacle.top_y_m - obstacle.width_m
    ax.add_patch(
        FancyBboxPatch(
            (x0 + r, y0 + r),
            obstacle.length_m - 2 * r,
            obstacle.width_m - 2 * r,
            boxstyle=f"round,pad={r}",
            facecolor="0.75",
            edgecolor="0.2",
            label="obstacle",
        )
    )
    times = np.linspace(0.0, trajectory.duration_s, 400)
    desired = study.path.position_at_time(times)
    actual = arm.end_effector_planar(trajectory.q(times))
    for k, t in enumerate(np.linspace(0.0, trajectory.duration_s, snapshots)):
        elbow, tip = link_segments(trajectory.q(float(t)), arm.link_lengths_m)
        alpha = 0.25 + 0.75 * k / max(1, snapshots - 1)
        ax.plot([0, elbow[0]], [0, elbow[1]], color="tab:blue", lw=2.2, alpha=alpha, solid_capstyle="round")
        ax.plot([elbow[0], tip[0]], [elbow[1], tip[1]], color="tab:green", lw=2.2, alpha=alpha, solid_capstyle="round")
        ax.plot(*elbow, "o", color="black", ms=2.5, alpha=alpha)
    ax.plot(desired[:, 0], desired[:, 1], "--", color="black", lw=1.2, label="desired path")
    ax.plot(actual[:, 0], actual[:, 1], "-", color="tab:red", lw=1.2, label="actual path")
    points = study.path.points_m
    ax.plot(points[:, 0], points[:, 1], "s", color="black", ms=3.5, label="P1..P5")
    ax.plot(0.0, 0.0, "^", color="black", ms=6)
    ax.set_aspect("equal")
    ax.set_xlim(points[:, 0].min() - 0.12, points[:, 0].max() + 0.12)
    ax.set_ylim(-0.05, obstacle.top_y_m + 0.08)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize=9)
    ax.grid(True, lw=0.3)


def plot_case_studies(studies: Sequence[CaseStudy], arm: PlanarArm, path: Path, *, suptitle: str = "") -> Path:
    """The four case studies in a 2 x 2 figure (the paper's Fig. 5 redone)."""
    cols = 2
    rows = max(1, (len(studies) + cols - 1) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(11.0, 4.8 * rows), squeeze=False)
    for ax, (k, study) in zip(axes.ravel(), enumerate(studies), strict=False):
        res = study.result
        verdict = "PASS" if res.passed else "FAIL"
        title = (
            f"case {k + 1}: L = {res.L_m:.3f} m, W = {res.W_m:.3f} m (off the DOE grid) - {verdict}\n"
            f"certified clearance {_mm(res.certified_clearance_m)}, endpoint error {_mm(res.endpoint_error_m)}, "
            f"tracking max {_mm(res.tracking_max_m)}"
        )
        draw_case_study(ax, study, arm, title=title)
    for ax in axes.ravel()[len(studies) :]:
        ax.axis("off")
    handles, labels = axes.ravel()[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8)
    if suptitle:
        fig.suptitle(suptitle)
    fig.tight_layout(rect=(0, 0.04, 1, 0.97))
    return save_figure(fig, path)


def _mm(value: float | None) -> str:
    return "n/a" if value is None else f"{value * 1e3:.2f} mm"


def write_plots(run: SweepRun, directory: Path, *, urdf_path: str | None = None) -> list[Path]:
    """Write clearance_map.png, endpoint_error_map.png, case_studies.png and, if the run checked a
    region map that belongs to its coefficients, region_map.png for ``run`` into ``directory``;
    for a sweep over more variables than (L, W), slices.png (:func:`plot_slices`, with the map if
    it belongs) instead of region_map.png, the (L, W) plots showing every case whatever its x.

    The case studies' trajectories are regenerated from the run's coefficients (as an online
    user would) and drawn with the run's arm (its URDF, recorded in ``run.provenance``; or
    ``urdf_path``); cases that cannot be generated are left out of the figure.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = _lw_maps(run, directory)
    written += _region_map_plots(run, directory)
    if run.case_studies:
        written.append(_case_studies_plot(run, directory, urdf_path))
    return written


def _lw_maps(run: SweepRun, directory: Path) -> list[Path]:
    """clearance_map.png and endpoint_error_map.png: the run's certified clearance and endpoint
    error [mm] over (L, W), every case whatever its other variables."""
    margin_mm = run.settings.thresholds.margin_m * 1e3
    return [
        plot_map(
            run.cases,
            lambda c: c.certified_clearance_m,
            directory / "clearance_map.png",
            title=f"{run.label}: certified clearance over (L, W) ({len(run.cases)} cases)",
            colorbar_label=f"certified clearance [mm] (centre: {margin_mm:g} mm margin)",
            fitted=run.fitted_range,
            center_mm=margin_mm,
            doe_grid=(DOE_L_M, DOE_W_M),
            case_studies=run.case_studies,
            cmap="RdYlGn",
        ),
        plot_map(
            run.cases,
            lambda c: c.endpoint_error_m,
            directory / "endpoint_error_map.png",
            title=f"{run.label}: endpoint error (max of start, end) over (L, W)",
            colorbar_label=(f"endpoint error [mm] (limit {run.settings.thresholds.max_endpoint_error_m * 1e3:g} mm)"),
            fitted=run.fitted_range,
            doe_grid=(DOE_L_M, DOE_W_M),
            case_studies=run.case_studies,
        ),
    ]


def _region_map_plots(run: SweepRun, directory: Path) -> list[Path]:
    """slices.png for a sweep over more variables than (L, W) (with the checked map if it belongs);
    region_map.png for a checked map over (L, W) that belongs to the run's coefficients."""
    written = []
    check = run.range_check
    region_map = None if check is None else check.region_map
    if run.sweep_range.extra_m:
        written.append(
            plot_slices(
                run.cases,
                run.sweep_range,
                directory / "slices.png",
                title=f"{run.label}: {len(run.cases)} cases over ({', '.join(run.sweep_range.names)}), "
                f"in slices of {run.sweep_range.extra_m[0][0]}",
                margin_m=run.settings.thresholds.margin_m,
                region_map=region_map,
                violations=() if check is None else check.violations,
            )
        )
    if check is not None and region_map is not None and len(region_map.axes) == 2:
        written.append(
            plot_region_map(
                check.region_map,
                run.cases,
                directory / "region_map.png",
                title=f"{run.label}: region map ({check.map.cells} cells; darker = smaller clearance bound) "
                f"and {len(run.cases)} cases",
                violations=check.violations,
            )
        )
    return written


def _case_studies_plot(run: SweepRun, directory: Path, urdf_path: str | None) -> Path:
    """case_studies.png: the run's case studies regenerated from its coefficients and drawn with its
    arm (``urdf_path``, default the run's recorded URDF); cases that cannot be generated left out."""
    coefficients = load_coefficients(run.source, region_map=None)
    arm = load_planar_arm(urdf_path if urdf_path is not None else run.provenance["urdf"]["path"])
    studies = []
    for result in run.case_studies:
        try:
            generated = generate(coefficients, result.L_m, result.W_m, out_of_range="ignore", **result.extra_values)
        except PipelineError:
            continue
        studies.append(CaseStudy(result, generated.trajectory, generated.path, generated.obstacle))
    return plot_case_studies(
        studies,
        arm,
        directory / "case_studies.png",
        suptitle=f"{run.label}: four case studies inside the fitted range, off the DOE grid (cf. Fig. 5)",
    )
