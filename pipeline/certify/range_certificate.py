"""The range certificate of one coefficients file: branch and bound over its axes x s for the
clearance (the axes are the coefficients' scene variables: (L, W), or with the obstacle's centre
x and / or its far edge d), then per leaf of the axes' subpaving (cuts of one axis at a time,
:mod:`pipeline.certify.search`) the endpoint-error bound and the infeasibility certificate,
assembled into a :class:`pipeline.certify.region_map.RegionMap`.

Soundness rests on the three bound modules (``clearance_bound``, ``endpoints``, ``duration``),
whose docstrings carry the derivations; this module only combines them:

* a leaf's clearance bound is the minimum of the bounds of every closed box whose node
  contains the leaf (the node itself or an ancestor, ``pipeline.certify.search``): those boxes
  cover the leaf times all of s in [0, 1];
* a leaf is cut further in two (its halves inherit that clearance bound, still valid on them)
  while its endpoint bound exceeds the tolerance, along the axis with the largest share of
  that bound's gap (``endpoints.endpoint_bounds_and_shares``; unless the family pins the
  endpoints by construction; and where the error at its centre exceeds the tolerance by more
  than the bound's gap above that error, only while the gap exceeds
  ``_ENDPOINT_RESOLUTION_M``: no cut brings such a cell within the tolerance), or while it is
  below the margin, not yet proven infeasible and close to being so, along its widest axis
  (its lowest level), down to the smallest cell.
  Smallest cells still close to being proven infeasible get the sub-cell bound of
  ``endpoints.infeasibility_upper_bounds`` (the lower of the two valid upper bounds is kept);
  with ``infeasibility_cuts`` instead, every leaf below the margin and not proven infeasible is cut
  along W where the part above a level is proven (``pipeline.certify.infeasibility_cuts``; the
  whole leaf is its lowest part);
* smallest cells certified collision-free that still miss the margin without being proven
  infeasible are cut into 2^``strip_split`` strips along W, each proven on its own
  (``pipeline.certify.strip_split``, which derives why W and why that is sound, over any axes);
  the strips replace their cell in the map as ordinary leaves of the subpaving.
"""

from __future__ import annotations

import functools
import itertools
import math
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from types import MappingProxyType
from typing import Any

import numpy as np

from pipeline.certify.certificate_settings import CertificateSettings
from pipeline.certify.clearance_cuts import half_clearance_bounds, steepest_axes
from pipeline.certify.end_pose_room import end_pose_room_m
from pipeline.certify.endpoints import (
    endpoint_bounds_and_shares,
    endpoint_clearance_upper_bounds,
    endpoint_error_bounds,
    infeasibility_upper_bounds,
)
from pipeline.certify.infeasibility_cuts import cut_leaves, lowest_infeasible_cuts, tilt_axes
from pipeline.certify.leaf_merge import merge_leaves
from pipeline.certify.range_model import RangeModel
from pipeline.certify.region_map import STATUSES, RegionMap, source_name
from pipeline.certify.search import (
    SearchLeaves,
    SearchSettings,
    cell_boxes,
    initial_roots,
    node_boxes,
    search,
    strip_levels,
)
from pipeline.certify.strip_split import strip_bounds
from pipeline.exceptions import InvalidParameterError
from pipeline.io.executor import DaskScheduler, Executor, LocalPool, as_executor, map_tasks
from pipeline.io.progress import ProgressCallback
from pipeline.offline.coefficients import Coefficients
from pipeline.validation import check_bool, check_non_negative, check_positive, check_positive_int

