"""Batched generation and certification (pipeline.online.batch) equal the per-query functions."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.sinusoid_certificate import certify_trajectory
from pipeline.online.batch import generate_batch
from pipeline.online.batch_certify import certify_batch
from pipeline.online.generator import generate


@pytest.fixture(scope="module")
def paper():
    return load_coefficients("paper")


def test_batch_equals_single_queries_including_refusals(paper) -> None:
    rng = np.random.default_rng(4)
    L = np.concatenate([rng.uniform(0.15, 0.35, 200), [0.001, np.nan, 1.5, 0.25, -1.0]])
    W = np.concatenate([rng.uniform(0.06, 0.14, 200), [0.001, 0.1, 0.1, 0.6, 0.1]])
    batch = generate_batch(paper, L, W)
    for i in range(L.size):
        try:
            answer = generate(paper, float(L[i]), float(W[i]), out_of_range="ignore")
        except Exception as exc:
            assert batch.error[i] is not None and type(exc).__name__ in batch.error[i]
            assert np.isnan(batch.durations_s[i])
            continue
        assert batch.error[i] is None
        assert abs(batch.durations_s[i] - answer.duration_s) <= 1e-12 * answer.duration_s
        assert np.max(np.abs(batch.parameters[i] - answer.trajectory.parameters)) <= 1e-12
        assert batch.extrapolated[i] == answer.extrapolated
    assert sum(e is not None for e in batch.error) == 5
    with pytest.raises(InvalidParameterError):
        batch.trajectory(200)
    with pytest.raises(InvalidParameterError):
        generate_batch(paper, [0.2, 0.3], [0.1])


def test_certify_batch_equals_per_query_certificates(paper, arm) -> None:
    rng = np.random.default_rng(6)
    # Eq. 9 near W = 0.12 m passes within the margin: both branches of the decide mode are exercised.
    batch = generate_batch(paper, rng.uniform(0.2, 0.3, 12), rng.uniform(0.1, 0.125, 12))
    for decide in (None, paper.scene.margin_m):
        result = certify_batch(paper, batch, arm, decide_above_m=decide)
        if decide is not None:
            assert 0 < np.sum(result.certified_clearance_m <= decide) < 12
        for i in range(12):
            answer = generate(paper, float(batch.lengths_m[i]), float(batch.widths_m[i]), out_of_range="ignore")
            single = certify_trajectory(answer.trajectory, arm, answer.obstacle, decide_above_m=decide)
            if decide is not None and single.certified_clearance_m <= decide:
                single = certify_trajectory(answer.trajectory, arm, answer.obstacle, decide_above_m=0.0)
                assert result.evaluations[i] > single.evaluations
            else:
                assert result.evaluations[i] == single.evaluations
            assert result.certified_clearance_m[i] == pytest.approx(single.certified_clearance_m, abs=1e-12)
