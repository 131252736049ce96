"""Experimental designs over k scene factors (:mod:`pipeline.offline.variables`): which runs the DOE
solves.

A :class:`Factor` is one scene variable and its range; a design places its runs in the box of
its factors' ranges:

* :class:`FullFactorial`: K levels per factor, K^k runs (the paper's 3 x 3 over (L, W)), in
  Table 1 order generalised: every factor descending, the first factor (L) fastest, the last one
  slowest. For (L, W) these are the paper's points, W descending by rows, L descending within a
  row, to the bit.
* :class:`BoxBehnken`: pyDOE's ``bbdesign`` (k >= 3): the midpoints of the box's edges and one
  centre run, 2 k (k - 1) + 1 runs.
* :class:`CentralComposite`: pyDOE's ``ccdesign`` face-centred (alpha = 1, so every run stays in
  the box): the 2^k corners, the 2 k face centres and one centre run.

The response-surface designs come in coded units (-1, 0, +1) and are scaled to the ranges on the
levels of the 3-level factorial (the same floats). Each keeps one centre run: the experiments are
deterministic for their seed, so replicated centres would add runs and no information.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.offline.variables import SIZE, Variables, check_name
from pipeline.validation import check_positive_int

__all__ = [
    "DEFAULT_RANGES_M",
    "DESIGN_KINDS",
    "BoxBehnken",
    "CentralComposite",
    "Factor",
    "FullFactorial",
    "ScaledDesign",
    "design_class",
]

#: Default ranges of the variables beyond L and W [m]: x = +-50 mm keeps P1..P5 of every corner of
#: the default (L, W) range inside the arm's reach (the limit is |x| < 60 mm, where P1 of L = 0.30 m
#: reaches the outer radius 0.65 m on the right and P5 on the left).
DEFAULT_RANGES_M: Mapping[str, tuple[float, float]] = MappingProxyType({"x": (-0.05, 0.05)})

TABLE1_ORDER = "Table 1: W descending by rows, L descending within a row"


def _round(value: float) -> float:
    return round(float(value), 12)


@dataclass(frozen=True)
class Factor:
    """One scene variable of a design and its range.

    Attributes:
        name: A variable of :data:`pipeline.offline.variables.NAMES` (L, W, x, d).
        range_m: (min, max) [m], min < max; positive for L and W.

    Raises:
        InvalidParameterError: an unknown name (with the closest valid one), a range that is not
            two finite numbers with min < max, or a non-positive L or W.
    """

    name: str
    range_m: tuple[float, float]

    def __post_init__(self) -> None:
        check_name(self.name)
        what = f"{self.name} range"
        try:
            lo, hi = (float(v) for v in self.range_m)
        except (TypeError, ValueError):
            raise InvalidParameterError(what, self.range_m, "(min, max) [m]") from None
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise InvalidParameterError(what, self.range_m, "finite (min, max) [m]")
        if self.name in SIZE:
            for side, value in (("min", lo), ("max", hi)):
                if not value > 0:
                    raise InvalidParameterError(f"{what} {side}", value, "> 0")
        if not lo < hi:
            raise InvalidParameterError(what, (lo, hi), "min < max")
        object.__setattr__(self, "range_m", (lo, hi))

    def levels(self, count: int) -> np.ndarray:
        """``count`` levels, max to min (descending), rounded to 1e-12 m."""
        return np.array([_round(v) for v in np.linspace(self.range_m[1], self.range_m[0], count)])


def _factors(factors: Iterable[Factor]) -> tuple[Factor, ...]:
    """``factors`` in the canonical variable order, each once, L and W among them."""
    given = tuple(factors)
    if not all(isinstance(f, Factor) for f in given):
        raise InvalidParameterError("factors", given, "Factor objects")
    names = tuple(f.name for f in given)
    if len(set(names)) != len(names):
        duplicate = next(n for n in names if names.count(n) > 1)
        raise InvalidParameterError("factors", duplicate, "each variable once")
    for name in SIZE:
        if name not in names:
            raise InvalidParameterError("factors", names, f"{name} among them (every design varies L and W)")
    order = Variables(names).names
    return tuple(sorted(given, key=lambda f: order.index(f.name)))


@dataclass(frozen=True)
class ScaledDesign:
    """What every design has: its factors (canonical order) and runs.

    Attributes:
        factors: One :class:`Factor` per variable, L and W among them; stored in the canonical
            order (L, W, x, d).
    """

    factors: tuple[Factor, ...]

    #: The design's name on the command line.
    kind = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "factors", _factors(self.factors))

    @property
    def variables(self) -> Variables:
        """The varied variables, canonical order."""
        return Variables(tuple(f.name for f in self.factors))

    @property
    def ranges_m(self) -> dict[str, tuple[float, float]]:
        """name -> (min, max) [m]."""
        return {f.name: f.range_m for f in self.factors}

    def coded(self) -> np.ndarray:
        """The runs in coded units (-1 = min, 0 = centre, +1 = max): (n, k)."""
        raise NotImplementedError

    def array(self) -> np.ndarray:
        """The runs' variable values (n, k) [m], columns in ``variables``' order."""
        coded = np.rint(self.coded()).astype(int)
        levels = np.column_stack([f.levels(3) for f in self.factors])  # rows: max, centre, min
        return levels[1 - coded, np.arange(len(self.factors))]

    def points(self) -> list[tuple[float, ...]]:
        """Each run's values, in ``variables``' order (for (L, W): (L, W) [m])."""
        return [tuple(float(v) for v in row) for row in self.array()]

    def runs(self) -> list[dict[str, float]]:
        """Each run's values by name."""
        names = self.variables.names
        return [dict(zip(names, point, strict=True)) for point in self.points()]

    def corners(self) -> list[dict[str, float]]:
        """The 2^k corners of the box."""
        names = self.variables.names
        return [dict(zip(names, c, strict=True)) for c in itertools.product(*(f.range_m for f in self.factors))]

    def to_json(self) -> dict:
        """The doe.json ``design`` block."""
        return {
            "kind": self.kind,
            "variables": list(self.variables.names),
            "ranges": {f.name: list(f.range_m) for f in self.factors},
            "runs": len(self.points()),
            **self._json_details(),
        }

    def _json_details(self) -> dict:
        return {}


