"""Trajectory families: objects with one interface (:class:`TrajectoryFamily`), one module each.

* :data:`PAPER` (``paper``): all eight sinusoid parameters free, as in the paper.
* :data:`EXACT_ENDPOINTS` (``exact-endpoints``): the tip pinned to P1 and P5 by construction.

Files and command lines name a family; :func:`family_from_name` turns the name into the object.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from pipeline.exceptions import InvalidParameterError
from pipeline.motion.families.base import CONTEXT_NAMES, EndpointContext, TrajectoryFamily, endpoint_context
from pipeline.motion.families.exact_endpoints import EXACT_ENDPOINTS, ExactEndpointsFamily
from pipeline.motion.families.paper import PAPER, PAPER_SOURCE, PaperFamily

#: Every family, by name.
FAMILIES: Mapping[str, TrajectoryFamily] = MappingProxyType(
    {family.name: family for family in (PAPER, EXACT_ENDPOINTS)}
)
FAMILY_NAMES: tuple[str, ...] = tuple(FAMILIES)


def family_from_name(name: object) -> TrajectoryFamily:
    """The family called ``name``.

    Raises:
        InvalidParameterError: no family has that name.
    """
    family = FAMILIES.get(name) if isinstance(name, str) else None
    if family is None:
        raise InvalidParameterError("family", name, f"one of {FAMILY_NAMES}")
    return family


__all__ = [
    "CONTEXT_NAMES",
    "EXACT_ENDPOINTS",
    "FAMILIES",
    "FAMILY_NAMES",
    "PAPER",
    "PAPER_SOURCE",
    "EndpointContext",
    "ExactEndpointsFamily",
    "PaperFamily",
    "TrajectoryFamily",
    "endpoint_context",
    "family_from_name",
]