#: Default endpoint tolerance of the infeasibility certificate [m] (the build's regression's).
DEFAULT_ENDPOINT_TOLERANCE_M = 0.002
#: Default smallest cell, as a fraction of the fitted range's side: finer cells resolve the
#: margin's contour better but cost time and lookup memory (at 1/2048 the index takes 16 MiB);
#: strips along W (:data:`DEFAULT_STRIP_SPLIT`) resolve the contours more cheaply
#: (measurements: docs/results.md, "The range certificate").
DEFAULT_MIN_CELL = 1.0 / 1024
#: Default cell size to which regions below the margin are resolved, fraction of the side.
DEFAULT_BOUNDARY_CELL = 1.0 / 64
#: Default (smallest cell, boundary cell, extra depth) per number of axes: over more axes a cell
#: of 1/2^d has more of them in the box, so the cells stop coarser; the extra depth lets a cell
#: go that many halvings deeper along the axes that dominate its gap, at the smallest cell's
#: volume (:class:`RangeCertificateConfig`). On the default (L, W, x) build's coefficients an
#: extra depth of 3 gave the same 790,196 leaves and the margin on 98.36 % of the box against
#: 98.50 % with cubes (docs/results.md), so every default is 0.
DEFAULT_CELLS: Mapping[int, tuple[float, float, int]] = MappingProxyType(
    {
        2: (DEFAULT_MIN_CELL, DEFAULT_BOUNDARY_CELL, 0),
        3: (1.0 / 256, 1.0 / 16, 0),
        4: (1.0 / 32, 1.0 / 8, 0),  # (L, W, x, d): the second-order endpoint form proves 2 mm on cubes of 1/32
    }
)
#: Default spread [m] within which sibling leaves' bounds must agree to be stored as their parent
#: (``pipeline.certify.leaf_merge``), per number of axes; 0: none merged. Over (L, W) the map is
#: small as it is and keeps every leaf's own bounds.
DEFAULT_MERGE_SPREAD_M: Mapping[int, float] = MappingProxyType({2: 0.0, 3: 1e-4, 4: 1e-4})
#: Default of ``RangeCertificateConfig.second_order`` per number of axes. Over (L, W)
#: the map's cells are small enough for the mean-value form and keep their bytes; over three and
#: four axes the second-order form proves 2 mm on cubes of 1/32 where the mean-value form needs
#: 1/64 and finer (python scripts/endpoint_gap.py, docs/results.md), and the margin on cells the
#: mean-value form leaves below it.
DEFAULT_SECOND_ORDER: Mapping[int, bool] = MappingProxyType({2: False, 3: True, 4: True})
#: Leaves below the margin are cut (for the infeasibility certificate) while its upper bound is
#: within this of the margin [m].
_INFEASIBILITY_REFINE_M = 1e-3
#: Leaves that miss the endpoint tolerance all over (the error at the centre, less the bound's
#: gap above it, still exceeds the tolerance: no cut brings them within it) are cut only while
#: the bound is more than this above the centre's error [m] (the clearance search's resolution).
_ENDPOINT_RESOLUTION_M = 5e-4
#: The witnesses that spare a cell the sub-cells (``_witnessed``): tips on 2 circles (the end
#: point and the tolerance) at 12 angles, and how far above the margin a witness must clear [m]
#: (covering the pose's rounding). On the (L, W, x) map's smallest cells that stay
#: collision-free, 0.036 ms per cell found a witness for 79.5 % of them, whose sub-cells cost
#: 2.83 ms each.
_WITNESS_RINGS = 2
_WITNESS_ANGLES = 12
_WITNESS_SLACK_M = 1e-6
#: Leaves per task of the infeasibility certificate's sub-cells (fixed, so that the map does not
#: depend on the worker count).
_SUB_CELL_CHUNK = 128
#: Leaves per task of the endpoint bounds (bounded memory: the paper's Eq. 9, 247,000 leaves
#: at 1/1024, took 3.0 GB in one batch; 0.64 GB in chunks).
_LEAF_CHUNK = 4096
#: Tasks of the clearance branch and bound (diagonal stripes of the initial grid, run_search).
_SEARCH_GROUPS = 4
#: Default halvings along W of the smallest cells that miss the margin without being proven
#: infeasible (``pipeline.certify.strip_split``). On the default build, the margin's fraction of the
#: feasible area by halvings: 0 -> 99.863 % (30,421 cells), 2 -> 99.927 % (34,681), 3 -> 99.935 %
#: (40,361 cells).
DEFAULT_STRIP_SPLIT = 3
#: Default strip halvings per number of axes (:meth:`RangeCertificateConfig.for_axes`). Strips work
#: over any axes; over (L, W, x) 2 strips per cell raise the default build's margin from 99.47 % to
#: 99.57 % of the feasible volume for about 190 s of its certificate's time (docs/results.md); over
#: (L, W, x, d) the cuts at the infeasibility contour do their work.
DEFAULT_STRIP_SPLITS: Mapping[int, int] = MappingProxyType({2: DEFAULT_STRIP_SPLIT, 3: 1, 4: 0})
#: Default levels along W at which a leaf still close to being proven infeasible may be cut, 2^cuts
#: of them (``pipeline.certify.infeasibility_cuts``), per number of axes. Over (L, W) the strips do
#: it; over (L, W, x) the cells of 1/256 (0.16 mm of W) lie within a few times the bound's own gap
#: of the contour, and the cuts' bounds cost more of the build's time than they gain; over
#: (L, W, x, d), on cells of 1/32 (1.25 mm of W), 2^7 levels (10 um).
DEFAULT_INFEASIBILITY_CUTS: Mapping[int, int] = MappingProxyType({2: 0, 3: 0, 4: 7})
#: Default halvings of a leaf the infeasibility contour crosses, along the axis that tilts the
#: contour across it, before its cut along W (``cut_at_infeasibility``), per number of axes.
DEFAULT_TILT_CUTS: Mapping[int, int] = MappingProxyType({2: 0, 3: 0, 4: 1})
#: Default rounds of halving the leaves that miss the margin where their boxes' centres keep it
#: (``pipeline.certify.clearance_cuts``), per number of axes: over (L, W) and (L, W, x) the cells
#: are small enough, over (L, W, x, d) every axis halved once.
DEFAULT_CLEARANCE_CUTS: Mapping[int, int] = MappingProxyType({2: 0, 3: 0, 4: 4})
#: Columns of strips per task of the strips' bounds (fixed, so that the tasks do not depend on
#: the worker count; a strip's bounds depend on its column alone, so neither does the map). The
#: strips' interval bounds cost about as much per call as per row at a few hundred rows, so larger
#: tasks are faster: on a sub-box of the default (L, W, x) build, 256 columns per task took the
#: strips 2.3 times less time than 32 (and 1024 columns 3.2 times).
_STRIP_COLUMNS = 512
#: Halves per task of the clearance cuts (fixed, so that the map does not depend on the worker
#: count; a half's bound depends on the half alone).
_HALF_CHUNK = 512