@dataclass(frozen=True)
class FullFactorial(ScaledDesign):
    """K levels per factor, K^k runs, Table 1 order generalised (module docstring).

    Attributes:
        levels: K (>= 3 for a quadratic fit).
    """

    levels: int = 3
    kind = "full-factorial"

    def __post_init__(self) -> None:
        super().__post_init__()
        check_positive_int("levels", self.levels, minimum=3)

    def array(self) -> np.ndarray:
        axes = [f.levels(self.levels) for f in self.factors]
        rows = [tuple(reversed(values)) for values in itertools.product(*reversed(axes))]
        return np.array(rows, dtype=float).reshape(-1, len(self.factors))

    def coded(self) -> np.ndarray:
        lo, hi = (np.array([f.range_m[i] for f in self.factors]) for i in (0, 1))
        return 2.0 * (self.array() - lo) / (hi - lo) - 1.0

    def to_json(self) -> dict:
        if self.variables.is_size_only:  # the paper's design: the doe.json block of old, key for key
            return {
                "levels": self.levels,
                "L_range": list(self.factors[0].range_m),
                "W_range": list(self.factors[1].range_m),
                "order": TABLE1_ORDER,
            }
        return super().to_json()

    def _json_details(self) -> dict:
        return {"levels": self.levels, "order": "every factor descending, the first fastest, the last slowest"}


def _pydoe():
    """The pyDOE module (``pydoe`` from 1.x, ``pyDOE`` before), imported where a response-surface
    design is built."""
    try:
        import pydoe
    except ImportError:  # pragma: no cover - the older distribution's module name
        import pyDOE as pydoe
    return pydoe


@dataclass(frozen=True)
class BoxBehnken(ScaledDesign):
    """pyDOE's Box-Behnken design with one centre run: 2 k (k - 1) + 1 runs (k >= 3)."""

    kind = "box-behnken"

    def __post_init__(self) -> None:
        super().__post_init__()
        if len(self.factors) < 3:
            names = ", ".join(self.variables.names)
            raise InvalidParameterError("design", self.kind, f"3 or more factors (this one varies {names} only)")

    def coded(self) -> np.ndarray:
        return np.asarray(_pydoe().bbdesign(len(self.factors), center=1), dtype=float)

    def _json_details(self) -> dict:
        return {"centre_runs": 1, "source": "pyDOE bbdesign"}


@dataclass(frozen=True)
class CentralComposite(ScaledDesign):
    """pyDOE's face-centred central composite design (alpha = 1) with one centre run: 2^k + 2 k + 1 runs."""

    kind = "central-composite"

    def coded(self) -> np.ndarray:
        return np.asarray(_pydoe().ccdesign(len(self.factors), center=(0, 1), face="ccf"), dtype=float)

    def _json_details(self) -> dict:
        return {"face": "centred", "alpha": 1, "centre_runs": 1, "source": "pyDOE ccdesign"}


#: The designs by their command-line name.
DESIGN_KINDS: Mapping[str, type[ScaledDesign]] = MappingProxyType(
    {cls.kind: cls for cls in (FullFactorial, BoxBehnken, CentralComposite)}
)


def design_class(name: str) -> type[ScaledDesign]:
    """The design class of a command-line name (one of :data:`DESIGN_KINDS`)."""
    return DESIGN_KINDS[check_name(name, DESIGN_KINDS, "design")]
