"""The sweep's cases against a region map (verify.acceptance.range_check): a true map holds on
every case, and deliberately wrong maps (clearance bound raised above the measured clearance,
endpoint bound lowered below the measured error, edited in the map's JSON) are caught case by
case; a map of other coefficients is reported as not belonging and not checked.

The map is the paper's Eq. 9 certified at a coarse setting (256 leaves, about 2 s); the cases
are measured with every certificate tight (and, in one test, in the sweep's default decide
mode). Per-case expectations are computed through the scalar route (:meth:`RegionMap.cell_at`),
independently of the vectorised ``cells_at`` the check uses.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.map_files import save_region_map
from pipeline.certify.map_for_coefficients import DEFAULT_MAP_NAME
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import DataFileError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M
from pipeline.offline.coefficients import save_coefficients
from pipeline.online.loading import map_path_beside
from verify.acceptance.metrics import MeasureSettings
from verify.acceptance.range_check import (
    ENDPOINT_SLACK_M,
    SAMPLED_SLACK_M,
    check_range,
    clearance_slack_m,
)
from verify.acceptance.results import failed_case
from verify.acceptance.run import run_cases
from verify.cli_support import load_coefficients_for_verify

SETTINGS = MeasureSettings(time_samples=200, certificate_mode="tight")  # every bound tight: every case compared
COARSE = RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8)
#: Ten cases inside the fitted range (0.2..0.3 x 0.08..0.12 m) and one outside it.
CASES_M = np.array(
    [
        [0.205, 0.085],
        [0.215, 0.118],
        [0.232, 0.095],
        [0.247, 0.111],
        [0.251, 0.082],
        [0.263, 0.104],
        [0.271, 0.117],
        [0.284, 0.089],
        [0.292, 0.108],
        [0.299, 0.119],
        [0.310, 0.100],  # outside the fitted range
    ]
)


@pytest.fixture(scope="module")
def paper():
    return load_coefficients("paper")


@pytest.fixture(scope="module")
def region_map(paper) -> RegionMap:
    return certify_range(paper, COARSE)


@pytest.fixture(scope="module")
def cases(paper):
    return run_cases("paper", CASES_M, SETTINGS, coefficients=paper)


def edited(region_map: RegionMap, edit) -> RegionMap:
    """The map through its JSON, after ``edit(document)``."""
    document = copy.deepcopy(region_map.to_json())
    edit(document)
    return RegionMap.from_json(document)


def leaf_of(region_map: RegionMap, case) -> tuple[float, float]:
    """(clearance bound, endpoint bound) [m] of the case's leaf, by the scalar lookup."""
    cell = region_map.cell_at(case.L_m, case.W_m)
    return cell.clearance_bound_m, cell.endpoint_bound_m


def leaf_number(region_map: RegionMap, case) -> int:
    return int(region_map.leaf_indices(case.L_m, case.W_m))


def test_slacks_are_the_documented_sums() -> None:
    assert clearance_slack_m(SETTINGS) == pytest.approx(SETTINGS.tolerance_m + 2 * COAL_DISTANCE_ERROR_M, abs=2e-9)
    assert SAMPLED_SLACK_M == pytest.approx(COAL_DISTANCE_ERROR_M, abs=2e-9)
    assert 0 < ENDPOINT_SLACK_M <= 1e-9


def test_the_true_map_holds_on_every_case(region_map, paper, cases) -> None:
    check = check_range(region_map, paper, cases, SETTINGS)
    assert check.map.belongs and check.checked and check.passed and check.violations == ()
    assert check.n_cases == 11 and check.n_out_of_range == 1 and check.n_not_measured == 0
    assert check.n_certificate_decided == check.n_certificate_unconverged == 0
    assert check.certified.checked == check.sampled.checked == check.endpoint.checked == 10
    inside = [c for c in cases if c.L_m <= 0.3]
    certified = min(c.certified_clearance_m - leaf_of(region_map, c)[0] for c in inside)
    sampled = min(c.clearance_m - leaf_of(region_map, c)[0] for c in inside)
    endpoint = min(leaf_of(region_map, c)[1] - c.endpoint_error_m for c in inside)
    assert check.certified.worst_slack_m == pytest.approx(certified, abs=1e-15)
    assert check.sampled.worst_slack_m == pytest.approx(sampled, abs=1e-15)
    assert check.endpoint.worst_slack_m == pytest.approx(endpoint, abs=1e-15)
    assert certified > -clearance_slack_m(SETTINGS) and endpoint >= 0.0
    summary = region_map.summary()
    assert check.map.area_fraction == summary["area_fraction"]
    assert check.map.clearance_bound_min_m == float(region_map.clearance_bound_m.min())
    assert list(check.map.worst_cell_L_m) == summary["worst_cell"]["L_m"]
    assert check.map.endpoint_bound_max_m == float(region_map.endpoint_bound_m.max())
    assert sum(check.map.area_fraction.values()) == pytest.approx(1.0, abs=1e-12)


