"""The certifiable regression's pieces (pipeline.certify.certifiable_regression): the clearance
it constrains against the generator and the analytic route, its Jacobian against finite
differences, one refit lifting the clearance at its constraint points, and the build's
file-level round (rewritten coefficients, map linked to them)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.certifiable_regression import (
    CertifiableFitConfig,
    clearance_at,
    clearance_grid,
    clearance_jacobian,
    clearance_points,
    refit,
    refit_for_clearance,
)
from pipeline.certify.end_pose_room import ROOM_ANGLES, ROOM_RINGS, end_pose_room_m
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance, analytic_link_clearance
from pipeline.model.arm import PlanarArm
from pipeline.model.kinematics import inverse_kinematics
from pipeline.model.obstacle import Obstacle
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import Coefficients, fit_coefficients, paper_data_path, save_coefficients
from pipeline.offline.doe import load_doe
from pipeline.offline.endpoint_regression import EndpointConstraint, endpoint_targets
from pipeline.online.generator import generate


@pytest.fixture(scope="module")
def eq9() -> Coefficients:
    return load_coefficients("paper")


def _matrix(coefficients: Coefficients) -> np.ndarray:
    return np.stack([coefficients.parameters[name] for name in PARAMETER_NAMES], -1).ravel()


def _points(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(0.2, 0.3, n), rng.uniform(0.08, 0.12, n), rng.uniform(0.0, 1.0, n)])


def test_constrained_clearance_is_the_generators(eq9: Coefficients, arm: PlanarArm) -> None:
    points = _points(50, 0)
    values = clearance_at(_matrix(eq9), clearance_points(eq9, points), eq9)
    for (L, W, s), value in zip(points, values, strict=True):
        answer = generate(eq9, L, W)
        expected = analytic_link_clearance(answer.q(s * answer.duration_s), arm, answer.obstacle).min()
        assert value == pytest.approx(expected, abs=1e-12)


def test_clearance_jacobian_matches_finite_differences(eq9: Coefficients) -> None:
    data = clearance_points(eq9, _points(20, 1))
    b = _matrix(eq9)
    jacobian = clearance_jacobian(b, data, eq9)
    step = 1e-7
    for k in np.random.default_rng(2).choice(48, 8, replace=False):
        e = np.zeros(48)
        e[k] = step
        numeric = (clearance_at(b + e, data, eq9) - clearance_at(b - e, data, eq9)) / (2 * step)
        assert jacobian[:, k] == pytest.approx(numeric, rel=1e-4, abs=1e-6)


def test_refit_lifts_the_clearance_at_its_points(eq9: Coefficients) -> None:
    """Eq. 9 dips below the margin near W = 0.12 m; one refit on Table 2's optima with those
    points as constraints (endpoint tolerance loose, so only the clearance binds) lifts them."""
    doe = load_doe(paper_data_path("paper_table2_doe.json"))
    points = np.array([[L, 0.117, s] for L in (0.2, 0.25) for s in np.linspace(0.9, 1.0, 4)])
    data = clearance_points(eq9, points)
    before = clearance_at(_matrix(eq9), data, eq9)
    assert np.min(before) < 0.0105
    config = CertifiableFitConfig(endpoint=EndpointConstraint(tolerance_m=0.02, grid_points=3, max_iterations=100))
    targets = endpoint_targets(eq9.fitted_range_m, eq9.scene, eq9.link_lengths_m, 3)
    fitted, _ = refit(eq9, doe.points, doe.free_parameters(), targets, data, 0.0105, config)
    after = clearance_at(_matrix(fitted), data, fitted)
    assert np.min(after) >= 0.0105 + config.cushion_m - 1e-6


def refit_file(path, doe, config):
    """:func:`refit_for_clearance` on the file ``path``, its text written back (as the build writes it)."""
    start = load_coefficients(path, region_map=None)
    saved, text, region_map, report = refit_for_clearance(start, doe, config, str(path))
    path.write_text(text, encoding="utf-8")
    return saved, region_map, report


def test_refit_file_rewrites_the_coefficients_and_links_their_map(tmp_path) -> None:
    """One round on Table 2's endpoint-constrained fit, coarse cells: the file is rewritten with
    the rounds (no times in it, so it stays reproducible), the map belongs to the file as written
    and is the certificate of exactly those coefficients, and the margin's area did not shrink."""
    doe = load_doe(paper_data_path("paper_table2_doe.json"))
    fitted, _ = fit_coefficients(doe, None, EndpointConstraint())
    path = tmp_path / "coefficients.json"
    save_coefficients(fitted, path)
    certificate = RangeCertificateConfig(
        min_cell=1 / 32, boundary_cell=1 / 16, strip_split=0
    )  # strips: tests/certify/test_strip_split.py
    config = CertifiableFitConfig(certificate=certificate, max_rounds=1)
    saved, region_map, report = refit_file(path, doe, config)
    assert region_map.belongs_to(load_coefficients(path)) and saved.parameters == load_coefficients(path).parameters
    again = certify_range(saved, certificate)
    assert np.array_equal(again.status, region_map.status)
    assert np.allclose(again.clearance_bound_m, region_map.clearance_bound_m, rtol=0, atol=1e-15)
    block = saved.extra["fit"]["clearance_refit"]
    assert [r["round"] for r in block["rounds"]] == [r["round"] for r in report["rounds"]]
    assert not any(key.endswith("_seconds") for r in block["rounds"] for key in r)
    before, after = report["rounds"][0]["area_fraction"], region_map.summary()["area_fraction"]
    assert after["margin"] >= before["margin"]
    assert saved.extra["fit"]["regression"].endswith("clearance constraint generation")


