"""The endpoint bound's second-order Taylor form (pipeline.certify.endpoints, second_order=True):
at dense points of random cells over (L, W, x) and (L, W, x, d) the tip's distance to the moved P1
and P5 (Pinocchio, and the closed form at many more points) stays within it; it is never looser
than the mean-value form and tighter on most cells; the jets' Hessians it reads enclose
finite differences (T's, and the error's)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.endpoints import _end_error_jets, endpoint_error_bounds
from pipeline.certify.range_model import RangeModel
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import constraint_points, desired_path
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.coefficients import Coefficients


@pytest.fixture(scope="module", params=["x", "xd"])
def lifted(request) -> Coefficients:
    """Eq. 9 lifted to (L, W, x) and to (L, W, x, d), with x and d terms of a size that makes
    the error vary across cells."""
    eq9 = load_coefficients("paper")
    if request.param == "x":
        return request.getfixturevalue("over_x")(eq9, scale=0.05)
    return request.getfixturevalue("over_xd")(eq9, scale=0.05, d_scale=0.5)


def _values(coefficients: Coefficients, point: np.ndarray) -> dict[str, float]:
    return dict(zip(coefficients.variables.names, map(float, point), strict=True))


def _end_errors(coefficients: Coefficients, point: np.ndarray, arm: PlanarArm | None = None) -> np.ndarray:
    """|tip(0) - P1| and |tip(T) - P5| [m] at one point of the variables, the obstacle and P1, P5
    moved by x and d; the tip by Pinocchio if ``arm`` is given, else by Eq. 2."""
    values = _values(coefficients, point)
    extra = {name: value for name, value in values.items() if name not in ("L", "W")}
    scene = coefficients.variables.scene_for(coefficients.scene, extra)
    obstacle = Obstacle.in_scene(values["L"], values["W"], scene)
    duration = desired_path(obstacle, scene).duration_s
    parameters = coefficients.family.expand(coefficients.predict_free(values["L"], values["W"], **extra), None)
    trajectory = JointTrajectory.trusted(tuple(float(p) for p in parameters), duration)
    points = constraint_points(obstacle, scene)
    errors = []
    for t, target in ((0.0, points[0]), (duration, points[-1])):
        q = trajectory.q(t)
        if arm is not None:
            tip = arm.end_effector_position(q)[:2]
        else:
            l1, l2 = coefficients.link_lengths_m
            tip = np.array([l1 * np.cos(q[0]) + l2 * np.cos(q[0] + q[1]), l1 * np.sin(q[0]) + l2 * np.sin(q[0] + q[1])])
        errors.append(float(np.linalg.norm(tip - target)))
    return np.array(errors)


def test_the_bound_holds_at_dense_points_of_random_cells(
    lifted: Coefficients, arm: PlanarArm, random_cells, points_in
) -> None:
    model = RangeModel.from_coefficients(lifted)
    center, radius = random_cells(model, 16, np.random.default_rng(3), depths=(0, 2, 3, 4, 5, 6))
    bounds = endpoint_error_bounds(model, center, radius, second_order=True)
    assert np.all(np.isfinite(bounds))
    rng = np.random.default_rng(4)
    worst_gap = []
    for k in range(center.shape[0]):
        points = points_in(center[k], radius[k], rng, 24)
        errors = np.array([_end_errors(lifted, p) for p in points])
        assert np.all(errors <= bounds[k] + 1e-12), (k, errors.max(0), bounds[k])
        for p in points[:2]:  # Pinocchio agrees with the closed form
            np.testing.assert_allclose(_end_errors(lifted, p, arm), _end_errors(lifted, p), rtol=0, atol=1e-12)
        if np.all(radius[k] <= model.range_size / 32):  # cells of 1/16 and smaller
            worst_gap.append(np.max(bounds[k] - errors.max(0)))
    # The check can see a wrong bound: on cells of 1/16 and smaller the bound lies within a few
    # millimetres of the sampled errors, within 1 mm at the median.
    assert len(worst_gap) >= 5 and max(worst_gap) < 4e-3 and np.median(worst_gap) < 1e-3, worst_gap


def test_never_looser_than_the_mean_value_form_and_tighter_on_most_cells(lifted: Coefficients, random_cells) -> None:
    model = RangeModel.from_coefficients(lifted)
    for depth in (4, 6):
        center, radius = random_cells(model, 200, np.random.default_rng(depth), depths=(depth,))
        first = endpoint_error_bounds(model, center, radius)
        second = endpoint_error_bounds(model, center, radius, second_order=True)
        centre = endpoint_error_bounds(model, center, np.zeros_like(radius))
        assert np.all(second <= first) and np.all(centre <= second)
        gaps = (second - centre) / (first - centre)  # the part of each bound the cell's extent adds
        # Tighter on most cells (by how much depends on the curvature against the slope: on these
        # lifted coefficients the slope dominates; on a build's, python scripts/endpoint_gap.py).
        assert np.mean(gaps < 1.0) > 0.9, (depth, np.mean(gaps < 1.0))


def test_on_tiny_cells_the_bound_is_the_error_at_the_centre(lifted: Coefficients) -> None:
    model = RangeModel.from_coefficients(lifted)
    rng = np.random.default_rng(5)
    lo, size = model.range_lo, model.range_size
    center = lo + size * rng.uniform(0.1, 0.9, (6, model.k))
    bounds = endpoint_error_bounds(model, center, np.tile(size * 1e-6, (6, 1)), second_order=True)
    for c, bound in zip(center, bounds, strict=True):
        np.testing.assert_allclose(bound, _end_errors(lifted, c), rtol=0, atol=1e-7)


def test_the_hessians_enclose_finite_differences(lifted: Coefficients, random_cells) -> None:
    """The Hessian enclosures of T's jet and of the error components' jets over a cell contain the
    central-difference Hessians at random points of the cell (each error component at s = 0 and 1)."""
    model = RangeModel.from_coefficients(lifted)
    center, radius = random_cells(model, 6, np.random.default_rng(6), depths=(2, 3))
    k = model.k
    hess_t = model.duration.jet(center, radius, k=k, order=2).hess
    rng = np.random.default_rng(7)
    step = model.range_size * 1e-4
    for n in range(center.shape[0]):
        boxes = [comps[1] for comps, _ in _end_error_jets(model, center[n : n + 1], radius[n : n + 1], True)]
        for point in center[n] + radius[n] * rng.uniform(-0.9, 0.9, (3, k)):

            def errors(v: np.ndarray) -> np.ndarray:
                zero = np.zeros((1, k))
                out = []
                for comps, _ in _end_error_jets(model, v[None], zero):
                    out += [float(comps[0][0].value.mid[0]), float(comps[0][1].value.mid[0])]
                return np.array(out + [float(model.duration.jet(v[None], zero, k=k).value.mid[0])])

            hessian = np.empty((k, k, 5))
            for i in range(k):
                for j in range(k):
                    ei, ej = np.eye(k)[i] * step[i], np.eye(k)[j] * step[j]
                    hessian[i, j] = (
                        errors(point + ei + ej)
                        - errors(point + ei - ej)
                        - errors(point - ei + ej)
                        + errors(point - ei - ej)
                    ) / (4 * step[i] * step[j])
            jets = [boxes[0][0], boxes[0][1], boxes[1][0], boxes[1][1]]
            for m, jet in enumerate(jets):
                slack = 1e-3 * np.maximum(1.0, np.abs(hessian[..., m]))
                assert np.all(jet.hess.lo[0, :k, :k] <= hessian[..., m] + slack)
                assert np.all(hessian[..., m] - slack <= jet.hess.hi[0, :k, :k])
            assert np.all(np.abs(hessian[:, :, 4]) <= hess_t.hi[n, :k, :k] + 1e-3)


def test_the_certificate_setting_reaches_the_leaves(lifted: Coefficients, monkeypatch: pytest.MonkeyPatch) -> None:
    """``RangeCertificateConfig.second_order`` (on by default over three and four axes)
    is the form the certificate's leaf bounds use, and its map needs no more leaves."""
    from pipeline.certify import range_certificate
    from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range

    assert RangeCertificateConfig.for_axes(lifted.variables.k).second_order
    assert not RangeCertificateConfig.for_axes(2).second_order
    seen = []
    bounds = range_certificate.endpoint_bounds_and_shares

    def spy(model, c, r, second_order=False):
        seen.append(second_order)
        return bounds(model, c, r, second_order)

    monkeypatch.setattr(range_certificate, "endpoint_bounds_and_shares", spy)
    coarse = RangeCertificateConfig.for_axes(lifted.variables.k, min_cell=1 / 8, boundary_cell=1 / 4, max_depth_s=8)
    second = certify_range(lifted, coarse)
    assert seen and all(seen)
    seen.clear()
    first = certify_range(lifted, replace(coarse, second_order=False))
    assert seen and not any(seen)
    assert second.size <= first.size


def test_the_command_line_chooses_the_form(capsys: pytest.CaptureFixture[str]) -> None:
    """``python -m pipeline.certify_range --bound-form``: either form by name, a bad one refused
    in one line; default_config passes it on (None: the default of the number of axes)."""
    from pipeline.certify.map_for_coefficients import default_config
    from pipeline.commands import certify_range

    args = certify_range.parser().parse_args(["paper", "--bound-form", "second-order"])
    assert certify_range.BOUND_FORMS[args.bound_form] is True
    eq9 = load_coefficients("paper")
    assert default_config(eq9, second_order=True).second_order
    assert not default_config(eq9).second_order
    assert certify_range.main(["paper", "--bound-form", "taylor"]) == 2
    err = capsys.readouterr().err
    assert "--bound-form" in err and "Traceback" not in err