def test_a_clearance_bound_raised_above_the_clearance_is_caught(region_map, paper, cases) -> None:
    target = cases[3]
    leaf = leaf_number(region_map, target)
    sharing = {c.index for c in cases if c.L_m <= 0.3 and leaf_number(region_map, c) == leaf}

    def raise_bound(document: dict) -> None:
        document["cells"]["clearance_bound_m"][leaf] = target.clearance_m + 1e-3  # above the sampled minimum

    wrong = edited(region_map, raise_bound)
    check = check_range(wrong, paper, cases, SETTINGS)
    assert not check.passed and target.index in check.violations
    assert target.index in check.certified.violations and target.index in check.sampled.violations
    assert set(check.violations) <= sharing and check.endpoint.violations == ()
    assert check.sampled.worst_slack_m <= target.clearance_m - (target.clearance_m + 1e-3) + 1e-15
    assert check.to_json()["cross_check"]["passed"] is False


def test_every_bound_raised_by_a_centimetre_contradicts_every_case(region_map, paper, cases) -> None:
    def raise_all(document: dict) -> None:
        cells = document["cells"]
        cells["clearance_bound_m"] = [None if v is None else v + 0.01 for v in cells["clearance_bound_m"]]

    check = check_range(edited(region_map, raise_all), paper, cases, SETTINGS)
    expected = []
    for c in cases:
        if c.L_m <= 0.3 and leaf_of(region_map, c)[0] + 0.01 > c.certified_clearance_m + clearance_slack_m(SETTINGS):
            expected.append(c.index)
    assert list(check.certified.violations) == expected and expected  # not vacuous


def test_the_certified_check_allows_exactly_the_documented_slack(region_map, paper, cases) -> None:
    target = cases[5]
    leaf = leaf_number(region_map, target)
    for factor, violated in ((0.9, False), (1.1, True)):

        def set_bound(document: dict, factor: float = factor) -> None:
            slack = clearance_slack_m(SETTINGS)
            document["cells"]["clearance_bound_m"][leaf] = target.certified_clearance_m + factor * slack

        check = check_range(edited(region_map, set_bound), paper, cases, SETTINGS)
        assert (target.index in check.certified.violations) is violated


def test_an_endpoint_bound_lowered_below_the_error_is_caught(region_map, paper, cases) -> None:
    target = cases[7]
    leaf = leaf_number(region_map, target)
    for lowered_by, violated in ((1e-6, True), (0.0, False)):

        def lower(document: dict, lowered_by: float = lowered_by) -> None:
            document["cells"]["endpoint_bound_m"][leaf] = target.endpoint_error_m - lowered_by

        check = check_range(edited(region_map, lower), paper, cases, SETTINGS)
        assert (target.index in check.endpoint.violations) is violated
        assert check.passed is (not check.violations)
        if violated:
            assert check.endpoint.worst_slack_m == pytest.approx(-lowered_by, abs=1e-12)
            assert check.certified.violations == () and check.sampled.violations == ()


def test_a_map_of_other_coefficients_is_flagged_and_not_used(region_map, paper, cases) -> None:
    def other(document: dict) -> None:
        document["coefficients"]["sha256"] = "0" * 64
        document["cells"]["clearance_bound_m"] = [1.0] * len(document["cells"]["clearance_bound_m"])  # absurd

    check = check_range(edited(region_map, other), paper, cases, SETTINGS)
    assert not check.map.belongs and not check.checked and check.passed
    assert check.certified is None and check.endpoint is None and check.region_map is None
    data = check.to_json()
    assert data["belongs_to_coefficients"] is False and data["cross_check"]["checked"] is False


