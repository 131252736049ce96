"""Coefficients files: the closed-form parameters(L, W) the online generator evaluates.

``coefficients.json`` holds, per free parameter of the trajectory family, the six
coefficients of :data:`pipeline.offline.regression.BASIS`, the (L, W) range they were fitted on,
and the scene and arm they assume. ``PAPER_SOURCE`` names the paper's own Eq. 9, shipped with
the package (``pipeline/data/paper_eq9_coefficients.json``).

Coefficients over more scene variables than L and W (:mod:`pipeline.offline.variables`, e.g.
the obstacle's centre x) name them: ``"variables": ["L", "W", "x"]``, written only when they are
not exactly (L, W), so an (L, W) file keeps its bytes. Their ``basis`` is the full quadratic in
those variables and ``fitted_range`` has one entry per variable. The scene is the base scene
(its ``centre_x_m`` is 0); a variable's value replaces its scene field per answer.
"""

from __future__ import annotations

import hashlib
import math
import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np

from pipeline.exceptions import DataFileError, InvalidParameterError, PipelineError, UnconvergedCoefficientsWarning
from pipeline.io.jsonio import dumps, read_json, write_text_atomic
from pipeline.model.scene import Scene
from pipeline.motion.families import PAPER_SOURCE, TrajectoryFamily, family_from_name
from pipeline.offline.endpoint_regression import EndpointConstraint, endpoint_targets, fit_points_with_endpoints
from pipeline.offline.regression import QuadraticFit, fit_quadratic_points, predict, predict_points
from pipeline.offline.variables import DEFAULT_VARIABLES, SIZE, Variables, variables_in

FORMAT = "twolink-coefficients/1"
PAPER = PAPER_SOURCE
#: Top-level key of a file written by a build that did not converge: ``false`` (absent: converged).
CONVERGED_KEY = "converged"
#: Top-level key listing what such a build missed (one string per failing experiment or fit).
UNCONVERGED_REASONS_KEY = "unconverged_reasons"


def paper_data_path(name: str) -> Path:
    """Path of a data file shipped with the package (the paper's Table 2 and Eq. 9)."""
    return Path(str(resources.files("pipeline") / "data" / name))


