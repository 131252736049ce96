"""Exception hierarchy of the pipeline.

Every error the pipeline raises on bad input derives from :class:`PipelineError`
and carries the offending value, so a caller can report it and a CLI can print
one clear line instead of a traceback.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from decimal import Decimal


class PipelineError(Exception):
    """Base class of every error raised by this project on bad input or state.

    Picklable with its attributes, so that an error raised in a worker process reaches the
    caller as itself (Python pickles an exception as ``cls(*args)``, which fails for
    constructors that take fields rather than the message: the pool then broke with a
    ``TypeError`` in place of the error).
    """

    def __reduce__(self):
        return _rebuild, (type(self), self.args, dict(self.__dict__))


def _rebuild(cls: type, args: tuple, state: dict) -> PipelineError:
    """The inverse of :meth:`PipelineError.__reduce__`: same class, message and attributes."""
    error = cls.__new__(cls, *args)
    Exception.__init__(error, *args)
    error.__dict__.update(state)
    return error


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


class ObstacleSizeError(InvalidParameterError):
    """An obstacle size (L, W) the generator cannot use: not a number, not finite and positive,
    smaller than the rounded corners, or covering the arm's base. The message names L and W.

    Attributes:
        name: "L", "W" or "L, W": the offending size(s).
        value: The offending value(s) as given.
        expected: What was expected instead.
        size: (L, W) as given.
    """

    def __init__(self, name: str, value: object, expected: str, size: tuple[object, object]) -> None:
        self.name = name
        self.value = value
        self.expected = expected
        self.size = size
        shown = ", ".join(
            f"{label} = {number!r} m" if isinstance(number, float) else f"{label} = {number!r}"
            for label, number in zip(("L", "W"), (_plain(v) for v in size), strict=True)
        )
        ValueError.__init__(self, f"{shown}: invalid obstacle size: expected {expected}")


def _variables_text(variables: Mapping[str, object] | None, decimals: int | None) -> str:
    """The text ``, x = 0.0200 m`` for each extra scene variable (name -> value [m]), formatted
    by :func:`format_number` with ``decimals`` (None: the repr of the plain float); "" for none."""
    if not variables:
        return ""
    shown = []
    for name, value in variables.items():
        text = repr(_plain(value)) if decimals is None else format_number(value, decimals)
        shown.append(f", {name} = {text} m")
    return "".join(shown)


def format_number(value: object, decimals: int = 4) -> str:
    """A number as a message shows it: fixed-point with ``decimals`` digits (``0.0500``) from
    10**-decimals up to 1e6 in magnitude (and for 0), general format with as many significant
    digits (``1e+300``, ``2.5e-07``) beyond, so that no message prints a 300-digit number or
    rounds a tiny one to 0; NaN, infinities and non-numbers as their repr."""
    plain = _plain(value)
    if isinstance(plain, int) and not isinstance(plain, bool):  # an integer too large for a float
        return format(Decimal(plain), f".{decimals}e")
    if not isinstance(plain, float) or not math.isfinite(plain):
        return repr(plain)
    if plain == 0.0 or 10.0**-decimals <= abs(plain) < 1e6:
        return f"{plain:.{decimals}f}"
    return f"{plain:.{decimals}g}"


def _plain(value: object) -> object:
    """A number as a plain float (NumPy scalars print as np.float64(...) otherwise)."""
    if isinstance(value, bool):
        return value
    try:
        return float(value) if isinstance(value, int | float) or hasattr(value, "__float__") else value
    except (TypeError, ValueError, OverflowError):
        return value


class ArmMismatchError(PipelineError):
    """The coefficients were fitted for another arm (link lengths or radii) than the one given.

    Attributes:
        expected_lengths_m, expected_radii_m: The coefficients' link lengths and radii [m].
        found_lengths_m, found_radii_m: The arm's [m].
        arm_source: Where the arm came from (its URDF).
    """

    def __init__(
        self,
        expected_lengths_m: tuple[float, float],
        expected_radii_m: tuple[float, float],
        found_lengths_m: tuple[float, float],
        found_radii_m: tuple[float, float],
        arm_source: object,
    ) -> None:
        self.expected_lengths_m = expected_lengths_m
        self.expected_radii_m = expected_radii_m
        self.found_lengths_m = found_lengths_m
        self.found_radii_m = found_radii_m
        self.arm_source = arm_source

        def show(values: tuple[float, float]) -> str:
            return ", ".join(f"{float(v):.6g}" for v in values)

        super().__init__(
            f"the coefficients were fitted for links of {show(expected_lengths_m)} m (radii "
            f"{show(expected_radii_m)} m) but the arm {arm_source} has links of {show(found_lengths_m)} m "
            f"(radii {show(found_radii_m)} m): use coefficients built for this arm"
        )


class RobotModelError(PipelineError):
    """The URDF is missing, unreadable, or not a two-revolute-joint planar arm."""


class UnreachableObstacleError(PipelineError):
    """The obstacle's constraint points lie outside the arm's reach.

    Attributes:
        point_name: Which constraint point is unreachable ("P1", ...).
        radius_m: Its distance from the base [m].
        reach_m: The annulus of reachable radii [m] as ``(min, max)``.
        size_m: The obstacle's (L, W) [m], or None.
        variables: The values of the scene variables beyond L and W (name -> value [m], e.g.
            {"x": 0.02}); {} for none. The message names them after L and W.
    """

    def __init__(
        self,
        point_name: str,
        radius_m: float,
        reach_m: tuple[float, float],
        size_m: tuple[float, float] | None = None,
        variables: Mapping[str, float] | None = None,
    ) -> None:
        self.point_name = point_name
        self.radius_m = radius_m
        self.reach_m = reach_m
        self.size_m = size_m
        self.variables = dict(variables or {})
        prefix = (
            ""
            if size_m is None
            else f"L = {_plain(size_m[0])!r} m, W = {_plain(size_m[1])!r} m{_variables_text(self.variables, None)}: "
        )
        super().__init__(
            f"{prefix}constraint point {point_name} is at {format_number(radius_m)} m from the base, outside "
            f"the arm's reach [{format_number(reach_m[0])}, {format_number(reach_m[1])}] m: the arm cannot pass "
            "this obstacle"
        )


class OutOfFittedRangeError(PipelineError):
    """(L, W), or the value of another scene variable, lies outside the range the regression was fitted on.

    Attributes:
        name: The variable: "L", "W", or another one of the coefficients (e.g. "x").
        value_m: The requested size [m].
        fitted_range_m: The fitted ``(lo, hi)`` [m].
    """

    def __init__(self, name: str, value_m: float, fitted_range_m: tuple[float, float]) -> None:
        self.name = name
        self.value_m = value_m
        self.fitted_range_m = fitted_range_m
        super().__init__(
            f"{name} = {format_number(value_m)} m is outside the fitted range "
            f"[{format_number(fitted_range_m[0])}, {format_number(fitted_range_m[1])}] m (extrapolation)"
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
        length_m, width_m: The obstacle, L and W [m].
        certified_clearance_m: Best certified clearance reached [m].
        margin_m: Required margin [m].
        reason: Why the repair stopped short.
        variables: The values of the scene variables beyond L and W (name -> value [m], e.g.
            {"x": 0.02}); {} for none. The message names them after L and W.
    """

    def __init__(
        self,
        length_m: float,
        width_m: float,
        certified_clearance_m: float,
        margin_m: float,
        reason: str,
        variables: Mapping[str, float] | None = None,
    ) -> None:
        self.length_m = length_m
        self.width_m = width_m
        self.certified_clearance_m = certified_clearance_m
        self.margin_m = margin_m
        self.reason = reason
        self.variables = dict(variables or {})
        where = f"L = {format_number(length_m)} m, W = {format_number(width_m)} m{_variables_text(self.variables, 4)}"
        super().__init__(
            f"no certified trajectory for {where}: best certified clearance "
            f"{format_number(certified_clearance_m * 1e3, 3)} mm < margin {format_number(margin_m * 1e3, 3)} mm "
            f"({reason})"
        )


