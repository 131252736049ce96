"""The online step with the range certificate: ``generate`` returns the map's certified bounds,
which hold against Coal's distances and Pinocchio's kinematics, in microseconds; a map is never
used with coefficients it does not certify; ``generate_certified`` skips the per-query
certificate exactly where the map proves the margin."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from pipeline import load_coefficients
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import RegionMapMismatchError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance
from pipeline.model.arm import PlanarArm
from pipeline.online.batch import generate_batch
from pipeline.online.generator import RANGE_SOURCE, generate
from pipeline.online.loading import region_map_beside
from pipeline.online.repair import generate_certified


@pytest.fixture(scope="module")
def paper():
    return load_coefficients("paper")


@pytest.fixture(scope="module")
def paper_map(paper) -> RegionMap:
    return certify_range(paper, RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8))


def _tip(arm: PlanarArm, q: np.ndarray) -> np.ndarray:
    data = arm.model.createData()
    pin.framesForwardKinematics(arm.model, data, np.asarray(q, dtype=float))
    return arm.to_plane(data.oMf[arm.ee_frame_id].translation[None, :])[0]


def test_answers_carry_the_maps_bounds_and_they_hold(arm: PlanarArm, paper, paper_map: RegionMap) -> None:
    rng = np.random.default_rng(7)
    for L, W in zip(rng.uniform(0.2, 0.3, 25), rng.uniform(0.08, 0.12, 25), strict=True):
        answer = generate(paper, float(L), float(W), region_map=paper_map)
        assert answer.certificate_source == RANGE_SOURCE
        cell = paper_map.cell_at(float(L), float(W))
        assert answer.certified_clearance_m == cell.clearance_bound_m
        assert answer.endpoint_error_bound_m == cell.endpoint_bound_m
        assert answer.range_status == cell.status
        # Soundness against Coal on a dense grid and Pinocchio at both ends.
        times = np.linspace(0.0, answer.duration_s, 1001)
        sampled = CoalClearance(arm, answer.obstacle).link_clearance(answer.q(times)).min()
        assert answer.certified_clearance_m <= sampled + COAL_DISTANCE_ERROR_M
        errors = [
            np.linalg.norm(_tip(arm, answer.q(0.0)) - answer.path.points_m[0]),
            np.linalg.norm(_tip(arm, answer.q(answer.duration_s)) - answer.path.points_m[-1]),
        ]
        assert max(errors) <= answer.endpoint_error_bound_m + 1e-9


def test_no_bounds_without_a_map_or_outside_the_range(paper, paper_map: RegionMap) -> None:
    plain = generate(paper, 0.25, 0.10)
    assert plain.certificate_source is None and plain.certified_clearance_m is None
    outside = generate(paper, 0.31, 0.10, region_map=paper_map, out_of_range="ignore")
    assert outside.extrapolated and outside.certificate_source is None and outside.endpoint_error_bound_m is None


def test_a_map_of_other_coefficients_is_refused(paper, paper_map: RegionMap) -> None:
    other = dataclasses.replace(paper, source_sha256="0" * 64)
    with pytest.raises(RegionMapMismatchError) as info:
        generate(other, 0.25, 0.10, region_map=paper_map)
    assert info.value.coefficients_sha256 == "0" * 64
    assert "certify_range" in str(info.value)


def test_generate_certified_skips_the_query_certificate_only_in_margin_cells(
    arm: PlanarArm, paper, paper_map: RegionMap
) -> None:
    margin = paper.scene.margin_m
    seen = set()
    rng = np.random.default_rng(3)
    for L, W in zip(rng.uniform(0.2, 0.3, 40), rng.uniform(0.08, 0.12, 40), strict=True):
        cell = paper_map.cell_at(float(L), float(W))
        try:
            answer = generate_certified(paper, float(L), float(W), arm, region_map=paper_map)
        except Exception:  # a refusal happens only off the margin cells
            assert cell.status != "margin"
            continue
        assert answer.certified_clearance_m >= margin
        if cell.status == "margin" and cell.clearance_bound_m >= margin:
            assert answer.certificate_source == "range" and answer.certificate is None
        else:
            assert answer.certificate_source == "query" and answer.certificate is not None
        seen.add(answer.certificate_source)
    assert seen == {"range", "query"}  # Eq. 9 keeps the margin in part of its range only


def test_the_shipped_paper_coefficients_have_no_map_beside_them(paper) -> None:
    assert region_map_beside(paper) is None and paper.region_map is None


def test_batched_answers_carry_the_same_bounds(paper, paper_map: RegionMap) -> None:
    rng = np.random.default_rng(11)
    L, W = rng.uniform(0.19, 0.31, 300), rng.uniform(0.075, 0.125, 300)
    batch = generate_batch(paper, L, W, region_map=paper_map)
    for i in range(L.size):
        one = generate(paper, float(L[i]), float(W[i]), region_map=paper_map, out_of_range="ignore")
        if one.certificate_source is None:
            assert np.isnan(batch.certified_clearance_m[i]) and batch.range_status[i] == -1
        else:
            assert batch.certified_clearance_m[i] == one.certified_clearance_m
            assert batch.endpoint_error_bound_m[i] == one.endpoint_error_bound_m
    assert generate_batch(paper, L, W).certified_clearance_m is None