def test_cases_out_of_range_or_not_generated_are_counted_not_checked(region_map, paper, cases) -> None:
    broken = failed_case(11, 0.25, 0.10, False, "UnreachableObstacleError: made up")
    check = check_range(region_map, paper, [*cases, broken], SETTINGS)
    assert check.n_cases == 12 and check.n_out_of_range == 1 and check.n_not_measured == 1
    assert check.endpoint.checked == 10 and check.passed


def test_the_commands_attach_the_map_beside_a_coefficients_file_only_if_it_certifies_them(
    capsys, tmp_path, paper
) -> None:
    """verify's commands load the coefficients as pipeline.load_coefficients does: the map beside
    them attached if it certifies them; one of other coefficients not attached, with a one-line
    warning; a broken one an error that says how to go on; none read when the command asks for
    none."""
    source = tmp_path / "coefficients.json"
    save_coefficients(paper, source)
    assert load_coefficients_for_verify("prog", str(source)).region_map is None
    beside = tmp_path / DEFAULT_MAP_NAME
    save_region_map(certify_range(load_coefficients(source, region_map=None), COARSE), beside)
    found = load_coefficients_for_verify("prog", str(source))
    assert found.region_map is not None and found.region_map.belongs_to(found)
    assert map_path_beside(found) == beside and capsys.readouterr().err == ""
    source.write_text(source.read_text() + "\n")  # other bytes, other sha256: the map no longer belongs
    changed = load_coefficients_for_verify("prog", str(source))
    err = capsys.readouterr().err
    assert changed.region_map is None and err.startswith("prog: warning: ") and len(err.splitlines()) == 1
    assert str(beside) in err and "python -m pipeline.certify_range" in err
    assert load_coefficients_for_verify("prog", "paper").region_map is None  # Eq. 9 has no file beside it
    beside.write_text("{not json")
    with pytest.raises(DataFileError, match="--no-region-map skips it") as info:
        load_coefficients_for_verify("prog", str(source), malformed_hint="--no-region-map skips it")
    assert info.value.path == beside
    assert load_coefficients_for_verify("prog", str(source), beside=False).region_map is None  # not read
    with pytest.raises(DataFileError, match="coefficients file not found"):  # as pipeline.cli says
        load_coefficients_for_verify("prog", str(tmp_path / "missing.json"), beside=False)


def test_in_decide_mode_only_tight_bounds_are_compared(region_map, paper, cases) -> None:
    """Decide mode: a case above the margin only gets a bound >= the margin, not comparable with the
    map's; the sampled check still covers it."""
    settings = MeasureSettings(time_samples=200)
    assert settings.certificate_mode == "decide"
    decided = run_cases("paper", CASES_M, settings, coefficients=paper)
    loose = [c for c in decided if c.L_m <= 0.3 and not c.certificate.tight]
    assert loose and len(loose) < 10  # both kinds among the ten cases in range
    check = check_range(region_map, paper, decided, settings)
    assert check.passed and check.n_certificate_decided == len(loose)
    assert check.certified.checked == 10 - len(loose) and check.sampled.checked == 10
    # A bound between a loose case's certified value and its sampled minimum is no contradiction,
    # one above the sampled minimum (plus Coal's error) is.
    target = loose[0]
    leaf = leaf_number(region_map, target)
    middle = (target.certified_clearance_m + target.clearance_m) / 2
    assert target.clearance_m - middle > SAMPLED_SLACK_M  # the decided bound lies well below the samples
    for bound, violated in ((middle, False), (target.clearance_m + 1e-3, True)):

        def set_bound(document: dict, bound: float = bound) -> None:
            document["cells"]["clearance_bound_m"][leaf] = bound

        result = check_range(edited(region_map, set_bound), paper, decided, settings)
        assert target.index not in result.certified.violations
        assert (target.index in result.sampled.violations) is violated
