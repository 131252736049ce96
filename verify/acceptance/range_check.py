"""The sweep against the range certificate: what the region map claims, and whether every
sampled case agrees with it.

The region map (:mod:`pipeline.certify.region_map`) claims, for every point of one leaf ((L, W),
or (L, W, x) and so on for coefficients over more scene variables: the map's ``axes``), a
lower bound ``b_c`` on the clearance of both links over all of [0, T] and an upper bound
``b_e`` on the endpoint error max(|tip(0) - P1|, |tip(T) - P5|). Each case is looked up at its
whole point (L, W and its extra variables' values), in the leaf holding it. The sweep measures
each case on its own (:mod:`verify.acceptance.metrics`), so each case tests the map's claim for
its cell:

**Clearance.** The per-query certificate of a case (``MeasureSettings``: the adaptive sinusoid
certificate with Coal's distances, error ``e`` = :data:`COAL_DISTANCE_ERROR_M`, refinement
tolerance ``tolerance_m``, 1e-5 m by default) is also only a lower bound, so ``certified >= b_c``
need not hold exactly: both certificates bound the same true minimum ``c`` from below. What does
hold is this. A converged certificate in *tolerance mode* has refined every interval until its
bound is within ``tolerance_m`` of the smallest Coal sample minus ``e``, and that sample is at
least ``c - e``; hence ``certified >= c - tolerance_m - 2 e >= b_c - tolerance_m - 2 e``. The
check is therefore ``certified + tolerance_m + 2 e + FLOAT_SLACK_M >= b_c``
(:func:`clearance_slack_m`), and only on *tight* bounds (``CertifiedClearance.tight``): in the
sweep's default *decide mode* a case whose clearance keeps the margin only gets a bound >= the
margin, which may lie anywhere below ``c`` and says nothing about ``b_c`` (such cases are counted
in ``n_certificate_decided``); a certificate that ran out of its evaluation budget (or did not
run) is not checked either (``n_certificate_unconverged``). The **sampled** clearance needs no
such care: every Coal sample is at least ``c - e``, so ``sampled + e + FLOAT_SLACK_M >= b_c``
must hold for every measured case whatever the certificate did; it is checked on every case.

**Endpoints.** The case's endpoint errors are Pinocchio's forward kinematics of the URDF, exact
up to rounding, and ``b_e`` is a rigorous upper bound, so ``max(start, end) <= b_e +
FLOAT_SLACK_M`` (1e-9 m, for rounding only) must hold.

**Execution bounds** (a map that has them, :mod:`pipeline.certify.execution_bounds`). Each
case's joint check gives the exact closed-form peaks of |dq| and |ddq| and the angle range of
the paper timing (``JointCheck``), and its largest sampled torque (RNEA's closed form; sampled
coarse and refined wherever it comes within 1 % of the leaf's bound, which the sweep hands to the
measurement: :func:`verify.acceptance.run.torque_ceilings`). The
leaf's bounds are rigorous upper bounds of all of them (the angle range encloses), so each
``bound - value`` must be >= -:data:`EXECUTION_SLACK` (rounding only); the torques are compared
only when the sweep's arm has the map's inertias (``dynamics``).

Cases outside the map's range are not checked (``n_out_of_range``); cases that could not be
generated have nothing to check (``n_not_measured``). A map of other coefficients (another
sha256) is reported as not belonging and not used for any check. Any violation makes the
check, and so the sweep, fail.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pipeline.certify.clearance_bound import FLOAT_SLACK_M
from pipeline.certify.region_map import STATUSES, RegionMap
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M
from pipeline.offline.coefficients import Coefficients
from pipeline.validation import check_non_negative

from .metrics import MeasureSettings
from .results import CaseResult

#: Rounding slack of the execution bounds' check [rad, rad/s, rad/s^2, N m].
EXECUTION_SLACK = 1e-9
#: The execution quantities checked, in report order.
EXECUTION_QUANTITIES = ("angle", "speed", "acceleration", "torque")


@dataclass(frozen=True)
class ExecutionCheck:
    """The map's execution bounds against the sweep's measured joints (paper timing).

    Attributes:
        checked: Cases compared.
        worst_slack: Per quantity (:data:`EXECUTION_QUANTITIES`), the smallest ``bound - value``
            over the cases [rad, rad/s, rad/s^2, N m] (None: not compared).
        violations: Case indices past a bound by more than :data:`EXECUTION_SLACK`.
    """

    checked: int
    worst_slack: dict
    violations: tuple[int, ...]

    def to_json(self) -> dict[str, Any]:
        """Plain JSON."""
        return {"checked": self.checked, "worst_slack": dict(self.worst_slack), "violations": list(self.violations)}


def _execution_check(
    region_map: RegionMap, cases: Sequence[CaseResult], leaf: np.ndarray, measured: np.ndarray, dynamics
) -> ExecutionCheck | None:
    """Compare every measured case's joint peaks with its leaf's execution bounds (module docstring)."""
    bounds = region_map.execution
    if bounds is None:
        return None
    rows = [k for k in np.flatnonzero(measured) if cases[k].measurement.joints is not None]
    if not rows:
        return ExecutionCheck(0, {q: None for q in EXECUTION_QUANTITIES}, ())
    joints = [cases[k].measurement.joints for k in rows]
    leaves = leaf[rows]
    ranges = np.array([j.range_rad for j in joints], dtype=float)  # (n, 2, 2)
    angles = bounds.angle_range_rad[leaves]
    slack = {
        "angle": np.minimum(ranges[:, :, 0] - angles[:, :, 0], angles[:, :, 1] - ranges[:, :, 1]).min(1),
        "speed": (bounds.paper_speed_rad_s[leaves] - np.array([j.peak_velocity_rad_s for j in joints])).min(1),
        "acceleration": (
            bounds.paper_acceleration_rad_s2[leaves] - np.array([j.peak_acceleration_rad_s2 for j in joints])
        ).min(1),
    }
    if dynamics is not None and dynamics == bounds.dynamics:
        sampled = np.array([j.peak_torque_sampled_n_m for j in joints], dtype=float)
        if np.all(np.isfinite(sampled)):
            slack["torque"] = (bounds.paper_torque_n_m[leaves] - sampled).min(1)
    index = np.array([cases[k].index for k in rows], dtype=np.int64)
    bad = np.zeros(len(rows), dtype=bool)
    for values in slack.values():
        bad |= values < -EXECUTION_SLACK
    worst = {q: (float(slack[q].min()) if q in slack else None) for q in EXECUTION_QUANTITIES}
    return ExecutionCheck(len(rows), worst, tuple(int(i) for i in index[bad]))


def clearance_slack_m(settings: MeasureSettings) -> float:
    """How far [m] a converged per-query certified clearance may lie below the map's bound of
    its cell without contradicting it: the certificate's tolerance, twice Coal's distance error
    and the rounding slack (module docstring)."""
    return settings.tolerance_m + 2.0 * COAL_DISTANCE_ERROR_M + FLOAT_SLACK_M


#: How far [m] a Coal-sampled clearance may lie below the map's bound: Coal's error and rounding.
SAMPLED_SLACK_M = COAL_DISTANCE_ERROR_M + FLOAT_SLACK_M
#: How far [m] an endpoint error (Pinocchio) may exceed the map's bound: rounding only.
ENDPOINT_SLACK_M = FLOAT_SLACK_M


@dataclass(frozen=True)
class MapReport:
    """What a region map claims, in numbers (from :meth:`RegionMap.summary`).

    Attributes:
        path: The map's file, or None if it was given in memory.
        coefficients_sha256: sha256 of the coefficients the map was made from.
        belongs: The map was made from exactly the sweep's coefficients.
        area_fraction: Area fraction of the fitted range per status (keys :data:`STATUSES`).
        clearance_bound_min_m: The smallest clearance bound of any leaf [m].
        worst_cell_L_m, worst_cell_W_m: That leaf's (lo, hi) in L and W [m].
        worst_cell_extra_m: ((name, (lo, hi)), ...) of that leaf along each axis beyond L and W [m]
            (empty for a map over (L, W)).
        endpoint_bound_max_m: The largest endpoint-error bound of any leaf [m].
        margin_m, endpoint_tolerance_m: The map's margin and endpoint tolerance [m].
        cells: Number of leaves.
    """

    path: str | None
    coefficients_sha256: str
    belongs: bool
    area_fraction: dict[str, float]
    clearance_bound_min_m: float
    worst_cell_L_m: tuple[float, float]
    worst_cell_W_m: tuple[float, float]
    endpoint_bound_max_m: float
    margin_m: float
    endpoint_tolerance_m: float
    cells: int
    worst_cell_extra_m: tuple[tuple[str, tuple[float, float]], ...] = ()

    def __post_init__(self) -> None:
        check_non_negative("margin_m", self.margin_m)
        if set(self.area_fraction) != set(STATUSES):
            raise InvalidParameterError("area_fraction", sorted(self.area_fraction), f"the keys {STATUSES}")

    @classmethod
    def of(cls, region_map: RegionMap, coefficients: Coefficients, path: str | None = None) -> MapReport:
        """The report of ``region_map`` for ``coefficients``."""
        summary = region_map.summary()
        worst = summary["worst_cell"]
        return cls(
            path=path,
            coefficients_sha256=region_map.coefficients_sha256,
            belongs=region_map.belongs_to(coefficients),
            area_fraction=dict(summary["area_fraction"]),
            clearance_bound_min_m=float(summary["clearance_bound_min_m"]),
            worst_cell_L_m=(float(worst["L_m"][0]), float(worst["L_m"][1])),
            worst_cell_W_m=(float(worst["W_m"][0]), float(worst["W_m"][1])),
            endpoint_bound_max_m=float(summary["endpoint_bound_max_m"]),
            margin_m=region_map.margin_m,
            endpoint_tolerance_m=region_map.endpoint_tolerance_m,
            cells=int(summary["cells"]),
            worst_cell_extra_m=tuple(
                (name, (float(worst[f"{name}_m"][0]), float(worst[f"{name}_m"][1]))) for name in region_map.axes[2:]
            ),
        )


@dataclass(frozen=True)
class BoundCheck:
    """One inequality checked on every eligible case.

    Attributes:
        checked: Cases it was checked on.
        allowed_slack_m: How far past the map's bound a case may lie without a violation [m].
        worst_slack_m: The smallest margin by which a case keeps the map's bound [m] (negative:
            past it; None if no case was checked): per-query value minus map bound for a lower
            bound, map bound minus per-query value for an upper bound.
        violations: Case indices (``CaseResult.index``) past the bound by more than the allowed slack.
    """

    checked: int
    allowed_slack_m: float
    worst_slack_m: float | None
    violations: tuple[int, ...]

    def __post_init__(self) -> None:
        check_non_negative("allowed_slack_m", self.allowed_slack_m)

    @classmethod
    def of(cls, slack_m: np.ndarray, index: np.ndarray, allowed_slack_m: float) -> BoundCheck:
        """From per-case slacks [m] (value kept beyond the bound) and the cases' indices."""
        bad = slack_m < -allowed_slack_m
        worst = float(np.min(slack_m)) if slack_m.size else None
        return cls(int(slack_m.size), allowed_slack_m, worst, tuple(int(i) for i in index[bad]))

    def to_json(self) -> dict[str, Any]:
        """Plain JSON (infinite slack, from an infinite map bound, becomes None)."""
        worst = self.worst_slack_m
        return {
            "checked": self.checked,
            "allowed_slack_m": self.allowed_slack_m,
            "worst_slack_m": worst if worst is not None and math.isfinite(worst) else None,
            "violations": list(self.violations),
        }


