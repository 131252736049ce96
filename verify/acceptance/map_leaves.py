"""The region map's leaves as drawable rectangles over (L, W), each coloured by its status and
shaded by its clearance bound: one look shared by the PNG (:mod:`verify.acceptance.plots`) and
the Meshcat sweep view (:mod:`verify.viewer.sweep_view`). A map over more axes (L, W, x) is
drawn in slices: the leaves holding one value of the extra axes (:func:`leaves_in_slice`).

Each status has its own hue (margin green, collision-free orange, infeasible purple, undecided
red); within a status, a leaf is the darker the smaller its clearance bound, on a linear scale
from the status's smallest to its largest finite bound (a bound of -inf is darkest).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.certify.region_map import STATUSES, RegionMap

#: Per status, (darkest, lightest) RGB in [0, 1]: the smallest and the largest clearance bound.
STATUS_SHADES: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "margin": ((0.0, 0.35, 0.15), (0.78, 0.93, 0.75)),
    "collision_free": ((0.65, 0.21, 0.01), (0.99, 0.82, 0.63)),
    "infeasible": ((0.25, 0.0, 0.49), (0.85, 0.85, 0.92)),
    "undecided": ((0.40, 0.0, 0.05), (0.99, 0.73, 0.63)),
}


@dataclass(frozen=True)
class LeafDrawing:
    """Every leaf of a map, ready to draw.

    Attributes:
        rectangles_m: (n, 4) rows (L_lo, L_hi, W_lo, W_hi) [m].
        rgb: (n, 3) colours in [0, 1].
        status: (n,) status index into :data:`STATUSES`.
        bound_range_m: Per status name, the (smallest, largest) finite clearance bound [m] of its
            leaves (the shading's scale), or None if the status has no leaf with a finite bound.
    """

    rectangles_m: np.ndarray
    rgb: np.ndarray
    status: np.ndarray
    bound_range_m: dict[str, tuple[float, float] | None]


def leaf_rectangles_m(region_map: RegionMap) -> np.ndarray:
    """(n, 4) rows (L_lo, L_hi, W_lo, W_hi) [m] of the leaves (vectorised :meth:`RegionMap.cell`);
    over more axes than (L, W), each leaf's extent in (L, W) (:func:`leaves_in_slice` picks those
    of one slice)."""
    lo = np.array(region_map.ranges_m)[:2, 0]
    size = region_map.leaf_sizes_m()[:, :2]
    index = region_map.subpaving.indices[:, :2].astype(float)
    start, end = lo + index * size, lo + (index + 1) * size
    return np.column_stack([start[:, 0], end[:, 0], start[:, 1], end[:, 1]])


def leaves_in_slice(region_map: RegionMap, extra_m: tuple[float, ...]) -> np.ndarray:
    """Mask (n,) of the leaves that tile the (L, W) plane at the extra axes' values ``extra_m``
    (``axes`` order, [m]): those the map's own lookup returns at their (L, W) centre and
    ``extra_m`` (so that a value on a leaf boundary picks the leaf the lookup picks). Every leaf
    for a map over (L, W)."""
    n = region_map.size
    if len(region_map.axes) == 2:
        return np.ones(n, dtype=bool)
    rectangles = leaf_rectangles_m(region_map)
    centre_l = 0.5 * (rectangles[:, 0] + rectangles[:, 1])
    centre_w = 0.5 * (rectangles[:, 2] + rectangles[:, 3])
    found = region_map.leaf_indices(centre_l, centre_w, *(np.full(n, float(v)) for v in extra_m))
    return found == np.arange(n)


def shade(status_name: str, fraction: np.ndarray) -> np.ndarray:
    """(n, 3) RGB of ``status_name`` at ``fraction`` in [0, 1] of its bound scale (0 darkest)."""
    dark, light = (np.array(c) for c in STATUS_SHADES[status_name])
    t = np.clip(np.asarray(fraction, dtype=float), 0.0, 1.0)[:, None]
    return dark + (light - dark) * t


def leaf_drawing(region_map: RegionMap) -> LeafDrawing:
    """Rectangles and colours of every leaf of ``region_map`` (module docstring)."""
    bound = region_map.clearance_bound_m
    rgb = np.zeros((bound.size, 3))
    ranges: dict[str, tuple[float, float] | None] = {}
    for k, name in enumerate(STATUSES):
        mask = region_map.status == k
        finite = mask & np.isfinite(bound)
        if not finite.any():
            ranges[name] = None
            rgb[mask] = shade(name, np.zeros(int(mask.sum())))
            continue
        lo, hi = float(bound[finite].min()), float(bound[finite].max())
        ranges[name] = (lo, hi)
        fraction = np.where(np.isfinite(bound[mask]), (bound[mask] - lo) / (hi - lo) if hi > lo else 1.0, 0.0)
        rgb[mask] = shade(name, fraction)
    return LeafDrawing(leaf_rectangles_m(region_map), rgb, region_map.status.copy(), ranges)
