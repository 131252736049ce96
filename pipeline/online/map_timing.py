"""The near-optimal timing of an obstacle at lookup cost: ``g.near_optimal(L, W)``.

For the regression's own answer, the region map proves its clearance and endpoint error for
every obstacle of its leaf, and the map's near-optimal cells (:mod:`pipeline.certify.near_optimal_cells`)
a timing and its bounds for every obstacle of the cell, within the limits of the arm the build
recorded (with the servo defaults). When all three hold (clearance at least the scene's margin,
endpoint bound within the tolerance, a certified cell), the answer is certified in full without a
per-query certificate: :func:`near_optimal_from_map` returns it after one generation and one cell
lookup, and builds the executed motion only when it is asked for. Anything the map does not decide
is refused in one line naming the per-query call, ``generate_certified(..., timing=NEAR_OPTIMAL)``,
which repairs or certifies it. NumPy only: neither Pinocchio nor Coal is loaded.
"""

from __future__ import annotations

from functools import cached_property
from typing import TYPE_CHECKING

from pipeline.exceptions import ExecutionRefusedError, InvalidParameterError
from pipeline.motion.execution_certificate import ExecutionCertificate
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.offline.coefficients import Coefficients
from pipeline.online.generator import GeneratedTrajectory, generate
from pipeline.online.tolerance import endpoint_tolerance_of

if TYPE_CHECKING:
    from pipeline.certify.near_optimal_cells import NearOptimalCells

__all__ = ["MapTiming", "near_optimal_from_map"]

_PER_QUERY = "generate_certified(..., timing=NEAR_OPTIMAL) repairs or certifies it per query"


class MapTiming:
    """A certified near-optimal answer read off the map (module docstring).

    Attributes:
        generated: The regression's answer, with the map's clearance and endpoint bounds.
        cell: The near-optimal cell holding the obstacle.
        duration_s: T' [s], the cell's.
        certificate: The cell's bounds (angles, |dq|, |ddq|, |tau|, |jerk|), proven for every
            obstacle of the cell, decided against ``certificate.decided_against``.
    """

    __slots__ = ("__dict__", "_cells", "cell", "certificate", "duration_s", "generated")

    def __init__(self, generated: GeneratedTrajectory, cells: NearOptimalCells, cell: int) -> None:
        self.generated = generated
        self._cells = cells
        self.cell = cell
        self.certificate: ExecutionCertificate = cells.certificate(cell)
        self.duration_s: float = self.certificate.duration_s

    @property
    def certified_clearance_m(self) -> float:
        """The map's proven clearance of the motion [m]."""
        return self.generated.certified_clearance_m

    @property
    def endpoint_error_bound_m(self) -> float:
        """The map's proven bound of the endpoint errors [m]."""
        return self.generated.endpoint_error_bound_m

    @cached_property
    def executed(self) -> TimedTrajectory:
        """The path with the cell's timing ``T sigma`` (built on first use)."""
        trajectory = self.generated.trajectory
        return TimedTrajectory(trajectory, self._cells.timing(self.cell, trajectory.duration_s))


def near_optimal_from_map(coefficients: Coefficients, length_m: float, width_m: float, **variables) -> MapTiming:
    """The certified near-optimal answer for the obstacle L x W [m] (and x, d [m] where the
    coefficients vary them), read off the attached map (module docstring).

    Raises:
        InvalidParameterError: no map, or a map without near-optimal cells; a bad obstacle (as
            :func:`pipeline.online.generator.generate`).
        ExecutionRefusedError: the map does not certify this obstacle in full (the reason, and the
            per-query call that decides it).
    """
    region_map = coefficients.region_map
    cells = None if region_map is None else region_map.near_optimal_cells
    if cells is None:
        raise InvalidParameterError(
            "region_map", "without near-optimal cells", "a map with them (python -m pipeline.build writes them)"
        )
    generated = generate(coefficients, length_m, width_m, **variables)
    reason = _undecided(coefficients, generated)
    cell = None
    if reason is None:  # the answer's variables in the coefficients' order, whatever the keywords' order
        values = dict(generated.variables)
        cell = cells.cell_of(length_m, width_m, *(values[name] for name in cells.axes[2:] if name in values))
        reason = "no certified near-optimal cell holds it" if cell is None else None
    if reason is not None:
        raise ExecutionRefusedError(length_m, width_m, "near-optimal", (f"{reason}; {_PER_QUERY}",), variables)
    return MapTiming(generated, cells, cell)


def _undecided(coefficients: Coefficients, generated: GeneratedTrajectory) -> str | None:
    """Why the map does not certify the answer's clearance and endpoints, or None."""
    clearance, endpoint = generated.certified_clearance_m, generated.endpoint_error_bound_m
    margin, tolerance = coefficients.scene.margin_m, endpoint_tolerance_of(coefficients)
    if clearance is None or endpoint is None:
        return "outside the map's range"
    if not clearance >= margin:
        return f"the map's clearance bound {1e3 * clearance:.3f} mm is below the margin {1e3 * margin:.3f} mm"
    if not endpoint <= tolerance:
        return f"the map's endpoint error bound {1e3 * endpoint:.3f} mm exceeds the tolerance {1e3 * tolerance:.3f} mm"
    return None
