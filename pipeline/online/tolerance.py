"""The endpoint tolerance an answer is held to by default (one rule for every online route)."""

from __future__ import annotations

from pipeline.offline.coefficients import Coefficients

__all__ = ["PINNED_ENDPOINT_TOLERANCE_M", "PLAIN_FIT_ENDPOINT_TOLERANCE_M", "endpoint_tolerance_of"]

#: Endpoint tolerance [m] of a family that pins the endpoints (exact up to rounding).
PINNED_ENDPOINT_TOLERANCE_M = 1e-9
#: Endpoint tolerance [m] of coefficients fitted without an endpoint constraint: such a fit holds
#: none, and the paper's Eq. 9 misses P1 or P5 by up to 8.4 mm over its range; 1 cm accepts its
#: answers (each carries its own endpoint errors) and still refuses a grossly wrong file.
PLAIN_FIT_ENDPOINT_TOLERANCE_M = 0.01


def endpoint_tolerance_of(coefficients: Coefficients) -> float:
    """The endpoint tolerance [m] an answer of ``coefficients`` is held to by default: 1 nm for a
    family that pins the endpoints; the tolerance the regression was fitted to hold (recorded in
    the file, 2 mm for the build's default); 1 cm for a plain fit, which holds none
    (:data:`PLAIN_FIT_ENDPOINT_TOLERANCE_M`)."""
    if coefficients.family.pins_endpoints:
        return PINNED_ENDPOINT_TOLERANCE_M
    recorded = coefficients.extra.get("fit", {}).get("endpoint_constraint", {}).get("tolerance_m")
    if isinstance(recorded, int | float) and not isinstance(recorded, bool) and recorded > 0:
        return float(recorded)
    return PLAIN_FIT_ENDPOINT_TOLERANCE_M
