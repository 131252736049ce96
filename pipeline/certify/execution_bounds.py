"""The execution bounds of a region map's leaves, as stored in the map: for one arm, per leaf,
what every trajectory of the leaf does to the arm's limits, proven for every (L, W) of the leaf
and all of [0, T] (computed by :mod:`pipeline.certify.execution_range`, where the derivation is).

Per leaf the map stores the path duration range, the angle ranges, the paper timing's peak
|dq| and |ddq| (arm-independent), the torque terms G (the paper timing's torque bound) and K of
the arm's dynamics, and the rest-to-rest timing's speed scale c and ramp r for the arm's
limits; the rest-to-rest bounds follow in closed form from them
(:func:`pipeline.motion.rest_to_rest.rest_to_rest_bounds`), so they are computed when the map
is read. Every stored value is rounded outward to
:data:`SIGNIFICANT_DIGITS` decimal digits (a lower bound down, an upper bound up, c down and r
up, which only lowers the timing's bounds), and a leaf whose rounded ramps would not fit
(r > T_lo / c) has no rest-to-rest timing. NumPy only: reading a map needs neither Pinocchio
nor Coal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType

import numpy as np

from pipeline.exceptions import DataFileError, InvalidParameterError, RegionMapLimitsError
from pipeline.io.decimal_columns import FloatColumns
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.rest_to_rest import rest_to_rest_bounds

__all__ = ["COLUMNS", "SIGNIFICANT_DIGITS", "ExecutionBounds", "dynamics_json", "limits_json", "outward"]

#: Decimal digits the columns keep (rounded outward: :func:`outward`).
SIGNIFICANT_DIGITS = 7
#: Columns that are lower bounds, or rounded down to stay safe (the speed scale).
ROUNDED_DOWN = ("duration_lo_s", "angle_lo1_rad", "angle_lo2_rad", "speed_scale")
#: The columns stored per leaf.
COLUMNS = (
    "duration_lo_s",
    "duration_hi_s",
    "angle_lo1_rad",
    "angle_hi1_rad",
    "angle_lo2_rad",
    "angle_hi2_rad",
    "peak_speed1_rad_s",
    "peak_speed2_rad_s",
    "peak_acceleration1_rad_s2",
    "peak_acceleration2_rad_s2",
    "paper_torque1_n_m",
    "paper_torque2_n_m",
    "ramp_torque1_n_m_s",
    "ramp_torque2_n_m_s",
    "speed_scale",
    "ramp_s",
)
#: What a null in a column stands for (default: +inf, an unbounded upper bound).
_NULL_MEANS = MappingProxyType(
    {"angle_lo1_rad": -math.inf, "angle_lo2_rad": -math.inf, "speed_scale": math.nan, "ramp_s": math.nan}
)


def dynamics_json(dynamics: PlanarDynamics) -> dict:
    """The inertias as JSON (the map's headers)."""
    return {
        "m0": [list(r) for r in dynamics.m0],
        "mc": [list(r) for r in dynamics.mc],
        "ms": [list(r) for r in dynamics.ms],
    }


def limits_json(limits: ArmLimits) -> dict:
    """The position, speed, acceleration and effort limits as JSON (the map's headers; no jerk)."""
    return {
        "position_rad": [list(p) for p in limits.position_rad],
        "velocity_rad_s": list(limits.velocity_rad_s),
        "acceleration_rad_s2": list(limits.acceleration_rad_s2),
        "effort_n_m": list(limits.effort_n_m),
    }


def _unnull(values, infinite: float):
    """JSON null (a non-finite value written by json_safe) back to ``infinite``, recursively."""
    if isinstance(values, list):
        return [_unnull(v, infinite) for v in values]
    return infinite if values is None else float(values)


@dataclass(frozen=True, eq=False)
class ExecutionBounds:
    """The execution bounds of every leaf of a region map, for one arm (module docstring).

    Attributes:
        limits: The arm's limits the rest-to-rest timings keep.
        dynamics: The arm's dynamics the torque bounds are of.
        columns: Per leaf (n,) arrays named as :data:`COLUMNS` (a dict, or the
            :class:`pipeline.io.decimal_columns.FloatColumns` of a map's table, read when asked
            for): the duration range T [s], the angle ranges [rad], the paper timing's peak |dq|
            [rad/s] and |ddq| [rad/s^2], and the rest-to-rest timing's speed scale c and ramp r
            [s] (NaN: no timing keeps the limits).
    """

    limits: ArmLimits
    dynamics: PlanarDynamics
    columns: dict = field(repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.limits, ArmLimits) or not isinstance(self.dynamics, PlanarDynamics):
            raise InvalidParameterError("limits, dynamics", (self.limits, self.dynamics), "ArmLimits, PlanarDynamics")
        missing = [c for c in COLUMNS if c not in self.columns]
        if missing:
            raise InvalidParameterError("columns", missing, f"all of {COLUMNS}")
        if isinstance(self.columns, FloatColumns):  # a map's table: read when asked for, lengths checked
            return
        arrays = {k: np.array(self.columns[k], dtype=float) for k in COLUMNS}
        n = arrays[COLUMNS[0]].size
        if any(a.shape != (n,) for a in arrays.values()):
            raise InvalidParameterError("columns", {k: a.shape for k, a in arrays.items()}, "equal 1-D arrays")
        for a in arrays.values():
            a.setflags(write=False)
        object.__setattr__(self, "columns", arrays)

    @property
    def size(self) -> int:
        """Number of leaves."""
        if isinstance(self.columns, FloatColumns):
            return self.columns.size
        return self.columns[COLUMNS[0]].size

    def _pair(self, stem: str, unit: str) -> np.ndarray:
        return np.stack([self.columns[f"{stem}1_{unit}"], self.columns[f"{stem}2_{unit}"]], -1)

    @cached_property
    def angle_range_rad(self) -> np.ndarray:
        """(n, 2, 2): per leaf and joint, (lo, hi) of every angle taken [rad]."""
        return np.stack([self._pair("angle_lo", "rad"), self._pair("angle_hi", "rad")], -1)

    @cached_property
    def paper_speed_rad_s(self) -> np.ndarray:
        """(n, 2) bounds of |dq_i| with the paper timing [rad/s]."""
        return self._pair("peak_speed", "rad_s")

    @cached_property
    def paper_acceleration_rad_s2(self) -> np.ndarray:
        """(n, 2) bounds of |ddq_i| with the paper timing [rad/s^2]."""
        return self._pair("peak_acceleration", "rad_s2")

    @cached_property
    def paper_torque_n_m(self) -> np.ndarray:
        """(n, 2) bounds of |tau_i| with the paper timing [N m]."""
        return self._pair("paper_torque", "n_m")

    @cached_property
    def rest_to_rest(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(n, 2) bounds of |dq_i| [rad/s], |ddq_i| [rad/s^2], |tau_i| [N m] with each leaf's
        rest-to-rest timing (NaN where it has none)."""
        return rest_to_rest_bounds(
            self.columns["speed_scale"],
            self.columns["ramp_s"],
            self.paper_speed_rad_s,
            self.paper_acceleration_rad_s2,
            self.dynamics,
            torque_terms=(self.paper_torque_n_m, self._pair("ramp_torque", "n_m_s")),
        )

    @cached_property
    def rest_to_rest_duration_max_s(self) -> np.ndarray:
        """(n,) the largest rest-to-rest duration T' = T / c + r over each leaf [s] (NaN: none)."""
        return self.columns["duration_hi_s"] / self.columns["speed_scale"] + self.columns["ramp_s"]

    @cached_property
    def _rows(self) -> list:
        """Per leaf, (c, r, angle range, rest-to-rest (dq, ddq, tau) bounds, paper (dq, ddq, tau)
        bounds) as Python objects: the online lookup's reads."""
        speed, acceleration, torque = self.rest_to_rest
        angles = self.angle_range_rad
        return [
            (
                float(self.columns["speed_scale"][k]),
                float(self.columns["ramp_s"][k]),
                ((float(angles[k, 0, 0]), float(angles[k, 0, 1])), (float(angles[k, 1, 0]), float(angles[k, 1, 1]))),
                (speed[k], acceleration[k], torque[k]),
                (self.paper_speed_rad_s[k], self.paper_acceleration_rad_s2[k], self.paper_torque_n_m[k]),
            )
            for k in range(self.size)
        ]

    def leaf(self, index: int) -> tuple:
        """The lookup row of leaf ``index`` (:attr:`_rows`)."""
        return self._rows[index]

    def paper_breaks(self) -> dict[str, np.ndarray]:
        """Per leaf, True where the paper timing's bounds exceed a limit, per kind ("angle",
        "speed", "acceleration", "torque"); a bound above a limit means the leaf is not proven
        to keep it (the true peak may lie below)."""
        limits = self.limits
        position = np.asarray(limits.position_rad)
        angles = self.angle_range_rad
        return {
            "angle": np.any((angles[:, :, 0] < position[None, :, 0]) | (angles[:, :, 1] > position[None, :, 1]), 1),
            "speed": np.any(self.paper_speed_rad_s > np.asarray(limits.velocity_rad_s), 1),
            "acceleration": np.any(self.paper_acceleration_rad_s2 > np.asarray(limits.acceleration_rad_s2), 1),
            "torque": np.any(self.paper_torque_n_m > np.asarray(limits.effort_n_m), 1),
        }

    def check_arm(self, limits: ArmLimits, dynamics: PlanarDynamics) -> None:
        """Refuse another arm's limits or inertias.

        Raises:
            RegionMapLimitsError: ``limits`` or ``dynamics`` differ from the map's (the first
                difference is named).
        """
        mine, theirs = limits_json(self.limits), limits_json(limits)
        for key in mine:
            if mine[key] != theirs[key]:
                raise RegionMapLimitsError(key, mine[key], theirs[key])
        if dynamics != self.dynamics:
            raise RegionMapLimitsError("inertia (mass matrix)", dynamics_json(self.dynamics), dynamics_json(dynamics))

    def header_json(self) -> dict:
        """The limits and dynamics the bounds are of, as plain JSON (without the columns)."""
        return {"limits": limits_json(self.limits), "dynamics": dynamics_json(self.dynamics)}

    def to_json(self) -> dict:
        """Plain JSON (non-finite values are written as null by the map's writer)."""
        return {**self.header_json(), "columns": {k: self.columns[k].tolist() for k in COLUMNS}}

    @classmethod
    def from_json(cls, document: dict, source: object) -> ExecutionBounds:
        """Read :meth:`to_json`'s document (a null stands for the column's infinite value), or a header
        whose ``columns`` are a map table's :class:`pipeline.io.decimal_columns.FloatColumns`.

        Raises:
            DataFileError: malformed.
        """
        try:
            lim = document["limits"]
            position = tuple(
                (-math.inf if lo is None else float(lo), math.inf if hi is None else float(hi))
                for lo, hi in lim["position_rad"]
            )
            limits = ArmLimits(
                position_rad=position,
                velocity_rad_s=_unnull(lim["velocity_rad_s"], math.inf),
                acceleration_rad_s2=_unnull(lim["acceleration_rad_s2"], math.inf),
                effort_n_m=_unnull(lim["effort_n_m"], math.inf),
            )
            dyn = document["dynamics"]
            dynamics = PlanarDynamics(
                *(tuple(tuple(float(v) for v in row) for row in dyn[k]) for k in ("m0", "mc", "ms"))
            )
            raw = document["columns"]
            if isinstance(raw, FloatColumns):  # columns of a map's table: read when asked for
                return cls(limits, dynamics, raw)
            columns = {}
            for key in COLUMNS:
                values = np.array(raw[key], dtype=float)  # null -> NaN
                columns[key] = np.where(np.isnan(values), _NULL_MEANS.get(key, math.inf), values)
            return cls(limits, dynamics, columns)
        except (KeyError, TypeError, ValueError, InvalidParameterError) as exc:
            raise DataFileError(source, f"malformed execution bounds ({exc.__class__.__name__}: {exc})") from None


def outward(values: np.ndarray, down: bool) -> np.ndarray:
    """``values`` rounded to :data:`SIGNIFICANT_DIGITS` decimal digits, never inward: down for a
    lower bound (and the speed scale), up otherwise; non-finite values stay. Short decimals keep
    the map file small; a bound looser by 1e-6 of itself is still a bound."""
    out = np.array(values, dtype=float)
    sign = -1.0 if down else 1.0
    for k in np.flatnonzero(np.isfinite(out)):
        x = float(out[k])
        y = float(f"{x:.{SIGNIFICANT_DIGITS}g}")
        if sign * (y - x) < 0.0:  # rounded inward: one unit of the last digit outward instead
            y = float(f"{x + sign * abs(x) * 10.0 ** (1 - SIGNIFICANT_DIGITS):.{SIGNIFICANT_DIGITS}g}")
        out[k] = y
    return out