@pytest.mark.parametrize(("margin_m", "tolerance_m"), [(None, 0.002), (0.002, 0.01)])
def test_the_last_round_certifies_with_the_final_cells(tmp_path, margin_m, tolerance_m) -> None:
    """Rounds on coarse cells, the returned map on finer ones (the build's split): the map is
    the final certificate of the file's coefficients, as certify_range makes it, and the last
    round records its fractions. With a 2 mm margin and a 1 cm endpoint tolerance the first map is
    clean, the loop stops
    before its last round, and the fit is certified once more with the final cells."""
    doe = load_doe(paper_data_path("paper_table2_doe.json"))
    fitted, _ = fit_coefficients(doe, None, EndpointConstraint())
    path = tmp_path / "coefficients.json"
    save_coefficients(fitted, path)
    cells = {"margin_m": margin_m, "endpoint_tolerance_m": tolerance_m, "boundary_cell": 1 / 16}
    coarse = RangeCertificateConfig(min_cell=1 / 32, strip_split=0, **cells)  # the build's rounds: no strips
    final = RangeCertificateConfig(min_cell=1 / 128, **cells)
    config = CertifiableFitConfig(certificate=coarse, final_certificate=final, max_rounds=1)
    saved, region_map, report = refit_file(path, doe, config)
    again = certify_range(saved, final)
    assert np.array_equal(again.subpaving.children, region_map.subpaving.children)
    assert np.array_equal(again.status, region_map.status)
    if margin_m is None:  # at the 1 cm margin the map resolves finer than the rounds' cells could
        assert region_map.subpaving.levels[:, 0].max() > 5
    last = report["rounds"][-1]
    recorded = last.get("final_area_fraction", last["area_fraction"])
    assert recorded == region_map.summary()["area_fraction"]
    assert ("final_area_fraction" in last) == (margin_m is not None)
    # each round records the cells its map was certified with, the file too
    first_cells = {"min_cell": 1 / 32, "boundary_cell": 1 / 16}
    final_cells = {"min_cell": 1 / 128, "boundary_cell": 1 / 16}
    assert {k: report["rounds"][0][k] for k in first_cells} == first_cells
    assert last.get("final_cells", {k: last[k] for k in final_cells}) == final_cells
    assert saved.extra["fit"]["clearance_refit"]["rounds"][-1]["min_cell"] == last["min_cell"]


@pytest.mark.parametrize("field", ["certificate", "final_certificate"])
def test_certificate_settings_must_be_certificate_configs(field: str) -> None:
    with pytest.raises(InvalidParameterError, match=field):
        CertifiableFitConfig(**{field: {"min_cell": 1 / 512}})


