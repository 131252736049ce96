"""Planar distance between segments and axis-aligned rectangles, compiled: the kernel under every
analytic clearance (the PSO's fast route, the range certificate's clearance and end-pose bounds).

For a segment a -> b and the rectangle of centre c and half extents h, both shifted so that the
rectangle is centred at the origin:

* the distance is 0 where they meet (slab test: the segment's parameter interval inside both
  slabs |x| <= h_x, |y| <= h_y is not empty);
* otherwise the minimum over the two convex sets is attained at a vertex of one of them: the
  smaller of the distances from a and b to the rectangle (|max(|p| - h, 0)|) and from the four
  corners (+-h_x, +-h_y) to the segment (the projection's parameter clipped to [0, 1]).

The loop does, per row, the operations the vectorised NumPy form does per element, in the same
order (no fused multiply-add: Numba contracts only under ``fastmath``), so it returns the same
doubles; the suite checks it bit for bit against that form and against dense sampling. Against
the vectorised form it removes the temporaries of some fifty NumPy operations per call, which
made the end-pose bounds of the range certificate's infeasibility proof slow (the polar branch
and bound calls it on a few thousand poses at a time).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["segment_rectangle_distance"]


def segment_rectangle_distance(a: np.ndarray, b: np.ndarray, center: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Planar distance [m] between segments a -> b and axis-aligned rectangles (module docstring).

    Args:
        a, b: Segment ends (..., 2) [m].
        center: Rectangle centres (..., 2) [m], broadcast against the segments.
        half: Rectangle half extents (..., 2) [m], >= 0, broadcast likewise.

    Returns:
        The distances, shape of the broadcast leading axes; 0 where a segment meets its rectangle.
    """
    a, b, center, half = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (a, b, center, half)))
    shape = a.shape[:-1]
    rows = [np.ascontiguousarray(v.reshape(-1, 2)) for v in (a, b, center, half)]
    out = np.empty(rows[0].shape[0])
    _distances(*rows, out)
    return out.reshape(shape)


@numba.njit(cache=True, nogil=True)
def _lesser(x: float, y: float) -> float:
    """``np.minimum`` of two floats: NaN if either is."""
    return x if (x < y or x != x) else y


@numba.njit(cache=True, nogil=True)
def _greater(x: float, y: float) -> float:
    """``np.maximum`` of two floats: NaN if either is."""
    return x if (x > y or x != x) else y


@numba.njit(cache=True, nogil=True)
def _slab(a: float, direction: float, half: float) -> tuple[float, float]:
    """The segment's parameter interval inside the slab |coordinate| <= half (infinite bounds
    where it runs parallel to the slab: all inside or none)."""
    if direction == 0.0:
        if abs(a) <= half:
            return -math.inf, math.inf
        return math.inf, -math.inf
    inv = 1.0 / direction
    t1 = (-half - a) * inv
    t2 = (half - a) * inv
    return _lesser(t1, t2), _greater(t1, t2)


@numba.njit(cache=True, nogil=True)
def _corner_distance(cx: float, cy: float, ax: float, ay: float, abx: float, aby: float) -> float:
    """Distance from the point (cx, cy) to the segment from (ax, ay) along (abx, aby)."""
    length2 = abx * abx + aby * aby
    s = ((cx - ax) * abx + (cy - ay) * aby) / (length2 if length2 > 0 else 1.0)
    s = _lesser(_greater(s, 0.0), 1.0)
    ox = cx - (ax + s * abx)
    oy = cy - (ay + s * aby)
    return math.sqrt(ox * ox + oy * oy)


@numba.njit(cache=True, nogil=True)
def _distances(a: np.ndarray, b: np.ndarray, center: np.ndarray, half: np.ndarray, out: np.ndarray) -> None:
    for i in range(out.shape[0]):
        ax, ay = a[i, 0] - center[i, 0], a[i, 1] - center[i, 1]
        bx, by = b[i, 0] - center[i, 0], b[i, 1] - center[i, 1]
        hx, hy = half[i, 0], half[i, 1]
        ex, ey = _greater(abs(ax) - hx, 0.0), _greater(abs(ay) - hy, 0.0)
        fx, fy = _greater(abs(bx) - hx, 0.0), _greater(abs(by) - hy, 0.0)
        best = _lesser(math.sqrt(ex * ex + ey * ey), math.sqrt(fx * fx + fy * fy))
        abx, aby = bx - ax, by - ay
        for sx, sy in ((1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)):
            best = _lesser(best, _corner_distance(hx * sx, hy * sy, ax, ay, abx, aby))
        lo_x, hi_x = _slab(ax, abx, hx)
        lo_y, hi_y = _slab(ay, aby, hy)
        enter = _greater(_greater(lo_x, lo_y), 0.0)
        leave = _lesser(_lesser(hi_x, hi_y), 1.0)
        out[i] = 0.0 if enter <= leave else best