@dataclass(frozen=True)
class RangeCheck:
    """The sweep's cases against a region map.

    Attributes:
        map: What the map claims.
        n_cases: Cases of the sweep.
        n_out_of_range: Cases outside the map's range (not checked).
        n_not_measured: Cases in range whose trajectory could not be generated.
        n_certificate_decided: Measured cases in range whose certificate only decided that the
            margin is kept (decide mode, bound not tight): their certified clearance is not checked.
        n_certificate_unconverged: Measured cases in range whose certificate did not converge (or
            did not run): their certified clearance is not checked.
        certified: certified clearance + slack >= the map's clearance bound.
        sampled: sampled (Coal) clearance + Coal's error >= the map's clearance bound.
        endpoint: max endpoint error <= the map's endpoint bound + rounding.
        execution: The joints against the map's execution bounds (None: the map has none, or
            it was not checked).
        region_map: The map itself (for drawing; not in the JSON), None if it does not belong.
    """

    map: MapReport
    n_cases: int
    n_out_of_range: int
    n_not_measured: int
    n_certificate_decided: int
    n_certificate_unconverged: int
    certified: BoundCheck | None
    sampled: BoundCheck | None
    endpoint: BoundCheck | None
    execution: ExecutionCheck | None = None
    region_map: RegionMap | None = field(default=None, repr=False, compare=False)

    @property
    def checked(self) -> bool:
        """The map belongs to the coefficients and was checked against the cases."""
        return self.endpoint is not None

    @property
    def violations(self) -> tuple[int, ...]:
        """Every case index that contradicts the map (sorted, once each)."""
        checks = (self.certified, self.sampled, self.endpoint, self.execution)
        return tuple(sorted({i for c in checks if c is not None for i in c.violations}))

    @property
    def passed(self) -> bool:
        """No case contradicts the map (a map that does not belong is not checked, so it passes)."""
        return not self.violations

    def to_json(self) -> dict[str, Any]:
        """Plain JSON: the map's claims and the cross-check."""
        m = self.map
        return {
            "path": m.path,
            "coefficients_sha256": m.coefficients_sha256,
            "belongs_to_coefficients": m.belongs,
            "area_fraction": m.area_fraction,
            "clearance_bound_min_m": m.clearance_bound_min_m,
            "worst_cell": {
                "L_m": list(m.worst_cell_L_m),
                "W_m": list(m.worst_cell_W_m),
                **{f"{name}_m": list(pair) for name, pair in m.worst_cell_extra_m},
            },
            "endpoint_bound_max_m": m.endpoint_bound_max_m,
            "margin_m": m.margin_m,
            "endpoint_tolerance_m": m.endpoint_tolerance_m,
            "cells": m.cells,
            "cross_check": {
                "checked": self.checked,
                "passed": self.passed,
                "n_cases": self.n_cases,
                "n_out_of_range": self.n_out_of_range,
                "n_not_measured": self.n_not_measured,
                "n_certificate_decided": self.n_certificate_decided,
                "n_certificate_unconverged": self.n_certificate_unconverged,
                "certified_clearance": None if self.certified is None else self.certified.to_json(),
                "sampled_clearance": None if self.sampled is None else self.sampled.to_json(),
                "endpoint_error": None if self.endpoint is None else self.endpoint.to_json(),
                "execution": None if self.execution is None else self.execution.to_json(),
                "violations": list(self.violations),
            },
        }