def test_end_pose_room_is_coals_sampled_room(eq9: Coefficients, arm: PlanarArm) -> None:
    """The refit's sampled room at the ends against Coal on the same tips (Pinocchio-free IK of
    the model module, Coal through the arm's geometry): equal to Coal's error, and below the
    margin exactly where the strip near W = 0.12 m leaves no room (0.20, 0.12), above it far away."""
    sizes = np.array([[0.2, 0.12], [0.25, 0.119], [0.27, 0.09]])
    room = end_pose_room_m(eq9, sizes[:, 0], sizes[:, 1], 0.002)
    radii = np.linspace(0.0, 0.002, ROOM_RINGS)
    angles = np.linspace(0.0, 2 * np.pi, ROOM_ANGLES, endpoint=False)
    for (L, W), value in zip(sizes, room, strict=True):
        coal = CoalClearance(arm, Obstacle.in_scene(L, W, eq9.scene))
        ends = []
        for side in (1.0, -1.0):
            end = np.array([side * (L / 2 + eq9.scene.start_dx_m), eq9.scene.y1_m])
            tips = [end + r * np.array([np.cos(a), np.sin(a)]) for r in radii for a in angles]
            poses = [inverse_kinematics(tip, arm.link_lengths_m, eq9.elbow) for tip in tips]
            ends.append(max(float(coal.link_clearance(q).min()) for q in poses))
        assert value == pytest.approx(min(ends), abs=COAL_DISTANCE_ERROR_M)
    assert room[0] < eq9.scene.margin_m < room[2]


def test_a_refit_that_fails_is_retried_without_the_tightest_points(monkeypatch) -> None:
    """The first refit is made to fail: the round retries with only the points whose end poses
    keep margin + a retry slack (each checked by end_pose_room_m), records that slack, and keeps
    the retry's converged fit."""
    from pipeline.certify import certifiable_regression as module

    doe = load_doe(paper_data_path("paper_table2_doe.json"))
    fitted, _ = fit_coefficients(doe, None, EndpointConstraint())
    calls = []
    real = module.refit

    def failing_first(start, points, values, targets, clearance, margin_m, config):
        calls.append(clearance.points.copy())
        result, converged = real(start, points, values, targets, clearance, margin_m, config)
        return result, converged and len(calls) > 1

    monkeypatch.setattr(module, "refit", failing_first)
    certificate = RangeCertificateConfig(
        min_cell=1 / 64, boundary_cell=1 / 16, strip_split=0
    )  # strips: tests/certify/test_strip_split.py
    config = CertifiableFitConfig(certificate=certificate, max_rounds=1)
    _, _, report = module.fit_certifiable(fitted, doe.points, doe.free_parameters(), config)
    first = report["rounds"][0]
    assert len(calls) >= 2 and first["refit_converged"]
    slack = first["retried_without_points_below_m"]
    assert slack in module.RETRY_SLACKS_M
    assert 0 < len(calls[-1]) < len(calls[0])
    room = end_pose_room_m(fitted, calls[-1][:, 0], calls[-1][:, 1], config.endpoint.fit_tolerance_m)
    assert np.all(room >= fitted.scene.margin_m + slack)


def test_clearance_grid_equals_the_points_it_expands(eq9: Coefficients) -> None:
    """Every obstacle at every s, obstacle-major, with the T of its obstacle: the same points,
    durations and clearances as clearance_points on the expanded rows."""
    sizes = np.array([[0.21, 0.09], [0.27, 0.118], [0.3, 0.12]])
    s = np.array([0.0, 0.3, 0.97, 1.0])
    grid = clearance_grid(eq9, sizes, s)
    rows = np.array([[L, W, t] for L, W in sizes for t in s])
    points = clearance_points(eq9, rows)
    assert np.array_equal(grid.points, points.points)
    assert np.array_equal(grid.duration_s, points.duration_s)
    assert np.array_equal(clearance_at(_matrix(eq9), grid, eq9), clearance_at(_matrix(eq9), points, eq9))
    assert np.all(np.diff(grid.duration_s.reshape(3, 4), axis=1) == 0.0)
    assert len(set(grid.duration_s.tolist())) == 3
