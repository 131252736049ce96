"""Exception hierarchy of the pipeline.

Every error the pipeline raises on bad input derives from :class:`PipelineError`
and carries the offending value, so a caller can report it and a CLI can print
one clear line instead of a traceback.
"""

from __future__ import annotations


class PipelineError(Exception):
    """Base class of every error raised by this project on bad input or state."""


class InvalidParameterError(PipelineError, ValueError):
    """A configuration value is out of its domain (NaN, non-positive, ...).

    Attributes:
        name: Name of the offending parameter.
        value: The offending value.
        expected: What was expected instead.
    """

    def __init__(self, name: str, value: object, expected: str) -> None:
        self.name = name
        self.value = value
        self.expected = expected
        super().__init__(f"{name} = {value!r} is invalid: expected {expected}")


class RobotModelError(PipelineError):
    """The URDF is missing, unreadable, or not a two-revolute-joint planar arm."""


class UnreachableObstacleError(PipelineError):
    """The obstacle's constraint points lie outside the arm's reach.

    Attributes:
        point_name: Which constraint point is unreachable ("P1", ...).
        radius_m: Its distance from the base [m].
        reach_m: The annulus of reachable radii [m] as ``(min, max)``.
    """

    def __init__(self, point_name: str, radius_m: float, reach_m: tuple[float, float]) -> None:
        self.point_name = point_name
        self.radius_m = radius_m
        self.reach_m = reach_m
        super().__init__(
            f"constraint point {point_name} is at {radius_m:.4f} m from the base, outside "
            f"the arm's reach [{reach_m[0]:.4f}, {reach_m[1]:.4f}] m: the arm cannot pass "
            "this obstacle"
        )


class OutOfFittedRangeError(PipelineError):
    """(L, W) lies outside the range the regression was fitted on.

    Attributes:
        name: "L" or "W".
        value_m: The requested size [m].
        fitted_range_m: The fitted ``(lo, hi)`` [m].
    """

    def __init__(self, name: str, value_m: float, fitted_range_m: tuple[float, float]) -> None:
        self.name = name
        self.value_m = value_m
        self.fitted_range_m = fitted_range_m
        super().__init__(
            f"{name} = {value_m:.4f} m is outside the fitted range "
            f"[{fitted_range_m[0]:.4f}, {fitted_range_m[1]:.4f}] m (extrapolation)"
        )


class OutOfFittedRangeWarning(UserWarning):
    """(L, W) lies outside the fitted range and extrapolation was allowed."""


class EndpointConstraintWarning(UserWarning):
    """The endpoint-constrained regression stopped before meeting its tolerance everywhere."""


class InexactEndpointsWarning(UserWarning):
    """A family that pins the tip to P1 and P5 could not, for these parameters (see the family's module)."""


class DataFileError(PipelineError):
    """A DOE or coefficients file is missing, unreadable or malformed.

    Attributes:
        path: The file in question.
        reason: What is wrong with it.
    """

    def __init__(self, path: object, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: {reason}")


class OutputExistsError(PipelineError):
    """An output file exists and overwriting was not allowed."""


class NoCertifiedTrajectoryError(PipelineError):
    """No trajectory with a certified clearance of at least the margin was found.

    Attributes:
        L_m, W_m: The obstacle [m].
        certified_clearance_m: Best certified clearance reached [m].
        margin_m: Required margin [m].
    """

    def __init__(self, L_m: float, W_m: float, certified_clearance_m: float, margin_m: float, reason: str) -> None:
        self.L_m = L_m
        self.W_m = W_m
        self.certified_clearance_m = certified_clearance_m
        self.margin_m = margin_m
        self.reason = reason
        super().__init__(
            f"no certified trajectory for L = {L_m:.4f} m, W = {W_m:.4f} m: best certified "
            f"clearance {certified_clearance_m * 1e3:.3f} mm < margin {margin_m * 1e3:.3f} mm "
            f"({reason})"
        )


class ViewerError(PipelineError):
    """The Meshcat viewer or the headless browser could not start, serve or render."""