@dataclass(frozen=True, kw_only=True)
class RangeCertificateConfig:
    """Settings of :func:`certify_range`.

    Attributes:
        margin_m: Clearance to certify [m]; None takes the coefficients' scene margin.
        endpoint_tolerance_m: Endpoint tolerance of the infeasibility certificate [m].
        min_cell: Smallest cell, fraction of the fitted range's side (rounded down to 1 / 2^k):
            a cell is cut no further once its volume is the volume of a cube of that side.
        extra_depth: Halvings beyond ``min_cell`` that a cell may take along one axis (at most
            that smallest volume: the other axes stay coarser), so that cells cut along the
            axes that dominate their gap resolve a contour across those axes finely (0: every
            axis stops at ``min_cell``).
        boundary_cell: Cell size to which regions that miss the margin are resolved (fraction).
        max_depth_s: Deepest cut of s = t / T (intervals of 1 / 2^depth).
        jobs: Worker processes for the branch and bound and the bounds (unless ``executor``).
        executor: Where the tasks run (:mod:`pipeline.io.executor`, e.g. a
            :class:`pipeline.io.executor.DaskScheduler`); None: ``LocalPool(jobs)``. Neither it nor
            ``jobs`` changes the map.
        max_boxes: Budget of box evaluations per worker task.
        strip_split: Halvings along W of the smallest cells that miss the margin without being
            proven infeasible (0: none; ``pipeline.certify.strip_split``).
        infeasibility_cuts: Levels along W (2^cuts of them) at which a leaf still close to being
            proven infeasible may be cut, its part above proven (0: none;
            ``pipeline.certify.infeasibility_cuts``).
        tilt_cuts: Halvings of a leaf the infeasibility contour crosses, along the axis that tilts
            the contour across it (``infeasibility_cuts.tilt_axes``), before its cut along W, each
            half cut on its own (0: none; with ``infeasibility_cuts`` only).
        clearance_cuts: Rounds of halving the leaves that miss the margin where their boxes'
            centres keep it, along their steepest axis, each half bounded on its own (0: none;
            ``pipeline.certify.clearance_cuts``).
        merge_spread_m: Sibling leaves of one status whose clearance bounds, and endpoint bounds,
            differ by at most this are stored as their parent [m] (``pipeline.certify.leaf_merge``;
            0: none).
        second_order: Bound the clearance and the endpoint errors by the tighter of the
            mean-value and the second-order Taylor forms (``pipeline.certify.clearance_bound``,
            ``pipeline.certify.endpoints``); False: the mean-value form alone.
    """

    margin_m: float | None = None
    endpoint_tolerance_m: float = DEFAULT_ENDPOINT_TOLERANCE_M
    min_cell: float = DEFAULT_MIN_CELL
    boundary_cell: float = DEFAULT_BOUNDARY_CELL
    extra_depth: int = 0
    max_depth_s: int = 16
    jobs: int = 1
    executor: Executor | None = None
    max_boxes: int = 5_000_000
    strip_split: int = DEFAULT_STRIP_SPLIT
    infeasibility_cuts: int = 0
    tilt_cuts: int = 0
    clearance_cuts: int = 0
    merge_spread_m: float = 0.0
    second_order: bool = False

    def __post_init__(self) -> None:
        if self.margin_m is not None:
            check_non_negative("margin_m", self.margin_m)
        check_non_negative("endpoint_tolerance_m", self.endpoint_tolerance_m)
        for name in ("min_cell", "boundary_cell"):
            value = check_positive(name, getattr(self, name))
            if value > 1.0 or value < 2.0**-20:
                raise InvalidParameterError(name, value, "a fraction of the range's side in [2^-20, 1]")
        check_positive_int("max_depth_s", self.max_depth_s, minimum=4)
        check_positive_int("extra_depth", self.extra_depth, minimum=0)
        if self.extra_depth > 6:
            raise InvalidParameterError("extra_depth", self.extra_depth, "0..6 halvings beyond the smallest cell")
        check_positive_int("jobs", self.jobs)
        if self.executor is not None and not isinstance(self.executor, LocalPool | DaskScheduler):
            raise InvalidParameterError("executor", self.executor, "a LocalPool, a DaskScheduler or None")
        check_positive_int("max_boxes", self.max_boxes)
        check_positive_int("strip_split", self.strip_split, minimum=0)
        check_non_negative("merge_spread_m", self.merge_spread_m)
        check_bool("second_order", self.second_order)
        if self.strip_split > 6:
            raise InvalidParameterError("strip_split", self.strip_split, "0..6 halvings along W")
        check_positive_int("infeasibility_cuts", self.infeasibility_cuts, minimum=0)
        if self.infeasibility_cuts > 8:
            raise InvalidParameterError("infeasibility_cuts", self.infeasibility_cuts, "0..8 halvings along W")
        check_positive_int("tilt_cuts", self.tilt_cuts, minimum=0)
        if self.tilt_cuts > 6:
            raise InvalidParameterError("tilt_cuts", self.tilt_cuts, "0..6 halvings across the contour")
        check_positive_int("clearance_cuts", self.clearance_cuts, minimum=0)
        if self.clearance_cuts > 8:
            raise InvalidParameterError("clearance_cuts", self.clearance_cuts, "0..8 rounds of halving")

    @classmethod
    def for_axes(cls, k: int, **settings: Any) -> RangeCertificateConfig:
        """The default settings over ``k`` axes (cells :data:`DEFAULT_CELLS`, merging
        :data:`DEFAULT_MERGE_SPREAD_M`, bound form :data:`DEFAULT_SECOND_ORDER`, strips
        :data:`DEFAULT_STRIP_SPLITS`, cuts at the infeasibility contour
        :data:`DEFAULT_INFEASIBILITY_CUTS`, tilted by :data:`DEFAULT_TILT_CUTS`, cuts for the
        clearance :data:`DEFAULT_CLEARANCE_CUTS`),
        with ``settings`` that are not None in their place (names of this class's fields)."""
        min_cell, boundary_cell, extra_depth = DEFAULT_CELLS.get(k, DEFAULT_CELLS[3])
        defaults = {
            "min_cell": min_cell,
            "boundary_cell": boundary_cell,
            "extra_depth": extra_depth,
            "merge_spread_m": DEFAULT_MERGE_SPREAD_M.get(k, DEFAULT_MERGE_SPREAD_M[3]),
            "second_order": DEFAULT_SECOND_ORDER.get(k, True),
            "strip_split": DEFAULT_STRIP_SPLITS.get(k, 0),
            "infeasibility_cuts": DEFAULT_INFEASIBILITY_CUTS.get(k, DEFAULT_INFEASIBILITY_CUTS[4]),
            "tilt_cuts": DEFAULT_TILT_CUTS.get(k, DEFAULT_TILT_CUTS[4]),
            "clearance_cuts": DEFAULT_CLEARANCE_CUTS.get(k, DEFAULT_CLEARANCE_CUTS[4]),
        }
        return cls(**{**defaults, **{name: value for name, value in settings.items() if value is not None}})

    @property
    def run_on(self) -> Executor:
        """Where the tasks run: ``executor``, or ``LocalPool(jobs)``."""
        return LocalPool(self.jobs) if self.executor is None else self.executor

    @property
    def max_depth_lw(self) -> int:
        """Quadtree depth of the smallest cell."""
        return max(0, math.floor(math.log2(1.0 / self.min_cell) + 1e-9))

    def settings_for(self, margin_m: float) -> CertificateSettings:
        """The stages' settings after the search, for the margin ``margin_m`` [m]."""
        return CertificateSettings(
            margin_m=margin_m,
            endpoint_tolerance_m=self.endpoint_tolerance_m,
            max_depth=self.max_depth_lw,
            extra_depth=self.extra_depth,
            max_depth_s=self.max_depth_s,
            strip_split=self.strip_split,
            infeasibility_cuts=self.infeasibility_cuts,
            tilt_cuts=self.tilt_cuts,
            clearance_cuts=self.clearance_cuts,
            second_order=self.second_order,
            run_on=self.run_on,
        )

    def search_settings(self, margin_m: float) -> SearchSettings:
        """The branch and bound's settings."""
        depth = self.max_depth_lw
        boundary = min(depth, max(0, math.floor(math.log2(1.0 / self.boundary_cell) + 1e-9)))
        return SearchSettings(
            margin_m=margin_m,
            max_depth_lw=depth,
            extra_depth_lw=self.extra_depth,
            boundary_depth_lw=boundary,
            max_depth_s=self.max_depth_s,
            initial_depth_lw=min(3, depth),
            initial_depth_s=4,
            max_boxes=self.max_boxes,
            second_order=self.second_order,
        )