class UnconvergedCoefficientsWarning(UserWarning):
    """A coefficients file was written by a build that did not converge (``--allow-unconverged``):
    its DOE optima or its regression missed the build's thresholds (the file lists which)."""


class BuildNotConvergedError(PipelineError):
    """A build's DOE optima or regression missed the thresholds; nothing was written.

    Attributes:
        problems: What was missed, one entry per failing experiment (and the regression).
        result: The build's unwritten result, for a caller that wants to look at it.
    """

    def __init__(self, problems: list, result: object = None) -> None:
        self.problems = list(problems)
        self.result = result
        super().__init__(
            f"the build did not converge ({len(self.problems)} problem(s)): "
            + " | ".join(str(p) for p in self.problems)
        )


class InfeasibleSceneError(PipelineError):
    """Somewhere in the (L, W) range the arm's pose at P1 or P5 itself collides with the obstacle,
    so no trajectory that ends there is collision-free: the scene or the range must change.

    Attributes:
        length_m, width_m: The obstacle with the deepest collision [m].
        point_name: "P1" or "P5".
        clearance_m: The pose's clearance there [m] (<= 0).
        count: How many obstacles of the checked grid have such a pose.
        checked: How many obstacles were checked.
    """

    def __init__(
        self, length_m: float, width_m: float, point_name: str, clearance_m: float, count: int, checked: int
    ) -> None:
        self.length_m = length_m
        self.width_m = width_m
        self.point_name = point_name
        self.clearance_m = clearance_m
        self.count = count
        self.checked = checked
        super().__init__(
            f"the arm's pose at {point_name} collides with the obstacle at {count} of {checked} sizes of the range "
            f"(deepest: L = {format_number(length_m, 3)} m, W = {format_number(width_m, 3)} m, clearance "
            f"{format_number(clearance_m * 1e3, 2)} mm), so no "
            "trajectory ending there is collision-free: narrow --L-range/--W-range or move the obstacle "
            "(--top-y, --scene)"
        )