@dataclass(frozen=True, eq=False)
class Coefficients:
    """Regression coefficients of one trajectory family.

    Attributes:
        family: The trajectory family the coefficients span.
        parameters: Free-parameter name -> (b0..b5) in BASIS order (``variables.basis`` order).
        fitted_range_m: {"L": (lo, hi), "W": (lo, hi)} [m], and one (lo, hi) per extra variable.
        scene: The scene the coefficients were fitted in.
        link_lengths_m: (l1, l2) of the arm [m].
        link_radii_m: (r1, r2) link capsule radii [m].
        elbow: Elbow branch (+1 / -1) of the exact-endpoints inverse kinematics.
        extra: Everything else in the file (fit quality, provenance), kept as read.
        source: Where the coefficients came from (a path or PAPER_SOURCE).
        source_sha256: SHA-256 of the file's bytes.
        region_map: The range certificate of these coefficients (a
            :class:`pipeline.certify.region_map.RegionMap` whose sha256 link matches
            ``source_sha256``), attached by :func:`pipeline.read_coefficients`; None without one.
            The generator's answers carry its bounds.
        variables: The scene variables the coefficients vary (default (L, W); always with L and W).
        online_state: The state the online queries of these coefficients share, made on first use.
    """

    family: TrajectoryFamily
    parameters: dict[str, tuple[float, ...]]
    fitted_range_m: dict[str, tuple[float, float]]
    scene: Scene
    link_lengths_m: tuple[float, float]
    link_radii_m: tuple[float, float]
    elbow: int = 1
    extra: dict = field(default_factory=dict)
    source: str = ""
    source_sha256: str = ""
    region_map: object = field(default=None, repr=False)
    variables: Variables = DEFAULT_VARIABLES
    #: What the online queries of this object share (a ``pipeline.online.query_state.QueryState``),
    #: made on the first query and owned by this object: not a field of the file, not pickled.
    online_state: object = field(default=None, init=False, repr=False, compare=False)

    def __getstate__(self) -> dict:
        """Pickled without :attr:`online_state` (a worker builds its own on its first query)."""
        return {**self.__dict__, "online_state": None}

    @property
    def converged(self) -> bool:
        """False if the file was written by a build that did not converge (``--allow-unconverged``)."""
        return self.extra.get(CONVERGED_KEY, True) is not False

    @property
    def unconverged_reasons(self) -> tuple[str, ...]:
        """What the build missed (empty if it converged)."""
        return tuple(str(r) for r in self.extra.get(UNCONVERGED_REASONS_KEY, ()))

    def marked_unconverged(self, reasons) -> Coefficients:
        """A copy marked as written by a build that did not converge, with ``reasons`` (strings)."""
        extra = {**self.extra, CONVERGED_KEY: False, UNCONVERGED_REASONS_KEY: [str(r) for r in reasons]}
        return replace(self, extra=extra)

    @property
    def provenance(self) -> dict:
        """The file's provenance block (seed, levels, versions, ...), or {}."""
        return dict(self.extra.get("provenance", {}))

    def predict_free(self, length_m, width_m, **values) -> np.ndarray:
        """The family's free parameters at (L, W) [m] and the extra variables' ``values`` by name
        (e.g. ``x=0.05``; arrays broadcast): shape (..., k), k as in ``family.free_parameter_names``.

        Raises:
            InvalidParameterError: a variable of the coefficients without a value, or a value
                for one they do not vary (the message names it).
        """
        ordered = {name: self.parameters[name] for name in self.family.free_parameter_names}
        if not values and self.variables is DEFAULT_VARIABLES:  # the (L, W) route, as it always was
            return predict(ordered, length_m, width_m)
        extra = self.variables.take(values)
        if not extra:
            return predict(ordered, length_m, width_m)
        arrays = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (length_m, width_m, *extra.values())))
        return predict_points(ordered, np.stack(arrays, -1))

    def in_range(self, length_m: float, width_m: float, **values) -> bool:
        """True if (L, W) and the extra variables' ``values`` (by name) lie in the fitted range
        (inclusive). Raises as :meth:`predict_free`."""
        (l_lo, l_hi), (w_lo, w_hi) = self.fitted_range_m["L"], self.fitted_range_m["W"]
        if not values and self.variables.is_size_only:
            return l_lo <= length_m <= l_hi and w_lo <= width_m <= w_hi
        given = {"L": length_m, "W": width_m, **self.variables.take(values)}
        ranges = self.fitted_range_m
        return all(ranges[name][0] <= value <= ranges[name][1] for name, value in given.items())

    def to_json(self) -> dict:
        """The plain-JSON document of the coefficients file."""
        named = {} if self.variables.is_size_only else {"variables": list(self.variables.names)}
        document = {
            "format": FORMAT,
            "family": self.family.name,
            **named,
            "basis": list(self.variables.basis),
            "parameters": {name: list(values) for name, values in self.parameters.items()},
            "fitted_range": {key: list(value) for key, value in self.fitted_range_m.items()},
            "scene": {
                **self.scene.to_dict(),
                "link_lengths_m": list(self.link_lengths_m),
                "link_radii_m": list(self.link_radii_m),
                "elbow": self.elbow,
            },
        }
        document.update({k: v for k, v in self.extra.items() if k not in document})
        return document


def save_coefficients(coefficients: Coefficients, path: str | Path, overwrite: bool = True) -> bool:
    """Write atomically; returns True if a file was replaced."""
    return write_text_atomic(path, dumps(coefficients.to_json()), overwrite)


def _pair(document: dict, key: str, path: object) -> tuple[float, float]:
    value = document.get(key)
    if (
        not isinstance(value, list)
        or len(value) != 2
        or not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    ):
        raise DataFileError(path, f"{key!r} must be a list of two finite numbers, found {value!r}")
    return float(value[0]), float(value[1])