#: Stages reported to a :data:`pipeline.io.progress.ProgressCallback` by :func:`certify_range`, in
#: order: the branch and bound (its tasks), the endpoint bounds (leaves: the total grows as leaves
#: are cut), the infeasibility certificate's sub-cells (leaves), its cuts along W (leaves) and the
#: clearance cuts (halves) and the strips (strips).
PROGRESS_STAGES = (
    "range map: search",
    "range map: refine",
    "range map: sub-cells",
    "range map: W cuts",
    "range map: clearance cuts",
    "range map: strips",
)
#: Each stage's name, read by name where it is reported (an index shifts when a stage is inserted).
(
    _STAGE_SEARCH,
    _STAGE_REFINE,
    _STAGE_SUB_CELLS,
    _STAGE_W_CUTS,
    _STAGE_CLEARANCE_CUTS,
    _STAGE_STRIPS,
) = PROGRESS_STAGES


def _no_progress(_stage: str, _done: int, _total: int) -> None:
    return None


def _run_tasks(
    function: Callable[..., Any],
    arguments: Sequence[tuple],
    jobs: int | Executor,
    on_done: Callable[[int], None] = lambda _k: None,
) -> list[Any]:
    """``[function(*a) for a in arguments]`` in that order, one task per worker call, on ``jobs``
    (a number of local processes or an executor: :func:`pipeline.io.executor.map_tasks`);
    ``on_done(k)`` as task ``k`` finishes (in the order they finish). The tasks are the caller's,
    fixed, so the results do not depend on where they run. An error (or Ctrl-C) cancels the tasks
    not yet started. A local pool forks its workers where the platform offers it (Linux): the
    tasks carry all they read, and a certificate starts several pools, each of which would
    otherwise pay a fresh interpreter's start-up (about a third of the default build's map)."""
    executor = as_executor(jobs)
    if isinstance(executor, LocalPool) and sys.platform.startswith("linux"):
        executor = replace(executor, start_method="fork")
    return map_tasks(executor, functools.partial(_unpacked, function), arguments, lambda k, _: on_done(k), chunk_size=1)


def _unpacked(function: Callable[..., Any], arguments: tuple) -> Any:
    return function(*arguments)


def _counted(
    progress: ProgressCallback | None, stage: str, sizes: Sequence[int], before: int = 0
) -> Callable[[int], None]:
    """The ``on_done`` of :func:`_run_tasks` reporting ``stage`` to ``progress``: task ``k`` is
    ``sizes[k]`` units, after ``before`` units of the stage already done (counted in the total).
    Reports ``done == before`` at once."""
    report = progress or _no_progress
    total = before + sum(sizes)
    done = before
    report(stage, done, total)

    def on_done(k: int) -> None:
        nonlocal done
        done += sizes[k]
        report(stage, done, total)

    return on_done


def run_search(
    model: RangeModel, settings: SearchSettings, jobs: int | Executor, progress: ProgressCallback | None = None
) -> SearchLeaves:
    """The branch and bound from the initial grid, in :data:`_SEARCH_GROUPS` tasks spread over
    ``jobs`` (processes, or an executor); ``progress`` gets "range map: search" over the tasks.

    The roots go to the tasks by diagonal stripes ((sum of the node's indices) mod groups), so that
    a strip along any axis, where the work concentrates (near the margin's contour), is shared out (by rows
    of the grid, the default build's strip along W = 0.12 m fell to one worker and two jobs took
    as long as one). The tasks are fixed, not one per worker, so the result (the box budget is
    per task) does not depend on ``jobs``.
    """
    roots = initial_roots(model.k, settings.initial_depth_lw)
    stripe = np.sum(roots[:, 1:], axis=1) % _SEARCH_GROUPS
    groups = [roots[stripe == k] for k in range(_SEARCH_GROUPS) if np.any(stripe == k)]
    on_done = _counted(progress, _STAGE_SEARCH, [1] * len(groups))
    parts = _run_tasks(search, [(model, settings, group) for group in groups], jobs, on_done)
    fields = ("levels", "index", "bound_m", "center_clearance_m")
    merged = {f: np.concatenate([getattr(p, f) for p in parts]) for f in fields}
    return SearchLeaves(
        **merged,
        evaluations=sum(p.evaluations for p in parts),
        boxes_closed=sum(p.boxes_closed for p in parts),
    )


def _split(arrays: list[np.ndarray], rows: np.ndarray, axes: np.ndarray) -> list[np.ndarray]:
    """Replace the leaves ``rows`` (mask) by their two halves along ``axes`` (one per leaf of
    ``rows``); other columns are inherited."""
    levels, index, *rest = arrays
    cut = np.flatnonzero(rows)
    axis = np.repeat(axes, 2)
    kids_level = np.repeat(levels[cut], 2, axis=0)
    kids_index = np.repeat(index[cut], 2, axis=0)
    at = np.arange(kids_level.shape[0])
    kids_level[at, axis] += 1
    kids_index[at, axis] = 2 * kids_index[at, axis] + at % 2
    kids = (kids_level, kids_index, *(np.repeat(column[cut], 2, axis=0) for column in rest))
    return [np.concatenate([column[~rows], kid]) for column, kid in zip(arrays, kids, strict=True)]


