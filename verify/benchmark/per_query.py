"""The per-query rows of the benchmark, timed side by side: (a), (a*) and (a*) over the
coefficients' variables (L, W, x or L, W, x, d).

Each row calls :func:`pipeline.online.generator.generate` once per obstacle and times every call
with ``time.perf_counter``. The rows are timed in interleaved passes: round after round, one pass
of every row over its obstacles in turn. A shared machine has stretches of seconds in which the
same code runs up to twice as slowly; interleaved, every row samples the same stretches, so their
ratios hold, and many short rounds spread each row's median over the whole timing rather than
over the one stretch a row timed alone would fall into. The obstacles are converted to Python
floats before timing, as a caller's floats would be, so a call's time is the generator's alone.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import PipelineError
from pipeline.offline.coefficients import Coefficients
from pipeline.online.generator import generate
from pipeline.online.map_timing import near_optimal_from_map

from .results import WARMUP_CALLS


@dataclass
class PerQueryRow:
    """One per-query row being timed.

    Attributes:
        coefficients: Of the generator.
        cases: (n, 2) obstacles (L, W) [m], or (n, k) values of the coefficients' k variables
            (L, W, then x and/or d) [m] for coefficients that vary more than (L, W).
        region_map: The map the answers' bounds come from (None: no bounds).
        near_optimal: Time ``near_optimal_from_map`` (the certified near-optimal answer read off the
            coefficients' attached map) instead of ``generate``.
        times_s: Every timed call [s], in order.
        answers: The answers of the last pass, None where the generator refused.
    """

    coefficients: Coefficients
    cases: np.ndarray
    region_map: RegionMap | None = None
    near_optimal: bool = False
    times_s: list[float] = field(default_factory=list, init=False)
    answers: list[Any] = field(init=False)

    def __post_init__(self) -> None:
        self._rows = [tuple(float(v) for v in case) for case in np.asarray(self.cases)]
        extra = self.coefficients.variables.extra if np.shape(self.cases)[1] > 2 else ()
        self._moved = [dict(zip(extra, case[2:], strict=True)) for case in self._rows]  # x=, d= per call
        self.answers = [None] * len(self._rows)

    def warm_up(self) -> None:
        """Untimed passes (at least :data:`WARMUP_CALLS` calls), so that the timed calls find the
        plan and the map's tables built and every obstacle's code path run once."""
        for _ in range(-(-WARMUP_CALLS // len(self._rows))):
            self._pass(record=False)

    def timed_pass(self) -> None:
        """One pass over the obstacles, every call timed."""
        self._pass(record=True)

    def _pass(self, record: bool) -> None:
        coefficients, region_map, answers = self.coefficients, self.region_map, self.answers
        times, clock = self.times_s if record else [], time.perf_counter
        if self.near_optimal:
            for i, (length, width) in enumerate(self._rows):
                started = clock()
                try:
                    answers[i] = near_optimal_from_map(coefficients, length, width)
                except PipelineError:
                    answers[i] = None
                times.append(clock() - started)
        elif np.shape(self.cases)[1] == 2:
            for i, (length, width) in enumerate(self._rows):
                started = clock()
                try:
                    answers[i] = generate(coefficients, length, width, region_map=region_map)
                except PipelineError:
                    answers[i] = None
                times.append(clock() - started)
        else:
            for i, (case, moved) in enumerate(zip(self._rows, self._moved, strict=True)):
                started = clock()
                try:
                    answers[i] = generate(coefficients, case[0], case[1], region_map=region_map, **moved)
                except PipelineError:
                    answers[i] = None
                times.append(clock() - started)


def time_side_by_side(rows: Sequence[PerQueryRow], passes: int) -> None:
    """Warm every row up, then ``passes`` rounds of one timed pass of every row in turn."""
    for row in rows:
        row.warm_up()
    for _ in range(passes):
        for row in rows:
            row.timed_pass()