def coefficients_from_json(document: dict, source: str, sha256: str) -> Coefficients:
    """Validate a parsed coefficients document.

    Raises:
        DataFileError: a field is missing or malformed.
    """
    if document.get("format") != FORMAT:
        raise DataFileError(source, f"format is {document.get('format')!r}, expected {FORMAT!r}")
    try:
        family = family_from_name(document.get("family"))
    except PipelineError as exc:
        raise DataFileError(source, str(exc)) from None
    variables = _variables(document, source)
    basis = list(variables.basis)
    if document.get("basis") != basis:
        raise DataFileError(source, f"basis is {document.get('basis')!r}, expected {basis}")
    raw = document.get("parameters")
    if not isinstance(raw, dict):
        raise DataFileError(source, f"'parameters' must be an object of name -> {len(basis)} coefficients")
    parameters = {}
    for name in family.free_parameter_names:
        values = raw.get(name)
        if (
            not isinstance(values, list)
            or len(values) != len(basis)
            or not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in values)
        ):
            raise DataFileError(source, f"parameter {name!r} must be {len(basis)} finite numbers, found {values!r}")
        parameters[name] = tuple(float(v) for v in values)
    fitted = document.get("fitted_range")
    if not isinstance(fitted, dict):
        keys = " and ".join(repr(name) for name in variables.names)
        raise DataFileError(source, f"'fitted_range' must be an object with {keys}")
    fitted_range = {key: _pair(fitted, key, source) for key in variables.names}
    for key, (lo, hi) in fitted_range.items():
        if key in SIZE and not 0 < lo <= hi:
            raise DataFileError(source, f"fitted_range {key} = [{lo}, {hi}] must satisfy 0 < lo <= hi")
        if not lo <= hi:
            raise DataFileError(source, f"fitted_range {key} = [{lo}, {hi}] must satisfy lo <= hi")
    scene_doc = document.get("scene")
    if not isinstance(scene_doc, dict):
        raise DataFileError(source, "'scene' must be an object")
    try:
        scene = Scene.from_dict(scene_doc)
    except (PipelineError, TypeError) as exc:
        raise DataFileError(source, f"scene: {exc}") from None
    if scene.centre_x_m != 0.0:
        raise DataFileError(
            source,
            f"scene: centre_x_m = {scene.centre_x_m!r}, expected 0 (the generator places the obstacle at x = 0, "
            "or at the x given online for coefficients that vary x)",
        )
    lengths = _pair(scene_doc, "link_lengths_m", source)
    radii = _pair(scene_doc, "link_radii_m", source)
    if min(lengths) <= 0 or min(radii) < 0:
        raise DataFileError(source, f"link lengths {lengths} must be > 0 and radii {radii} >= 0")
    elbow = scene_doc.get("elbow", 1)
    if elbow not in (1, -1):
        raise DataFileError(source, f"scene.elbow is {elbow!r}, expected 1 or -1")
    converged = document.get(CONVERGED_KEY, True)
    reasons = document.get(UNCONVERGED_REASONS_KEY, [])
    if not isinstance(converged, bool) or not isinstance(reasons, list):
        raise DataFileError(
            source, f"{CONVERGED_KEY!r} must be true or false and {UNCONVERGED_REASONS_KEY!r} a list of strings"
        )
    known = {"format", "family", "variables", "basis", "parameters", "fitted_range", "scene"}
    return Coefficients(
        family=family,
        parameters=parameters,
        fitted_range_m=fitted_range,
        scene=scene,
        link_lengths_m=lengths,
        link_radii_m=radii,
        elbow=int(elbow),
        extra={k: v for k, v in document.items() if k not in known},
        source=source,
        source_sha256=sha256,
        variables=variables,
    )


def _variables(document: dict, source: str) -> Variables:
    """The file's ``variables`` (absent: (L, W)), which must hold L and W, in the canonical order."""
    variables = variables_in(document, source)
    if "variables" not in document:
        return variables
    names = document["variables"]
    if list(variables.names) != names or variables.names[:2] != SIZE:
        expected = list(Variables((*SIZE, *variables.extra)).names)
        raise DataFileError(source, f"variables are {names!r}, expected L and W first, in the order {expected}")
    return variables


