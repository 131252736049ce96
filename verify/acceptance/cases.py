"""Which obstacles a sweep judges: the sampled box of sizes (and of the coefficients' other scene
variables), the seeded sampler, the paper's DOE grid and the four case studies off it. Every
length in m."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.offline.doe import Design
from pipeline.offline.variables import NAMES, SIZE, Variables, check_name
from pipeline.validation import check_finite, check_positive, check_positive_int

Pair = tuple[float, float]

#: The paper's DOE grid (Table 1): the levels of L and of W [m], ascending.
DOE_L_M: tuple[float, ...] = tuple(sorted({length for length, _ in Design().points()}))
DOE_W_M: tuple[float, ...] = tuple(sorted({width for _, width in Design().points()}))
#: Where the four case studies sit in the fitted range, as fractions (of L, of W); they fall off
#: the DOE grid: with the paper's range they are (0.270, 0.110), (0.220, 0.090), (0.280, 0.085)
#: and (0.230, 0.115) m.
CASE_STUDY_FRACTIONS = ((0.70, 0.75), (0.20, 0.25), (0.80, 0.125), (0.30, 0.875))


@dataclass(frozen=True)
class SweepRange:
    """The box of scene values sampled [m]: the obstacle's size (L, W) and, for coefficients that
    vary more scene variables (:mod:`pipeline.offline.variables`, e.g. the obstacle's centre x),
    a range per extra variable.

    Attributes:
        L_m: (min, max) of L [m].
        W_m: (min, max) of W [m].
        extra_m: ((name, (min, max)), ...) of each extra variable, in the canonical order of
            :data:`pipeline.offline.variables.NAMES` [m] (empty: the box is (L, W)).
    """

    L_m: Pair
    W_m: Pair
    extra_m: tuple[tuple[str, Pair], ...] = ()

    def __post_init__(self) -> None:
        for name, (lo, hi) in (("L", self.L_m), ("W", self.W_m)):
            check_positive(f"{name} min", lo)
            check_positive(f"{name} max", hi)
            if lo > hi:
                raise InvalidParameterError(f"{name} range", (lo, hi), "min <= max")
        extra = []
        for name, (lo, hi) in self.extra_m:
            check_name(name, NAMES[2:])
            check_finite(f"{name} min", lo)
            check_finite(f"{name} max", hi)
            if lo > hi:
                raise InvalidParameterError(f"{name} range", (lo, hi), "min <= max")
            extra.append((name, (float(lo), float(hi))))
        names = [name for name, _ in extra]
        if names != sorted(set(names), key=NAMES.index):
            raise InvalidParameterError("extra variables", names, "each once, in the order " + ", ".join(NAMES[2:]))
        object.__setattr__(self, "L_m", (float(self.L_m[0]), float(self.L_m[1])))
        object.__setattr__(self, "W_m", (float(self.W_m[0]), float(self.W_m[1])))
        object.__setattr__(self, "extra_m", tuple(extra))

    @classmethod
    def from_fitted(cls, fitted_range_m: dict[str, Sequence[float]], names: Sequence[str] = SIZE) -> SweepRange:
        """The range of a coefficients file's ``fitted_range_m`` ({"L": (lo, hi), "W": (lo, hi),
        ...}) over the variables ``names`` (default (L, W); ``coefficients.variables.names`` for
        the whole box of the coefficients)."""
        extra = tuple((name, tuple(fitted_range_m[name])) for name in Variables.of(names).extra)
        return cls(tuple(fitted_range_m["L"]), tuple(fitted_range_m["W"]), extra)  # type: ignore[arg-type]

    @property
    def names(self) -> tuple[str, ...]:
        """The sampled variables: L, W, then the extra ones."""
        return (*SIZE, *(name for name, _ in self.extra_m))

    @property
    def ranges_m(self) -> tuple[Pair, ...]:
        """(min, max) of every variable of :attr:`names` [m]."""
        return (self.L_m, self.W_m, *(pair for _, pair in self.extra_m))

    def contains(self, other: SweepRange) -> bool:
        """True if ``other`` lies inside this range (over the same variables)."""
        return self.names == other.names and all(
            lo <= o_lo <= o_hi <= hi for (lo, hi), (o_lo, o_hi) in zip(self.ranges_m, other.ranges_m, strict=True)
        )

    def intersection(self, other: SweepRange) -> SweepRange | None:
        """The common part of both ranges, or None if they do not overlap.

        Raises:
            InvalidParameterError: the ranges are over different variables.
        """
        if self.names != other.names:
            raise InvalidParameterError(
                "ranges", [list(self.names), list(other.names)], "ranges over the same variables"
            )
        common = [
            (max(lo, o_lo), min(hi, o_hi)) for (lo, hi), (o_lo, o_hi) in zip(self.ranges_m, other.ranges_m, strict=True)
        ]
        if any(lo > hi for lo, hi in common):
            return None
        return SweepRange(common[0], common[1], tuple(zip(self.names[2:], common[2:], strict=True)))

    def widened(self, fraction: float, floor_m: float = 1e-3) -> SweepRange:
        """This range grown by ``fraction`` of its width on each side (L and W never below
        ``floor_m`` [m])."""
        grow_l = fraction * (self.L_m[1] - self.L_m[0])
        grow_w = fraction * (self.W_m[1] - self.W_m[0])
        extra = tuple((name, (lo - fraction * (hi - lo), hi + fraction * (hi - lo))) for name, (lo, hi) in self.extra_m)
        return SweepRange(
            (max(floor_m, self.L_m[0] - grow_l), self.L_m[1] + grow_l),
            (max(floor_m, self.W_m[0] - grow_w), self.W_m[1] + grow_w),
            extra,
        )

    def to_dict(self) -> dict[str, list[float]]:
        """{"L": [lo, hi], "W": [lo, hi]} [m], and [lo, hi] per extra variable."""
        return {"L": list(self.L_m), "W": list(self.W_m), **{name: list(pair) for name, pair in self.extra_m}}

    def describe(self) -> str:
        """ "L in [lo, hi] m, W in [lo, hi] m" and one such item per extra variable."""
        pairs = zip(self.names, self.ranges_m, strict=True)
        return ", ".join(f"{name} in [{lo:.4f}, {hi:.4f}] m" for name, (lo, hi) in pairs)


def sample_cases(sweep_range: SweepRange, n: int, seed: int) -> np.ndarray:
    """n points (L, W, then the extra variables) [m], uniform in ``sweep_range``, from
    ``numpy.random.default_rng(seed)``: n values of L, then n of W, then n of each extra variable.

    Returns shape (n, k), k = ``len(sweep_range.names)`` (2 for (L, W), whose cases do not depend
    on the extra variables). The same (range, n, seed) always gives the same cases.
    """
    check_positive_int("n", n, minimum=1)
    check_positive_int("seed", seed, minimum=0)
    rng = np.random.default_rng(seed)
    columns = [rng.uniform(lo, hi, n) for lo, hi in sweep_range.ranges_m]
    return np.stack(columns, -1)


def case_study_sizes(fitted: SweepRange) -> list[Pair]:
    """The four case-study obstacles (L, W) [m]: inside the fitted range, off the DOE grid, to 1 mm."""
    sizes = []
    for fl, fw in CASE_STUDY_FRACTIONS:
        length = round(fitted.L_m[0] + fl * (fitted.L_m[1] - fitted.L_m[0]), 3)
        width = round(fitted.W_m[0] + fw * (fitted.W_m[1] - fitted.W_m[0]), 3)
        sizes.append((length, width))
    return sizes


def on_doe_grid(length_m: float, width_m: float) -> bool:
    """True if (L, W) is one of the paper's nine DOE points."""
    return any(math.isclose(length_m, a, abs_tol=1e-9) for a in DOE_L_M) and any(
        math.isclose(width_m, b, abs_tol=1e-9) for b in DOE_W_M
    )