def _in_chunks(
    function: Callable[..., np.ndarray],
    rows: int | list[slice],
    jobs: int | Executor,
    model: RangeModel,
    arrays: tuple,
    *constants,
    progress: ProgressCallback | None = None,
    stage: str = "",
    before: int = 0,
) -> list[np.ndarray]:
    """``function(model, *chunks of arrays, *constants)`` over fixed chunks of ``rows`` rows (or
    the given slices), spread over ``jobs`` (processes, or an executor); the list of its results in order. The
    chunks do not depend on ``jobs`` (the polar branch and bound caps its boxes per call), so
    neither do the results. ``progress`` gets ``stage`` in rows, after ``before`` rows done."""
    size = arrays[0].shape[0]
    if isinstance(rows, int):
        chunks = [slice(k, k + rows) for k in range(0, size, rows)]
    else:
        chunks = rows
    tasks = [(model, *(a[k] for a in arrays), *constants) for k in chunks]
    sizes = [len(range(*k.indices(size))) for k in chunks]
    return _run_tasks(function, tasks, jobs, _counted(progress, stage, sizes, before))


def sub_cell_bounds(
    model: RangeModel,
    c: np.ndarray,
    r: np.ndarray,
    settings: CertificateSettings,
    progress: ProgressCallback | None = None,
) -> np.ndarray:
    """``endpoints.infeasibility_upper_bounds`` over chunks of :data:`_SUB_CELL_CHUNK` leaves,
    spread over ``settings.run_on`` (the bounds do not depend on it), +inf without trying for
    the cells with a witness that they are not infeasible (``_witnessed``); ``progress`` gets
    "range map: sub-cells" in leaves."""
    out = np.full(c.shape[0], np.inf)
    todo = np.flatnonzero(~_witnessed(model, c, r, settings))
    if progress is not None and c.shape[0]:
        progress(_STAGE_SUB_CELLS, 0, c.shape[0])
        if todo.size == 0:
            progress(_STAGE_SUB_CELLS, c.shape[0], c.shape[0])
    if todo.size == 0:
        return out
    parts = _in_chunks(
        infeasibility_upper_bounds,
        _SUB_CELL_CHUNK,
        settings.run_on,
        model,
        (c[todo], r[todo]),
        settings.endpoint_tolerance_m,
        settings.margin_m,
        progress=progress,
        stage=_STAGE_SUB_CELLS,
        before=c.shape[0] - todo.size,  # the witnessed cells: done
    )
    out[todo] = np.concatenate(parts)
    return out


def _witnessed(model: RangeModel, c: np.ndarray, r: np.ndarray, settings: CertificateSettings) -> np.ndarray:
    """Cells (centres, half widths (n, k) [m]) with a witness that they are not infeasible: a
    pose at each end, sampled (``end_pose_room_m``, :data:`_WITNESS_RINGS` x
    :data:`_WITNESS_ANGLES` tips), that keeps the margin (by :data:`_WITNESS_SLACK_M`) against
    the obstacle at one point of the cell, its smallest L and W and its centre's x and d (P1
    and P5 moved with them). No sub-cell bound can prove such a cell infeasible (it would
    return +inf), so it is not tried: a choice of work that changes no bound."""
    if c.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    corner = c - r
    room = end_pose_room_m(
        model,
        corner[:, 0],
        corner[:, 1],
        settings.endpoint_tolerance_m,
        rings=_WITNESS_RINGS,
        angles=_WITNESS_ANGLES,
        **model.obstacle_moves(c),
    )
    return room >= settings.margin_m + _WITNESS_SLACK_M


def _leaf_bounds(
    model: RangeModel,
    c: np.ndarray,
    r: np.ndarray,
    need: np.ndarray,
    tolerance_m: float,
    margin_m: float,
    second_order: bool = False,
) -> np.ndarray:
    """Per leaf (centres, half widths): the endpoint bound (with the second-order form if
    ``second_order``), the endpoint error at the centre, where ``need`` the endpoint clearance
    upper bound (else inf), then each axis's share of the endpoint bound's gap, as columns of an
    (n, 3 + k) array."""
    out = np.full((c.shape[0], 3 + model.k), np.inf)
    bounds, out[:, 3:] = endpoint_bounds_and_shares(model, c, r, second_order)
    out[:, 0] = np.max(bounds, axis=1)
    out[:, 1] = np.max(endpoint_error_bounds(model, c, np.zeros_like(r)), axis=1)
    if np.any(need):
        out[need, 2] = np.min(endpoint_clearance_upper_bounds(model, c[need], r[need], tolerance_m, margin_m), axis=1)
    return out


def _halves_upper_bounds(
    model: RangeModel, c: np.ndarray, r: np.ndarray, open_axes: np.ndarray, tolerance_m: float, margin_m: float
) -> np.ndarray:
    """Per cell (centres, half widths (n, k) [m]) and axis, the lower of its two halves' endpoint
    clearance upper bounds along that axis [m] (+inf along an axis not in ``open_axes``)."""
    n, k = c.shape
    out = np.full((n, k), np.inf)
    for axis in range(k):
        rows = np.flatnonzero(open_axes[:, axis])
        if rows.size == 0:
            continue
        half = r[rows].copy()
        half[:, axis] /= 2
        shift = np.zeros_like(half)
        shift[:, axis] = half[:, axis]
        centres = np.concatenate([c[rows] - shift, c[rows] + shift])
        upper = np.min(
            endpoint_clearance_upper_bounds(model, centres, np.concatenate([half, half]), tolerance_m, margin_m), axis=1
        )
        out[rows, axis] = np.minimum(upper[: rows.size], upper[rows.size :])
    return out


def _infeasibility_axes(
    model: RangeModel, levels: np.ndarray, index: np.ndarray, open_axes: np.ndarray, settings: CertificateSettings
) -> np.ndarray:
    """Per leaf close to being proven infeasible, the open axis to cut it along: the one whose
    lower half's or upper half's endpoint clearance upper bound is lowest (each axis tried, as
    interval subpavings try the directions of an undecided box). A choice of work: any axis
    keeps the certificate sound."""
    c, r = cell_boxes(model, levels, index)
    parts = _in_chunks(
        _halves_upper_bounds,
        _SUB_CELL_CHUNK,
        settings.run_on,
        model,
        (c, r, open_axes),
        settings.endpoint_tolerance_m,
        settings.margin_m,
    )
    return np.argmin(np.concatenate(parts), axis=1)