def read_coefficients(source: str | Path) -> Coefficients:
    """Read a coefficients file, or the paper's Eq. 9 for :data:`PAPER_SOURCE` (no region map:
    :func:`pipeline.online.loading.read_coefficients` attaches one).

    Warns:
        UnconvergedCoefficientsWarning: the file is marked ``"converged": false`` (a build
            with ``--allow-unconverged`` that missed its thresholds).

    Raises:
        InvalidParameterError: ``source`` is not a path.
        DataFileError: the file is missing, unreadable, not JSON, or malformed.
    """
    if isinstance(source, bytes) or not isinstance(source, str | os.PathLike):
        raise InvalidParameterError(
            "coefficients", source, f"a coefficients file path or {PAPER!r}, not {type(source).__name__}"
        )
    path = paper_data_path("paper_eq9_coefficients.json") if str(source) == PAPER else Path(source)
    document = read_json(path)
    sha256 = hashlib.sha256(path.read_bytes()).hexdigest()
    label = PAPER if str(source) == PAPER else str(path)
    coefficients = coefficients_from_json(document, label, sha256)
    if not coefficients.converged:
        reasons = "; ".join(coefficients.unconverged_reasons) or "no reasons recorded"
        warnings.warn(
            f"{label} was written by a build that did not converge (--allow-unconverged): {reasons}",
            UnconvergedCoefficientsWarning,
            stacklevel=3,
        )
    return coefficients


def fit_coefficients(
    doe, extra: dict | None = None, endpoint_constraint: EndpointConstraint | None = None
) -> tuple[Coefficients, QuadraticFit]:
    """Regress a DOE (a :class:`pipeline.offline.doe.DoeData`) into coefficients over its
    variables ((L, W), or those its experiments vary, e.g. (L, W, x)).

    Every optimum is first mapped to the canonical form of Eq. 8, then each free
    parameter of the family is fitted on the quadratic basis: by plain least squares (the
    paper's Eq. 9), or, given an :class:`pipeline.offline.endpoint_regression.EndpointConstraint`
    (paper family only), with the endpoint errors held within its tolerance over the range.
    The fitted range is the DOE's (smallest and largest value of each variable [m]); over more
    variables than (L, W) the endpoint constraint runs on its coarser grids
    (:meth:`~pipeline.offline.endpoint_regression.EndpointConstraint.for_variables`).
    :func:`fit_over_variables` does the work.

    Returns:
        (coefficients, the :class:`pipeline.offline.regression.QuadraticFit` with R^2 and LOO errors).

    Raises:
        InvalidParameterError: an endpoint constraint for a family that is exact by
            construction, or as :func:`pipeline.offline.regression.fit_quadratic`.
    """
    variables = doe.variables
    if not variables.is_size_only:
        points = np.asarray(doe.points, dtype=float)
        fitted_range = {
            name: (float(points[:, k].min()), float(points[:, k].max())) for k, name in enumerate(variables.names)
        }
        constraint = None if endpoint_constraint is None else endpoint_constraint.for_variables(variables)
        return fit_over_variables(doe, variables, fitted_range, extra, constraint)
    fitted_range = {
        "L": (float(doe.lengths_m.min()), float(doe.lengths_m.max())),
        "W": (float(doe.widths_m.min()), float(doe.widths_m.max())),
    }
    return fit_over_variables(doe, DEFAULT_VARIABLES, fitted_range, extra, endpoint_constraint)