class RegionMapMismatchError(PipelineError):
    """A region map was used with coefficients other than those it certifies.

    Attributes:
        map_coefficients_sha256: The sha256 of the coefficients the map was made for.
        coefficients_sha256: The sha256 of the coefficients in use.
    """

    def __init__(self, map_coefficients_sha256: str, coefficients_sha256: str) -> None:
        self.map_coefficients_sha256 = map_coefficients_sha256
        self.coefficients_sha256 = coefficients_sha256
        super().__init__(
            f"the region map certifies coefficients sha256 {map_coefficients_sha256[:12]}, "
            f"not these (sha256 {coefficients_sha256[:12]}); run python -m pipeline.certify_range on them"
        )


class RegionMapLimitsError(PipelineError):
    """A region map's execution bounds were asked for an arm other than the one they were made for.

    Attributes:
        quantity: What differs (a limit's name, or the inertia).
        map_value: The map's value.
        given_value: The given arm's value.
    """

    def __init__(self, quantity: str, map_value: object, given_value: object) -> None:
        self.quantity = quantity
        self.map_value = map_value
        self.given_value = given_value
        super().__init__(
            f"the region map's execution bounds were made for {quantity} {map_value}, not {given_value}; "
            "build the map with this arm (python -m pipeline.build --urdf ... --acceleration-limit ...)"
        )


class RegionMapMismatchWarning(UserWarning):
    """The region map beside a coefficients file certifies other coefficients: it is not attached."""


class WorkerPoolError(PipelineError):
    """The worker processes of a pool stopped before finishing their work.

    Attributes:
        reason: What stopped them, as far as the caller can tell.
    """

    def __init__(self, reason: str) -> None:
        self.reason = reason
        super().__init__(
            f"the worker processes stopped ({reason}); a script that starts them (jobs other than 1) must call "
            'the work under `if __name__ == "__main__":`, since each worker re-imports the script'
        )


class SchedulerUnreachableError(PipelineError):
    """The Dask scheduler the work was to run on cannot be reached (checked before any work).

    Attributes:
        address: The scheduler's address as given.
        reason: What the connection attempt said.
    """

    def __init__(self, address: str, reason: str) -> None:
        self.address = address
        self.reason = reason
        super().__init__(f"cannot reach the Dask scheduler at {address}: {' '.join(str(reason).split())}")


