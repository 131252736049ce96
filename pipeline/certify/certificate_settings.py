"""What the range certificate's stages share: :class:`CertificateSettings`, made from a
:class:`pipeline.certify.range_certificate.RangeCertificateConfig` once the margin is known."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.certify.subpaving import open_axes
from pipeline.exceptions import InvalidParameterError
from pipeline.io.executor import DaskScheduler, Executor, LocalPool
from pipeline.validation import check_bool, check_non_negative, check_positive_int

__all__ = ["CertificateSettings"]


@dataclass(frozen=True, kw_only=True)
class CertificateSettings:
    """The settings of the certificate's stages after the search (the leaves' bounds, the
    sub-cells, the strips).

    Attributes:
        margin_m: The clearance the statuses refer to [m].
        endpoint_tolerance_m: The endpoint tolerance of the infeasibility certificate [m].
        max_depth: Level of the smallest cell (cells of 1 / 2^max_depth of the range): a cell
            whose levels sum to k times it is cut no further.
        extra_depth: Levels beyond ``max_depth`` a cell may reach along one axis.
        max_depth_s: Deepest cut of s = t / T (intervals of 1 / 2^depth).
        strip_split: Halvings along W of the smallest cells that miss the margin without being
            proven infeasible (0: none; ``pipeline.certify.strip_split``).
        infeasibility_cuts: Levels along W (2^cuts of them) at which a leaf still close to being
            proven infeasible may be cut, its part above proven (0: none;
            ``pipeline.certify.infeasibility_cuts``).
        tilt_cuts: Halvings of a leaf the infeasibility contour crosses, along the axis that tilts
            the contour across it, before it is cut along W (0: none).
        clearance_cuts: Rounds of halving the leaves that miss the margin where their boxes'
            centres keep it, along their steepest axis (0: none; ``pipeline.certify.clearance_cuts``).
        second_order: Bound the clearance and the endpoint errors by the tighter of the
            mean-value and the second-order Taylor forms (``pipeline.certify.clearance_bound``,
            ``pipeline.certify.endpoints``); False: the mean-value form.
        run_on: Where the tasks run: ``LocalPool(jobs)`` or a ``DaskScheduler`` (the bounds do
            not depend on it).
    """

    margin_m: float
    endpoint_tolerance_m: float
    max_depth: int
    extra_depth: int = 0
    max_depth_s: int = 16
    strip_split: int = 0
    infeasibility_cuts: int = 0
    tilt_cuts: int = 0
    clearance_cuts: int = 0
    second_order: bool = False
    run_on: Executor = field(default_factory=LocalPool)

    def __post_init__(self) -> None:
        check_non_negative("margin_m", self.margin_m)
        check_non_negative("endpoint_tolerance_m", self.endpoint_tolerance_m)
        check_positive_int("max_depth", self.max_depth, minimum=0)
        check_positive_int("extra_depth", self.extra_depth, minimum=0)
        check_positive_int("max_depth_s", self.max_depth_s, minimum=1)
        check_positive_int("strip_split", self.strip_split, minimum=0)
        check_positive_int("infeasibility_cuts", self.infeasibility_cuts, minimum=0)
        check_positive_int("tilt_cuts", self.tilt_cuts, minimum=0)
        check_positive_int("clearance_cuts", self.clearance_cuts, minimum=0)
        check_bool("second_order", self.second_order)
        if not isinstance(self.run_on, LocalPool | DaskScheduler):
            raise InvalidParameterError("run_on", self.run_on, "a LocalPool or a DaskScheduler")

    def open_axes(self, levels: np.ndarray) -> np.ndarray:
        """Per cell (levels (n, k)) and axis, whether a cut along it is allowed: the axis is below
        ``max_depth + extra_depth`` and the cell larger than the smallest cell's volume."""
        return open_axes(levels, self.max_depth, self.extra_depth)