def refine_leaves(
    model: RangeModel,
    leaves: list[np.ndarray],
    settings: CertificateSettings,
    progress: ProgressCallback | None = None,
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Endpoint bounds and infeasibility upper bounds per leaf, cutting leaves as the module
    docstring says. ``leaves`` = [levels (n, k), index (n, k), clearance bound, *further columns the
    children inherit]; returns the final leaves (the same columns),
    their endpoint bounds (n,) and their endpoint clearance upper bounds (n,) (inf where not needed).
    The bounds run on ``settings.run_on`` over fixed chunks of leaves (the result does not depend
    on it). ``progress`` gets "range map: refine" in leaves bounded, whose total grows by
    the children of each round's cuts, then "range map: sub-cells"."""
    margin_m, tolerance_m = settings.margin_m, settings.endpoint_tolerance_m
    bounded = 0  # leaves whose bounds are computed, over the rounds
    n = leaves[0].shape[0]
    endpoint, centre_error, upper = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    arrays = [*leaves, endpoint, centre_error, upper, np.zeros((n, model.k))]
    while True:
        (levels, index, bound), (endpoint, centre_error, upper, shares) = arrays[:3], arrays[-4:]
        todo = np.isnan(endpoint)
        if np.any(todo):
            c, r = cell_boxes(model, levels[todo], index[todo])
            need = bound[todo] < margin_m
            parts = _in_chunks(
                _leaf_bounds,
                _LEAF_CHUNK,
                settings.run_on,
                model,
                (c, r, need),
                tolerance_m,
                margin_m,
                settings.second_order,
                progress=progress,
                stage=_STAGE_REFINE,
                before=bounded,
            )
            columns = np.concatenate(parts)
            endpoint[todo], centre_error[todo], upper[todo] = columns[:, :3].T
            shares[todo] = columns[:, 3:]
            bounded += int(np.count_nonzero(todo))
        open_axes = settings.open_axes(levels)
        deep = np.any(open_axes, axis=1)
        close = (bound < margin_m) & (upper >= margin_m) & (upper < margin_m + _INFEASIBILITY_REFINE_M)
        # A family that pins the endpoints has errors of rounding size: its bound is reported, not
        # refined. A leaf whose error at the centre minus the bound's gap above it exceeds the
        # tolerance (the error falls below its centre value by about as much as it rises above
        # it, the search's rule for the margin) misses the tolerance whatever the cut: its bound
        # is refined only to within _ENDPOINT_RESOLUTION_M of the centre's error.
        missed = (2.0 * centre_error - endpoint > tolerance_m) & (endpoint - centre_error <= _ENDPOINT_RESOLUTION_M)
        loose = (endpoint > tolerance_m) & ~missed & (not model.family.pins_endpoints)
        rows = deep & (loose | close)
        if not np.any(rows):
            # Smallest cells still close: try sub-cells (pipeline.certify.endpoints); with cuts at the
            # infeasibility contour, cut_at_infeasibility does, the whole cell being its lowest part.
            if np.any(close) and settings.infeasibility_cuts == 0:
                c, r = cell_boxes(model, levels[close], index[close])
                sub = sub_cell_bounds(model, c, r, settings, progress)
                upper[close] = np.minimum(upper[close], sub)
            return arrays[:-4], endpoint, upper
        # Cut a loose leaf along the axis with the largest share of its endpoint bound's gap, one
        # close to infeasible along its widest axis (cubes: with no extra depth it is cut to the
        # smallest cube whatever the order), or, with an extra depth, along the axis whose halves
        # come closest to the proof; among the open axes.
        axes = np.argmax(np.where(open_axes, shares, -np.inf), axis=1)
        close_rows = rows & ~loose
        if settings.extra_depth == 0:
            axes[close_rows] = np.argmin(np.where(open_axes, levels, np.iinfo(np.int64).max), axis=1)[close_rows]
        elif np.any(close_rows):
            axes[close_rows] = _infeasibility_axes(
                model, levels[close_rows], index[close_rows], open_axes[close_rows], settings
            )
        arrays = _split(arrays, rows, axes[rows])
        for column in arrays[-4:-1]:  # children get their own endpoint bounds
            column[-2 * np.count_nonzero(rows) :] = np.nan


def cut_at_infeasibility(
    model: RangeModel,
    leaves: list[np.ndarray],
    endpoint: np.ndarray,
    upper: np.ndarray,
    settings: CertificateSettings,
    progress: ProgressCallback | None = None,
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Cut the leaves below the margin that are not proven infeasible along W, at the lowest of
    2^``settings.infeasibility_cuts`` levels above which the part is proven
    (``pipeline.certify.infeasibility_cuts``, whose sampled end poses spare the leaves with room at
    their top the bounds). A leaf the contour crosses (its top part lacks room, yet the whole is
    not proven) is first halved, up to ``settings.tilt_cuts`` times, along the axis that tilts the
    contour across it (``infeasibility_cuts.tilt_axes``), each half searched again: a cut along W
    leaves the wedge between the tilted contour and the level proven, which halves with the leaf.
    ``leaves`` = [levels (n, k), index (n, k), *columns the pieces inherit]; returns the leaves (the
    same columns), their endpoint bounds and their infeasibility bounds (the proven parts': theirs).
    ``progress`` gets "range map: W cuts" in leaves."""
    e, margin_m = settings.infeasibility_cuts, settings.margin_m
    if e == 0:
        return leaves, endpoint, upper
    n, top = leaves[0].shape[0], 2**e
    todo = (leaves[2] < margin_m) & (upper >= margin_m)
    level, level_bound = np.full(n, float(top)), np.full(n, np.inf)
    arrays = [*leaves, endpoint, upper, level, level_bound, todo]
    searched = 0  # leaves searched, over the rounds
    for tilt_round in range(settings.tilt_cuts + 1):
        rows = np.flatnonzero(arrays[-1])
        if rows.size == 0:
            break
        c, r = cell_boxes(model, arrays[0][rows], arrays[1][rows])
        found = np.concatenate(
            _in_chunks(
                lowest_infeasible_cuts,
                _SUB_CELL_CHUNK,
                settings.run_on,
                model,
                (c, r),
                e,
                settings.endpoint_tolerance_m,
                margin_m,
                progress=progress,
                stage=_STAGE_W_CUTS,
                before=searched,
            )
        )
        searched += rows.size
        arrays[-3][rows], arrays[-2][rows] = found[:, 0], found[:, 1]
        arrays[-1][:] = False
        tilted = (found[:, 0] > 0) & (found[:, 2] < top)  # the contour crosses it, the whole not proven
        if tilt_round == settings.tilt_cuts or not np.any(tilted):
            break
        tolerance_m = settings.endpoint_tolerance_m
        axes = np.concatenate(
            _in_chunks(tilt_axes, _SUB_CELL_CHUNK, settings.run_on, model, (c[tilted], r[tilted]), tolerance_m)
        )
        split = np.zeros(arrays[0].shape[0], dtype=bool)
        split[rows[tilted]] = True
        arrays = _split(arrays, split, axes)
        arrays[-1][-2 * axes.size :] = True
        arrays[-3][-2 * axes.size :], arrays[-2][-2 * axes.size :] = top, np.inf
    return _cut_pieces(arrays[:-5], arrays[-5], arrays[-4], arrays[-3].astype(np.int64), arrays[-2], e)


def _cut_pieces(
    leaves: list[np.ndarray],
    endpoint: np.ndarray,
    upper: np.ndarray,
    level: np.ndarray,
    level_bound: np.ndarray,
    e: int,
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """The leaves with each one proven above its ``level`` (< 2^e) replaced by its dyadic pieces
    along W (``infeasibility_cuts.cut_leaves``): the pieces above get ``level_bound``, the others
    keep the leaf's bounds."""
    cut_rows = np.flatnonzero(level < 2**e)
    if cut_rows.size == 0:
        return leaves, endpoint, upper
    owner, piece_levels, piece_index, above = cut_leaves(leaves[0][cut_rows], leaves[1][cut_rows], level[cut_rows], e)
    parent = cut_rows[owner]
    keep = np.ones(endpoint.size, dtype=bool)
    keep[cut_rows] = False
    pieces = [piece_levels, piece_index, *(column[parent] for column in leaves[2:])]
    joined = [np.concatenate([column[keep], piece]) for column, piece in zip(leaves, pieces, strict=True)]
    piece_upper = np.where(above, level_bound[parent], upper[parent])
    return joined, np.concatenate([endpoint[keep], endpoint[parent]]), np.concatenate([upper[keep], piece_upper])


def cut_for_clearance(
    model: RangeModel,
    leaves: list[np.ndarray],
    endpoint: np.ndarray,
    upper: np.ndarray,
    settings: CertificateSettings,
    progress: ProgressCallback | None = None,
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Halve the leaves below the margin, not proven infeasible, whose boxes' centres keep the
    margin, along their steepest axis, for ``settings.clearance_cuts`` rounds, each half bounded on
    its own (``pipeline.certify.clearance_cuts``, which derives why that is sound). ``leaves`` =
    [levels (n, k), index (n, k), clearance bound, centre clearance, *further columns the halves
    inherit]; returns the leaves (the same columns; a half's centre clearance is its leaf's, or
    -inf where one of its boxes' centres missed the margin), their endpoint bounds and their
    infeasibility bounds (inherited). ``progress`` gets "range map: clearance cuts" in halves."""
    margin_m = settings.margin_m
    todo = (leaves[2] < margin_m) & (upper >= margin_m) & (leaves[3] >= margin_m)
    arrays = [*leaves, endpoint, upper, todo]
    bounded = 0  # halves bounded, over the rounds
    for _ in range(settings.clearance_cuts):
        rows = arrays[-1]
        count = int(np.count_nonzero(rows))
        if count == 0:
            break
        c, r = cell_boxes(model, arrays[0][rows], arrays[1][rows])
        axes = np.concatenate(_in_chunks(steepest_axes, _HALF_CHUNK, settings.run_on, model, (c, r)))
        arrays = _split(arrays, rows, axes)
        halves = slice(arrays[0].shape[0] - 2 * count, None)
        c, r = cell_boxes(model, arrays[0][halves], arrays[1][halves])
        found = np.concatenate(
            _in_chunks(
                half_clearance_bounds,
                _HALF_CHUNK,
                settings.run_on,
                model,
                (c, r, arrays[2][halves]),
                margin_m,
                settings.max_depth_s,
                settings.second_order,
                progress=progress,
                stage=_STAGE_CLEARANCE_CUTS,
                before=bounded,
            )
        )
        bounded += 2 * count
        hopeful = found[:, 1] > 0.0
        arrays[2][halves] = found[:, 0]
        arrays[3][halves] = np.where(hopeful, arrays[3][halves], -np.inf)
        arrays[-1][:] = False
        arrays[-1][halves] = (found[:, 0] < margin_m) & hopeful
    return arrays[:-3], arrays[-3], arrays[-2]


def split_strips(
    model: RangeModel,
    leaves: list[np.ndarray],
    endpoint: np.ndarray,
    upper: np.ndarray,
    settings: CertificateSettings,
    progress: ProgressCallback | None = None,
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Replace the smallest cells certified collision-free that miss the margin without being
    proven infeasible, and lie near a contour, by their 2^``settings.strip_split`` strips along W
    (module docstring). ``leaves`` = [levels (n, k), index (n, k), clearance
    bound, lowest clearance at a box centre]; returns the leaves [levels, index, clearance bound]
    and their endpoint and infeasibility bounds. ``progress`` gets "range map: strips" in strips."""
    levels, index, bound, centre = leaves
    leaves = leaves[:3]
    margin_m = settings.margin_m
    e = settings.strip_split
    # Collision-free cells only: a cell not certified collision-free stays "undecided" whole.
    smallest = np.all(levels == settings.max_depth, axis=1)
    rows = smallest & (bound > 0.0) & (bound < margin_m) & (upper >= margin_m)
    if e == 0 or not np.any(rows):
        return leaves, endpoint, upper
    depth, i_w = levels[:, 0], index[:, 1]
    # A column: one interval on every axis but W (its own key per leaf, in lexicographic order).
    others = np.delete(index, 1, axis=1)
    column = np.unique(others, axis=0, return_inverse=True)[1].reshape(-1)
    rows &= _near_a_contour(column, i_w, bound, centre, rows, margin_m)
    k = 2**e
    order = np.lexsort((i_w[rows], column[rows]))  # by column, then W
    s_depth = np.repeat(depth[rows][order], k)
    s_column = np.repeat(column[rows][order], k)
    s_index = np.repeat(index[rows][order], k, axis=0)
    s_index[:, 1] = (i_w[rows][order][:, None] * k + np.arange(k)).ravel()
    floor = np.repeat(bound[rows][order], k)
    c, r = node_boxes(model, s_depth, s_index, split_w=e)
    # Tasks of whole columns (the infeasibility's monotonicity works along a column), fixed in size.
    column_starts = np.concatenate([[0], np.flatnonzero(np.diff(s_column)) + 1])
    cuts = [*column_starts[::_STRIP_COLUMNS].tolist(), s_column.size]
    chunks = [slice(a, b) for a, b in itertools.pairwise(cuts)]
    parts = _in_chunks(
        strip_bounds,
        chunks,
        settings.run_on,
        model,
        (c, r, floor, s_column),
        margin_m,
        settings.endpoint_tolerance_m,
        settings.max_depth_s,
        settings.second_order,
        progress=progress,
        stage=_STAGE_STRIPS,
    )
    s_bound, s_endpoint, s_upper = np.concatenate(parts).T
    keep = ~rows
    joined = [
        np.concatenate([a[keep], b])
        for a, b in zip(
            (levels, index, bound, endpoint, upper),
            (
                strip_levels(s_depth, model.k, e),
                s_index,
                s_bound,
                s_endpoint,
                s_upper,
            ),
            strict=True,
        )
    ]
    return joined[:3], joined[3], joined[4]


def _near_a_contour(
    column: np.ndarray, i_w: np.ndarray, bound: np.ndarray, centre: np.ndarray, rows: np.ndarray, margin_m: float
) -> np.ndarray:
    """Which of the smallest cells ``rows`` may gain from strips: near the margin's contour by the
    search's rule (2 centre - bound >= margin: the clearance may rise to the margin within the
    cell), or within two cells of the top of their column's run of such cells (where the
    infeasible region, which is the top of a column when it is anything, begins). Elsewhere
    (the paper's Eq. 9 misses the margin over a fifth of the range) strips could change no
    status. A choice of work, not of soundness. ``column``: each leaf's column (0..)."""
    near_margin = 2.0 * centre - bound >= margin_m
    top = np.full(int(column.max()) + 1, -1)
    np.maximum.at(top, column[rows], i_w[rows])
    near_top = i_w >= top[column] - 2
    return near_margin | near_top


def statuses(bound: np.ndarray, upper: np.ndarray, margin_m: float) -> np.ndarray:
    """Status index (into :data:`STATUSES`) per leaf."""
    status = np.full(bound.size, STATUSES.index("undecided"))
    status[bound > 0.0] = STATUSES.index("collision_free")
    status[(upper < margin_m)] = STATUSES.index("infeasible")
    status[bound >= margin_m] = STATUSES.index("margin")
    return status


def certify_range(
    coefficients: Coefficients,
    config: RangeCertificateConfig | None = None,
    progress: ProgressCallback | None = None,
) -> RegionMap:
    """Certify the whole fitted range of ``coefficients``: the region map (module docstring).

    Args:
        coefficients: Loaded coefficients (any family with jets; the paper's Eq. 9 too).
        config: Settings; default :meth:`RangeCertificateConfig.for_axes` of the coefficients'
            number of axes.
        progress: Called as work finishes, ``progress(stage, done, total)`` for the stages of
            :data:`PROGRESS_STAGES` that have work (e.g. :class:`pipeline.io.progress.ProgressBars`);
            the map does not depend on it.

    Returns:
        The :class:`RegionMap`, linked to the coefficients by their sha256.
    """
    if config is None:
        config = RangeCertificateConfig.for_axes(coefficients.variables.k)
    start = time.perf_counter()
    margin = coefficients.scene.margin_m if config.margin_m is None else config.margin_m
    model = RangeModel.from_coefficients(coefficients)
    found = run_search(model, config.search_settings(margin), config.run_on, progress)
    settings = config.settings_for(margin)
    leaves = [found.levels, found.index, found.bound_m, found.center_clearance_m]
    leaves, endpoint, upper = refine_leaves(model, leaves, settings, progress)
    leaves, endpoint, upper = cut_at_infeasibility(model, leaves, endpoint, upper, settings, progress)
    leaves, endpoint, upper = cut_for_clearance(model, leaves, endpoint, upper, settings, progress)
    (levels, index, bound), endpoint, upper = split_strips(model, leaves, endpoint, upper, settings, progress)
    if config.merge_spread_m > 0.0:
        status = statuses(bound, upper, margin)
        merged = merge_leaves(
            model.ranges_m,
            levels,
            index,
            status,
            (bound, endpoint, upper),
            config.endpoint_tolerance_m,
            config.merge_spread_m,
        )
        levels, index = merged.levels, merged.index
        bound, endpoint, upper = merged.clearance_bound_m, merged.endpoint_bound_m, merged.endpoint_clearance_upper_m
    seconds = time.perf_counter() - start
    return RegionMap.of_leaves(
        model.ranges_m,
        levels,
        index,
        family=coefficients.family.name,
        coefficients_source=source_name(coefficients.source),
        coefficients_sha256=coefficients.source_sha256,
        axes=model.axes.names,
        margin_m=float(margin),
        endpoint_tolerance_m=float(config.endpoint_tolerance_m),
        clearance_bound_m=bound,
        endpoint_bound_m=endpoint,
        endpoint_clearance_upper_m=upper,
        status=statuses(bound, upper, margin),
        seconds=seconds,
        details={  # the map does not depend on where it ran: neither recorded, nor times
            "config": {k: v for k, v in asdict(config).items() if k not in ("jobs", "executor")},
            "boxes_evaluated": found.evaluations,
            "boxes_closed": found.boxes_closed,
        },
    )
