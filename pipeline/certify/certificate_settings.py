"""What the range certificate's stages share: :class:`CertificateSettings`, made from a
:class:`pipeline.certify.range_certificate.RangeCertificateConfig` once the margin is known."""

from __future__ import annotations

from dataclasses import dataclass, field

from pipeline.exceptions import InvalidParameterError
from pipeline.io.executor import DaskScheduler, Executor, LocalPool
from pipeline.validation import check_non_negative, check_positive_int

__all__ = ["CertificateSettings"]


@dataclass(frozen=True, kw_only=True)
class CertificateSettings:
    """The settings of the certificate's stages after the search (the leaves' bounds, the
    sub-cells, the strips).

    Attributes:
        margin_m: The clearance the statuses refer to [m].
        endpoint_tolerance_m: The endpoint tolerance of the infeasibility certificate [m].
        max_depth: Deepest level of a cell along any axis (cells of 1 / 2^max_depth of the range).
        max_depth_s: Deepest cut of s = t / T (intervals of 1 / 2^depth).
        strip_split: Halvings along W of the smallest cells that miss the margin without being
            proven infeasible (0: none; ``pipeline.certify.strip_split``).
        run_on: Where the tasks run: ``LocalPool(jobs)`` or a ``DaskScheduler`` (the bounds do
            not depend on it).
    """

    margin_m: float
    endpoint_tolerance_m: float
    max_depth: int
    max_depth_s: int = 16
    strip_split: int = 0
    run_on: Executor = field(default_factory=LocalPool)

    def __post_init__(self) -> None:
        check_non_negative("margin_m", self.margin_m)
        check_non_negative("endpoint_tolerance_m", self.endpoint_tolerance_m)
        check_positive_int("max_depth", self.max_depth, minimum=0)
        check_positive_int("max_depth_s", self.max_depth_s, minimum=1)
        check_positive_int("strip_split", self.strip_split, minimum=0)
        if not isinstance(self.run_on, LocalPool | DaskScheduler):
            raise InvalidParameterError("run_on", self.run_on, "a LocalPool or a DaskScheduler")