def _case_columns(cases: Sequence[CaseResult]) -> dict[str, np.ndarray]:
    """Per case: index, L, W [m], and the measured numbers [m] (NaN where absent; the certified
    clearance only where it is tight and converged), and whether the certificate only decided."""

    def column(values: list[float | None]) -> np.ndarray:
        return np.array([np.nan if v is None else v for v in values], dtype=float)

    certificates = [c.certificate for c in cases]
    return {
        "decided": np.array([k is not None and k.converged and not k.tight for k in certificates], dtype=bool),
        "index": np.array([c.index for c in cases], dtype=np.int64),
        "L": np.array([c.L_m for c in cases], dtype=float),
        "W": np.array([c.W_m for c in cases], dtype=float),
        "measured": np.array([c.measurement is not None for c in cases], dtype=bool),
        "certified": column(
            [k.certified_clearance_m if k is not None and k.converged and k.tight else None for k in certificates]
        ),
        "sampled": column([c.clearance_m for c in cases]),
        "endpoint": column([c.endpoint_error_m for c in cases]),
    }


def _extra_columns(region_map: RegionMap, cases: Sequence[CaseResult]) -> list[np.ndarray]:
    """The cases' values along each of the map's axes beyond L and W, in ``axes`` order [m].

    Raises:
        InvalidParameterError: a case without a value of one of those axes.
    """
    columns = []
    for name in region_map.axes[2:]:
        values = [c.extra_values.get(name) for c in cases]
        if any(v is None for v in values):
            axes = ", ".join(region_map.axes)
            raise InvalidParameterError("cases", name, f"a value of {name} in every case (the map's axes are {axes})")
        columns.append(np.array(values, dtype=float))
    return columns