def fit_over_variables(
    doe,
    variables: Variables,
    fitted_range_m: Mapping[str, tuple[float, float]],
    extra: dict | None = None,
    endpoint_constraint: EndpointConstraint | None = None,
) -> tuple[Coefficients, QuadraticFit]:
    """Regress a DOE (a :class:`pipeline.offline.doe.DoeData`) into coefficients over ``variables``.

    The route of every fit, (L, W) (:func:`fit_coefficients`) or k scene variables (the build's
    ``--vary``, :func:`pipeline.build.doe_fit.fit_variables`): each free parameter of the family,
    in the canonical form of Eq. 8, is fitted on the full quadratic in ``variables`` by plain least
    squares, or, given an endpoint constraint (paper family only), with the endpoint errors held
    within its tolerance over ``fitted_range_m``. For (L, W) the floats are those of
    :func:`pipeline.offline.regression.fit_quadratic` and
    :func:`pipeline.offline.endpoint_regression.fit_with_endpoints`.

    Args:
        doe: The DOE as read back from its file; its ``points`` columns are ``variables``' (L and
            W first).
        variables: The scene variables of the fit (L and W among them).
        fitted_range_m: (lo, hi) [m] per variable: the range the coefficients claim, and that of
            the endpoint constraint's grids.
        extra: More top-level keys of the coefficients (provenance).
        endpoint_constraint: The endpoint constraint, or None for the plain fit.

    Returns:
        (coefficients, the :class:`pipeline.offline.regression.QuadraticFit` with R^2 and LOO errors).

    Raises:
        InvalidParameterError: ``variables`` without L and W first, or other than the DOE's
            columns; an endpoint constraint for a family that is exact by construction; or as
            :func:`pipeline.offline.regression.fit_quadratic_points`.
    """
    variables, points = _fit_points(doe, variables)
    fitted_range = {name: (float(fitted_range_m[name][0]), float(fitted_range_m[name][1])) for name in variables.names}
    fit, method = _fit_free_parameters(doe, points, variables, fitted_range, endpoint_constraint)
    quality = {
        "r_squared": fit.r_squared,
        "loo_rmse": fit.loo_rmse,
        "max_residual": fit.max_residual,
        "experiments": len(points),
        **method,
    }
    coefficients = Coefficients(
        family=doe.family,
        parameters=fit.coefficients,
        fitted_range_m=fitted_range,
        scene=doe.scene,
        link_lengths_m=doe.link_lengths_m,
        link_radii_m=doe.link_radii_m,
        elbow=doe.elbow,
        extra={"fit": quality, **(extra or {})},
        variables=variables,
    )
    return coefficients, fit


def _fit_points(doe, variables: Variables) -> tuple[Variables, np.ndarray]:
    """The variables of the fit and the DOE's runs over them, (n, k) [m]: for (L, W) the instance an
    (L, W) :class:`Coefficients` carries (its fast route) and the DOE's lengths and widths.

    Raises:
        InvalidParameterError: ``variables`` without L and W first, or other than the DOE's columns.
    """
    variables = Variables.of(variables)
    if variables.names[:2] != SIZE:
        raise InvalidParameterError("variables", variables.names, "variables that hold L and W")
    if variables.is_size_only:
        return DEFAULT_VARIABLES, np.column_stack([doe.lengths_m, doe.widths_m])
    points = np.asarray(doe.points, dtype=float)
    if points.shape[1:] != (variables.k,):
        raise InvalidParameterError("variables", variables.names, f"the DOE's {doe.variables.names}")
    return variables, points


def _fit_free_parameters(
    doe,
    points: np.ndarray,
    variables: Variables,
    fitted_range: dict[str, tuple[float, float]],
    endpoint_constraint: EndpointConstraint | None,
) -> tuple[QuadraticFit, dict]:
    """The quadratic fit of the DOE's free parameters on its runs ``points`` (n, k) [m], by plain
    least squares or with the endpoint errors held over ``fitted_range`` [m], and how it was fitted
    (the coefficients' ``fit`` method keys).

    Raises:
        InvalidParameterError: an endpoint constraint for a family that is exact by construction.
    """
    free = doe.free_parameters()
    if endpoint_constraint is None:
        return fit_quadratic_points(points, free, variables), {"regression": "least squares"}
    if doe.family.pins_endpoints:
        raise InvalidParameterError(
            "endpoint_constraint", endpoint_constraint, f"None for the {doe.family.name} family (exact by construction)"
        )
    targets = endpoint_targets(fitted_range, doe.scene, doe.link_lengths_m, endpoint_constraint.grid_points, variables)
    check = None
    if endpoint_constraint.check_points:
        check = endpoint_targets(
            fitted_range, doe.scene, doe.link_lengths_m, endpoint_constraint.check_points, variables
        )
    fit, report = fit_points_with_endpoints(points, free, targets, endpoint_constraint, check)
    return fit, {"regression": "least squares + endpoint constraint", "endpoint_constraint": report}
