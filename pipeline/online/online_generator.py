"""One object for the online side: ``g = pipeline.load("results")``, then ``g(L, W)``.

:func:`load` reads a build's results folder (or a coefficients file, or ``"paper"``) with the range
certificate beside it and returns an :class:`OnlineGenerator`, which owns the coefficients, their
map and, loaded on first use, the arm, its recorded limits and its dynamics (the coefficients'
:class:`pipeline.online.query_state.QueryState`). Its methods are the online functions with these
coefficients bound: ``g(L, W, x=..., d=...)`` is :func:`pipeline.online.generator.generate`,
``g.batch`` :func:`pipeline.online.batch.generate_batch`, ``g.certified``
:func:`pipeline.online.repair.generate_certified`, ``g.certify_batch``
:func:`pipeline.online.batch_certify.certify_batch` and ``g.execution_batch``
:func:`pipeline.online.batch_execution.execution_batch`, ``g.near_optimal``
:func:`pipeline.online.map_timing.near_optimal_from_map`; their keywords and errors are those
functions'. The functions stay, and an object and a function given the same coefficients share one
state and give the same answers.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from pipeline.exceptions import InvalidParameterError
from pipeline.offline.coefficients import Coefficients
from pipeline.online.batch import GeneratedBatch, generate_batch
from pipeline.online.batch_execution import ExecutionBatch, execution_batch
from pipeline.online.generator import GeneratedTrajectory, generate
from pipeline.online.loading import load_coefficients
from pipeline.online.map_timing import MapTiming, near_optimal_from_map
from pipeline.online.query_state import QueryState, state_of

if TYPE_CHECKING:  # Pinocchio and Coal: loaded by the methods that certify, on first use
    from pipeline.model.arm import PlanarArm
    from pipeline.model.dynamics import PlanarDynamics
    from pipeline.model.limits import ArmLimits
    from pipeline.online.batch_certify import CertifiedBatch
    from pipeline.online.repair import CertifiedTrajectory

__all__ = ["COEFFICIENTS_FILE_NAME", "OnlineGenerator", "load"]

#: The coefficients' file name in a build's results folder.
COEFFICIENTS_FILE_NAME = "coefficients.json"


class OnlineGenerator:
    """Trajectories for new obstacles from one set of coefficients (module docstring).

    Attributes:
        coefficients: The coefficients, with their region map attached (or None).
    """

    __slots__ = ("_state", "coefficients")

    def __init__(self, coefficients: Coefficients) -> None:
        self._state: QueryState = state_of(coefficients)
        self.coefficients = coefficients

    def __repr__(self) -> str:
        names = ", ".join(self.coefficients.variables.names)
        mapped = "a region map" if self.region_map is not None else "no region map"
        return f"OnlineGenerator({self.coefficients.source!r}, variables ({names}), {mapped})"

    @property
    def region_map(self):
        """The range certificate of the coefficients (a ``RegionMap``), or None."""
        return self.coefficients.region_map

    @property
    def arm(self) -> PlanarArm:
        """The arm the coefficients were fitted with, loaded from its URDF on first use."""
        return self._state.arm

    @property
    def limits(self) -> ArmLimits:
        """The arm's limits as the build recorded them (acceleration limits included)."""
        return self._state.limits

    @property
    def dynamics(self) -> PlanarDynamics:
        """The arm's closed-form dynamics, identified on first use."""
        return self._state.dynamics

    def __call__(self, length_m: float, width_m: float, **options) -> GeneratedTrajectory:
        """The trajectory for the obstacle L x W [m]: :func:`pipeline.online.generator.generate`."""
        return generate(self.coefficients, length_m, width_m, **options)

    def batch(self, lengths_m, widths_m, **options) -> GeneratedBatch:
        """n trajectories at once: :func:`pipeline.online.batch.generate_batch`."""
        return generate_batch(self.coefficients, lengths_m, widths_m, **options)

    def certified(self, length_m: float, width_m: float, **options) -> CertifiedTrajectory:
        """The certified (if needed repaired) trajectory, with its execution:
        :func:`pipeline.online.repair.generate_certified`, with the recorded arm and limits unless given."""
        from pipeline.online.repair import generate_certified

        return generate_certified(self.coefficients, length_m, width_m, **options)

    def certify_batch(self, batch: GeneratedBatch, **options) -> CertifiedBatch:
        """Per-query clearance certificates of a batch: :func:`pipeline.online.batch_certify.certify_batch`."""
        from pipeline.online.batch_certify import certify_batch

        return certify_batch(self.coefficients, batch, **options)

    def near_optimal(self, length_m: float, width_m: float, **variables) -> MapTiming:
        """The certified near-optimal answer read off the map, at lookup cost:
        :func:`pipeline.online.map_timing.near_optimal_from_map`."""
        return near_optimal_from_map(self.coefficients, length_m, width_m, **variables)

    def execution_batch(self, batch: GeneratedBatch, **options) -> ExecutionBatch:
        """The batch's execution bounds from the map: :func:`pipeline.online.batch_execution.execution_batch`."""
        return execution_batch(self.coefficients, batch, **options)


def load(source: str | os.PathLike, **options) -> OnlineGenerator:
    """The :class:`OnlineGenerator` of a build's results folder, a coefficients file or ``"paper"``.

    Args:
        source: A folder holding ``coefficients.json`` (as ``python -m pipeline.build`` writes it),
            the path of a coefficients file, or ``"paper"`` (the paper's Eq. 9).
        options: As :func:`pipeline.online.loading.load_coefficients` (``region_map=``).

    Raises:
        InvalidParameterError: ``source`` is not a path or ``"paper"``.
        DataFileError: the folder holds no coefficients file, or a file is missing, unreadable or
            malformed.
        RegionMapMismatchError: a region map named by ``region_map=`` certifies other coefficients.
    """
    if isinstance(source, bytes) or not isinstance(source, str | os.PathLike):
        raise InvalidParameterError("source", source, "a results folder, a coefficients file or 'paper'")
    path = Path(source)
    if str(source) != "paper" and path.is_dir():
        path = path / COEFFICIENTS_FILE_NAME
        source = path
    return OnlineGenerator(load_coefficients(source, **options))