def check_range(
    region_map: RegionMap,
    coefficients: Coefficients,
    cases: Sequence[CaseResult],
    settings: MeasureSettings,
    *,
    path: str | None = None,
    dynamics=None,
) -> RangeCheck:
    """Report ``region_map`` and cross-check every in-range case of a sweep against it, each in
    the leaf holding its whole point (L, W, then the map's extra axes, from ``CaseResult.extra``)
    (vectorised through :meth:`RegionMap.cells_at`; inequalities in the module docstring).

    Args:
        region_map: The map.
        coefficients: The sweep's coefficients (the map is used only if it belongs to them).
        cases: The sweep's cases.
        settings: How the cases were measured (the certificate's tolerance; in decide mode only
            the tight bounds are compared).
        path: The map's file, for the report.
        dynamics: The sweep's arm's :class:`pipeline.model.dynamics.PlanarDynamics` (the torque
            bounds are compared only if it is the map's).
    """
    report = MapReport.of(region_map, coefficients, path)
    if not report.belongs:
        return RangeCheck(report, len(cases), 0, 0, 0, 0, None, None, None)
    col = _case_columns(cases)
    cells = region_map.cells_at(col["L"], col["W"], *_extra_columns(region_map, cases))
    inside = cells["leaf"] >= 0
    measured = inside & col["measured"]
    tight = measured & np.isfinite(col["certified"])
    decided = measured & col["decided"]
    bound_c, bound_e = cells["clearance_bound_m"], cells["endpoint_bound_m"]
    return RangeCheck(
        map=report,
        n_cases=len(cases),
        n_out_of_range=int(np.count_nonzero(~inside)),
        n_not_measured=int(np.count_nonzero(inside & ~col["measured"])),
        n_certificate_decided=int(np.count_nonzero(decided)),
        n_certificate_unconverged=int(np.count_nonzero(measured & ~tight & ~decided)),
        certified=BoundCheck.of(
            col["certified"][tight] - bound_c[tight], col["index"][tight], clearance_slack_m(settings)
        ),
        sampled=BoundCheck.of(col["sampled"][measured] - bound_c[measured], col["index"][measured], SAMPLED_SLACK_M),
        endpoint=BoundCheck.of(bound_e[measured] - col["endpoint"][measured], col["index"][measured], ENDPOINT_SLACK_M),
        execution=_execution_check(region_map, cases, cells["leaf"], measured, dynamics),
        region_map=region_map,
    )
