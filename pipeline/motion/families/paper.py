"""The paper's family: all eight sinusoid parameters are free, as in the paper's PSO and Eq. 9.

The endpoints are whatever the eight parameters give: the fitness pulls the tip towards P1 and
P5 (Eq. 5's weighted end points), nothing pins it there.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from pipeline.motion.families.base import EndpointContext, TrajectoryFamily
from pipeline.motion.trajectory import PARAMETER_NAMES, canonicalize

#: Source name of the paper's own Eq. 9 coefficients and Table 2 optima, shipped with the package.
PAPER_SOURCE = "paper"


@dataclass(frozen=True)
class PaperFamily(TrajectoryFamily):
    """All 8 parameters free; :meth:`expand` is the identity."""

    name: ClassVar[str] = "paper"
    free_parameter_names: ClassVar[tuple[str, ...]] = PARAMETER_NAMES
    pins_endpoints: ClassVar[bool] = False
    uses_endpoint_context: ClassVar[bool] = False
    expands_to_itself: ClassVar[bool] = True

    def expand(self, free: np.ndarray, context: EndpointContext | None) -> np.ndarray:
        return np.asarray(free, dtype=float)

    def canonical_free(self, free: np.ndarray) -> np.ndarray:
        """The 8 parameters in the canonical form of :func:`pipeline.motion.trajectory.canonicalize`."""
        return canonicalize(np.asarray(free, dtype=float))

    def expand_jacobians(self, free: np.ndarray, context: EndpointContext | None) -> tuple[np.ndarray, np.ndarray]:
        free = np.asarray(free, dtype=float)
        batch = free.shape[:-1]
        return np.broadcast_to(np.eye(8), (*batch, 8, 8)).copy(), np.zeros((*batch, 8, 5))

    def endpoints_exact(self, free: np.ndarray, context: EndpointContext | None) -> np.ndarray:
        return np.zeros(np.shape(free)[:-1], dtype=bool)


PAPER = PaperFamily()
