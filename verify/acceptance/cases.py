"""Which obstacles a sweep judges: the sampled rectangle of sizes, the seeded sampler, the paper's
DOE grid and the four case studies off it. Every length in m."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.offline.doe import Design
from pipeline.validation import check_positive, check_positive_int

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
    """The rectangle of obstacle sizes sampled [m].

    Attributes:
        L_m: (min, max) of L [m].
        W_m: (min, max) of W [m].
    """

    L_m: Pair
    W_m: Pair

    def __post_init__(self) -> None:
        for name, (lo, hi) in (("L", self.L_m), ("W", self.W_m)):
            check_positive(f"{name} min", lo)
            check_positive(f"{name} max", hi)
            if lo > hi:
                raise InvalidParameterError(f"{name} range", (lo, hi), "min <= max")
        object.__setattr__(self, "L_m", (float(self.L_m[0]), float(self.L_m[1])))
        object.__setattr__(self, "W_m", (float(self.W_m[0]), float(self.W_m[1])))

    @classmethod
    def from_fitted(cls, fitted_range_m: dict[str, Sequence[float]]) -> SweepRange:
        """The range of a coefficients file's ``fitted_range_m`` ({"L": (lo, hi), "W": (lo, hi)})."""
        return cls(tuple(fitted_range_m["L"]), tuple(fitted_range_m["W"]))  # type: ignore[arg-type]

    def contains(self, other: SweepRange) -> bool:
        """True if ``other`` lies inside this range."""
        return (
            self.L_m[0] <= other.L_m[0] <= other.L_m[1] <= self.L_m[1]
            and self.W_m[0] <= other.W_m[0] <= other.W_m[1] <= self.W_m[1]
        )

    def intersection(self, other: SweepRange) -> SweepRange | None:
        """The common part of both ranges, or None if they do not overlap."""
        lo_l, hi_l = max(self.L_m[0], other.L_m[0]), min(self.L_m[1], other.L_m[1])
        lo_w, hi_w = max(self.W_m[0], other.W_m[0]), min(self.W_m[1], other.W_m[1])
        if lo_l > hi_l or lo_w > hi_w:
            return None
        return SweepRange((lo_l, hi_l), (lo_w, hi_w))

    def widened(self, fraction: float, floor_m: float = 1e-3) -> SweepRange:
        """This range grown by ``fraction`` of its width on each side (never below ``floor_m`` [m])."""
        grow_l = fraction * (self.L_m[1] - self.L_m[0])
        grow_w = fraction * (self.W_m[1] - self.W_m[0])
        return SweepRange(
            (max(floor_m, self.L_m[0] - grow_l), self.L_m[1] + grow_l),
            (max(floor_m, self.W_m[0] - grow_w), self.W_m[1] + grow_w),
        )

    def to_dict(self) -> dict[str, list[float]]:
        """{"L": [lo, hi], "W": [lo, hi]} [m]."""
        return {"L": list(self.L_m), "W": list(self.W_m)}


def sample_cases(sweep_range: SweepRange, n: int, seed: int) -> np.ndarray:
    """n obstacle sizes (L, W) [m], uniform in ``sweep_range``, from ``numpy.random.default_rng(seed)``.

    Returns shape (n, 2). The same (range, n, seed) always gives the same cases.
    """
    check_positive_int("n", n, minimum=1)
    check_positive_int("seed", seed, minimum=0)
    rng = np.random.default_rng(seed)
    lengths = rng.uniform(sweep_range.L_m[0], sweep_range.L_m[1], n)
    widths = rng.uniform(sweep_range.W_m[0], sweep_range.W_m[1], n)
    return np.stack([lengths, widths], -1)


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
