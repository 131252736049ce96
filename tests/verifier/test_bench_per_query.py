"""The per-query rows of the benchmark (verify.benchmark.per_query): every call timed, the
generator's own answers, and the rows timed in interleaved passes (one pass of each in turn)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.exceptions import UnreachableObstacleError
from pipeline.offline.coefficients import Coefficients
from pipeline.online.generator import generate
from verify.benchmark import per_query
from verify.benchmark.per_query import PerQueryRow, time_side_by_side
from verify.benchmark.results import WARMUP_CALLS


@pytest.fixture(scope="module")
def paper() -> Coefficients:
    return load_coefficients("paper")


def test_rows_are_timed_in_interleaved_passes(paper: Coefficients, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[tuple[int, float]] = []

    def recording(coefficients, length, width, **given):
        assert type(length) is float and type(width) is float  # converted before the clock starts
        calls.append((id(coefficients), length))
        return generate(coefficients, length, width, **given)

    monkeypatch.setattr(per_query, "generate", recording)
    other = dataclasses.replace(paper, source="another object")
    first = PerQueryRow(paper, np.array([[0.21, 0.09], [0.22, 0.1], [0.23, 0.11]]))
    second = PerQueryRow(other, np.array([[0.27, 0.09], [0.28, 0.1]]))
    time_side_by_side([first, second], passes=4)
    warm = -(-WARMUP_CALLS // 3) * 3 + -(-WARMUP_CALLS // 2) * 2
    assert len(calls) == warm + 4 * 5
    rounds = [calls[warm + 5 * r : warm + 5 * (r + 1)] for r in range(4)]
    for timed in rounds:  # every round: the first row's pass, then the second's
        assert [key for key, _ in timed] == [id(paper)] * 3 + [id(other)] * 2
        assert [length for _, length in timed] == [0.21, 0.22, 0.23, 0.27, 0.28]
    assert len(first.times_s) == 12 and len(second.times_s) == 8
    assert all(t > 0.0 for t in first.times_s + second.times_s)


def test_answers_are_the_generators_and_refusals_are_none(paper: Coefficients) -> None:
    cases = np.array([[0.25, 0.1], [0.9, 0.1], [0.22, 0.09]])  # L = 0.9 m leaves the arm's reach
    with pytest.raises(UnreachableObstacleError):
        generate(paper, 0.9, 0.1)
    row = PerQueryRow(paper, cases)
    time_side_by_side([row], passes=2)
    assert row.answers[1] is None and len(row.times_s) == 6
    for (length, width), answer in zip(cases[[0, 2]], (row.answers[0], row.answers[2]), strict=True):
        assert answer.trajectory == generate(paper, float(length), float(width)).trajectory