class ExecutionRefusedError(PipelineError):
    """A trajectory certified collision-free is not certified to execute: an endpoint error
    beyond the tolerance, or a joint angle, speed, acceleration or torque beyond the arm's limits.

    Attributes:
        length_m, width_m: The obstacle, L and W [m].
        timing_name: The timing that was certified ("paper" or "rest-to-rest"; None for an
            endpoint error, which no timing changes).
        reasons: One line per failed check, naming the joint, the bound, the limit and the excess.
        variables: The values of the scene variables beyond L and W (name -> value [m], e.g.
            {"x": 0.02}); {} for none. The message names them after L and W.
    """

    def __init__(
        self,
        length_m: float,
        width_m: float,
        timing_name: str | None,
        reasons: tuple[str, ...],
        variables: Mapping[str, float] | None = None,
    ) -> None:
        self.length_m = length_m
        self.width_m = width_m
        self.timing_name = timing_name
        self.reasons = tuple(reasons)
        self.variables = dict(variables or {})
        timing = "" if timing_name is None else f" with the {timing_name} timing"
        where = f"L = {format_number(length_m)} m, W = {format_number(width_m)} m{_variables_text(self.variables, 4)}"
        super().__init__(f"no executable trajectory for {where}{timing}: " + "; ".join(self.reasons))


class TimingRefusedError(PipelineError):
    """No timing of a path keeps the limits: the path's angles leave them, a limit binds at rest,
    or no profile tried was certified (:func:`pipeline.motion.near_optimal.near_optimal_timing`).

    Attributes:
        reasons: One line per failed check, naming the joint, the certified bound and the limit.
    """

    def __init__(self, reasons: tuple[str, ...]) -> None:
        self.reasons = tuple(reasons)
        super().__init__("no certified timing: " + "; ".join(self.reasons))


class MissingDependencyError(PipelineError):
    """An optional package that a requested feature needs is not installed (checked before any work).

    Attributes:
        package: The missing package, as pip names it.
        extra: The extra of this project that installs it.
        purpose: What needed it (e.g. "writing a ROS 2 bag").
    """

    def __init__(self, package: str, extra: str, purpose: str) -> None:
        self.package = package
        self.extra = extra
        self.purpose = purpose
        super().__init__(f"{purpose} needs {package}: pip install 'twolink-obstacle[{extra}]'")


class OutputLockedError(PipelineError):
    """Another build is writing the output folder: its lock file is there and its process is
    alive, or runs on another host, or the lock cannot be read (checked before any work).

    Attributes:
        folder: The output folder.
        lock_path: The lock file in it.
        pid: The process holding the lock (None: the lock cannot be read).
        host: The host that process runs on (None: the lock cannot be read).
        elsewhere: True if that host is not this one (its process cannot be checked from here).
    """

    def __init__(self, folder: object, lock_path: object, pid: int | None, host: str | None, elsewhere: bool) -> None:
        self.folder = folder
        self.lock_path = lock_path
        self.pid = pid
        self.host = host
        self.elsewhere = elsewhere
        holder = "another build (its lock cannot be read)" if pid is None else f"the build of process {pid}"
        if pid is not None and elsewhere:
            holder += f" on {host}"
        super().__init__(f"{folder}/ is being written by {holder} (lock {lock_path}); wait for it or remove the lock")


class NoSceneWindowError(PipelineError):
    """No far edge d of the obstacle lets an arm pass a range of obstacles: for every d some
    constraint point leaves the arm's reach, or an end pose keeps less than the required clearance.

    Attributes:
        length_range_m, width_range_m: The (L, W) range asked for [m].
        reasons: The constraints that close the window, one phrase each.
        lowest_m: The least d the constraints below ask for [m] (None: not known).
        highest_m: The most d the constraints above allow [m] (None: not known).
        shrink_tried: True if shrunk L and W ranges were tried too.
    """

    def __init__(
        self,
        length_range_m: tuple[float, float],
        width_range_m: tuple[float, float],
        reasons: tuple[str, ...],
        lowest_m: float | None,
        highest_m: float | None,
        shrink_tried: bool,
    ) -> None:
        self.length_range_m = length_range_m
        self.width_range_m = width_range_m
        self.reasons = tuple(reasons)
        self.lowest_m = lowest_m
        self.highest_m = highest_m
        self.shrink_tried = shrink_tried
        (l0, l1), (w0, w1) = length_range_m, width_range_m
        nor = ", nor a shrunk L or W range" if shrink_tried else ""
        super().__init__(
            f"no d (the obstacle's far edge y, --top-y) fits L in [{l0:.3f}, {l1:.3f}] m, W in [{w0:.3f}, {w1:.3f}] m"
            f"{nor}: " + "; ".join(self.reasons)
        )
