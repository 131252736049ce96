"""The obstacle's centre x as an online input (pipeline.online.generator, batch, repair): with
coefficients over (L, W, x), the answer's obstacle and path are those of x = 0 moved by exactly x,
T does not change, the exact-endpoints family pins the tip (Pinocchio) to the moved P1 and P5,
a missing or unexpected x is refused by name, the batch equals the scalar answers, and
certify-or-repair certifies the moved obstacle."""

from __future__ import annotations

import math
import pickle
import warnings
from dataclasses import replace

import numpy as np
import pytest

from pipeline.exceptions import (
    InexactEndpointsWarning,
    InvalidParameterError,
    NoCertifiedTrajectoryError,
    OutOfFittedRangeError,
    OutOfFittedRangeWarning,
    UnreachableObstacleError,
)
from pipeline.geometry.sinusoid_certificate import certify_trajectory
from pipeline.model.kinematics import inverse_kinematics
from pipeline.motion.families.exact_endpoints import ExactEndpointsFamily
from pipeline.motion.path import desired_path
from pipeline.offline.coefficients import Coefficients
from pipeline.offline.variables import VOCABULARY, Variables
from pipeline.online.batch import generate_batch
from pipeline.online.generator import generate, generate_parameters
from pipeline.online.repair import RepairConfig, generate_certified

LWX = Variables(("L", "W", "x"))
X_RANGE = (-0.03, 0.03)


@pytest.fixture(scope="module")
def paper_x(paper, over_x) -> Coefficients:
    return over_x(paper)


@pytest.fixture(scope="module")
def exact_x(exact, over_x) -> Coefficients:
    return over_x(exact, seed=2, scale=0.05)


CASES = [(0.25, 0.10, 0.02), (0.21, 0.085, -0.03), (0.29, 0.115, 0.011), (0.27, 0.09, -0.004)]


@pytest.mark.parametrize("family", ["paper", "exact"])
@pytest.mark.parametrize(("L", "W", "x"), CASES)
def test_obstacle_and_path_are_moved_by_x_and_t_is_unchanged(request, rounding, family, L, W, x) -> None:
    coefficients = request.getfixturevalue(f"{family}_x")
    centred = generate(coefficients, L, W, x=0.0)
    moved = generate(coefficients, L, W, x=x)
    assert moved.centre_x_m == moved.scene.centre_x_m == moved.obstacle.centre_x_m == x
    assert replace(moved.scene, centre_x_m=0.0) == coefficients.scene
    shift = np.array([x, 0.0])
    assert np.array_equal(moved.obstacle.footprint_corners_m(), centred.obstacle.footprint_corners_m() + shift)
    assert np.array_equal(moved.path.points_m, centred.path.points_m + shift)
    # T: the x = 0 path's, and the moved path's own arc length agrees (a rigid shift).
    assert abs(moved.duration_s - centred.duration_s) <= 1e-15 * centred.duration_s
    own = desired_path(moved.obstacle, moved.scene)
    assert abs(own.duration_s - centred.duration_s) <= 1e-14 * centred.duration_s
    assert abs(moved.path.length_m - centred.path.length_m) <= 1e-14 * centred.path.length_m
    xs = np.linspace(centred.path.end_x_m, centred.path.start_x_m, 41)
    np.testing.assert_allclose(moved.path.y(xs + x), centred.path.y(xs), rtol=0, atol=1e-12)
    # The regression is evaluated at (L, W, x); no map bounds over (L, W, x).
    if family == "paper":
        reference, bound = rounding.regression(coefficients, L, W, x=x)
        assert np.all(np.abs(np.subtract(moved.trajectory.parameters, reference)) <= bound)
    assert moved.certificate_source is None and moved.certified_clearance_m is None
    assert moved.range_status is None and not moved.extrapolated


def test_x_terms_of_zero_give_the_l_w_answer(paper, over_x) -> None:
    """With the x terms zero, x moves only the obstacle and the path: the parameters are the
    (L, W) coefficients' to rounding and T is theirs to the bit."""
    flat = over_x(paper, scale=0.0)
    for L, W, x in CASES:
        reference = generate(paper, L, W)
        answer = generate(flat, L, W, x=x)
        np.testing.assert_allclose(answer.trajectory.parameters, reference.trajectory.parameters, rtol=0, atol=1e-14)
        assert answer.duration_s == reference.duration_s


@pytest.mark.parametrize(("L", "W", "x"), CASES)
def test_exact_endpoints_pin_the_tip_to_the_moved_p1_and_p5(exact_x, arm, L, W, x) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no InexactEndpointsWarning, no out-of-range warning
        answer = generate(exact_x, L, W, x=x)
    points = answer.path.points_m
    start = inverse_kinematics(points[0], exact_x.link_lengths_m, exact_x.elbow)
    end = inverse_kinematics(points[-1], exact_x.link_lengths_m, exact_x.elbow)
    assert abs(start[1] - end[1]) > 1e-3  # theta2_s != theta2_e: the asymmetric phi2 branch
    q = answer.trajectory.q(np.array([0.0, answer.duration_s]))
    tips = arm.to_plane(arm.end_effector_positions(q))  # Pinocchio's kinematics of the URDF
    errors = np.linalg.norm(tips - points[[0, -1]], axis=1)
    assert errors.max() <= 1e-9
    half = L / 2 + exact_x.scene.start_dx_m
    assert points[0, 0] == half + x and points[-1, 0] == -half + x


def test_a_missing_or_unexpected_variable_is_refused_by_name(paper, paper_x) -> None:
    cases = [
        (lambda: generate(paper_x, 0.25, 0.1), r"^x = None is invalid: .*x= is required"),
        (lambda: generate(paper, 0.25, 0.1, x=0.01), r"^x = 0\.01 is invalid: .*vary L, W only"),
        (lambda: generate(paper_x, 0.25, 0.1, x=0.01, d=0.55), r"^d = 0\.55 is invalid: .*vary L, W, x only"),
        (lambda: generate(paper_x, 0.25, 0.1, x="0.01"), r"^x = '0\.01' is invalid: .*not str"),
        (lambda: generate(paper_x, 0.25, 0.1, x=math.nan), r"^x = nan is invalid"),
        (lambda: generate_batch(paper_x, [0.25], [0.1]), r"^x = None is invalid"),
        (lambda: generate_batch(paper, [0.25], [0.1], x=[0.01]), r"^x = \[0\.01\] is invalid"),
        (lambda: generate_batch(paper_x, [0.25, 0.2], [0.1, 0.1], x=[0.0, 0.0, 0.0]), r"^x = \(3,\) is invalid"),
        (lambda: generate_parameters(paper_x, [0.25], [0.1]), r"^x = None is invalid"),
        (lambda: generate_certified(paper_x, 0.25, 0.1), r"^x = None is invalid"),
        (lambda: generate_certified(paper, 0.25, 0.1, x=0.01), r"^x = 0\.01 is invalid"),
    ]
    for call, message in cases:
        with pytest.raises(InvalidParameterError, match=message) as info:
            call()
        assert "\n" not in str(info.value)


def test_x_outside_its_fitted_range_follows_the_policy(paper_x) -> None:
    with pytest.warns(OutOfFittedRangeWarning, match="x"):
        answer = generate(paper_x, 0.25, 0.1, x=0.04)
    assert answer.extrapolated
    with pytest.raises(OutOfFittedRangeError, match="x"):
        generate(paper_x, 0.25, 0.1, x=-0.04, out_of_range="error")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert generate(paper_x, 0.25, 0.1, x=0.04, out_of_range="ignore").extrapolated
    with pytest.raises(UnreachableObstacleError, match="P1"):
        generate(paper_x, 0.3, 0.1, x=0.2, out_of_range="ignore")


@pytest.mark.parametrize("family", ["paper", "exact"])
def test_batch_equals_scalar_answers(request, family) -> None:
    coefficients = request.getfixturevalue(f"{family}_x")
    rng = np.random.default_rng(7)
    n = 40
    L = np.concatenate([rng.uniform(0.19, 0.31, n), [0.25, 0.001, 0.3]])
    W = np.concatenate([rng.uniform(0.075, 0.125, n), [0.1, 0.1, 0.1]])
    x = np.concatenate([rng.uniform(-0.035, 0.035, n), [np.nan, 0.0, 0.2]])
    batch = generate_batch(coefficients, L, W, x=x)
    assert np.array_equal(batch.variables["x"], x, equal_nan=True)
    for i in range(L.size):
        try:
            answer = generate(coefficients, float(L[i]), float(W[i]), x=float(x[i]), out_of_range="ignore")
        except (InvalidParameterError, UnreachableObstacleError) as exc:
            assert batch.error[i] is not None and type(exc).__name__ in batch.error[i]
            assert np.isnan(batch.durations_s[i])
            continue
        assert batch.error[i] is None
        assert batch.durations_s[i] == answer.duration_s
        np.testing.assert_allclose(batch.parameters[i], answer.trajectory.parameters, rtol=0, atol=1e-15)
        assert batch.extrapolated[i] == answer.extrapolated
    assert sum(e is not None for e in batch.error) == 3
    assert batch.certified_clearance_m is None
    parameters = generate_parameters(coefficients, L[:n], W[:n], x=x[:n])
    np.testing.assert_allclose(parameters, batch.parameters[:n], rtol=0, atol=1e-15)
    # One x for every obstacle.
    same = generate_batch(coefficients, L[:n], W[:n], x=0.01)
    single = generate(coefficients, float(L[0]), float(W[0]), x=0.01, out_of_range="ignore")
    np.testing.assert_allclose(same.parameters[0], single.trajectory.parameters, rtol=0, atol=1e-15)


def test_certify_or_repair_certifies_the_moved_obstacle(exact_x, arm) -> None:
    """The per-query certificate is the moved obstacle's: its bound equals a certificate of the
    answer's trajectory against the obstacle at x, not at x = 0."""
    config = RepairConfig(repair=False, certificate_tolerance_m=1e-4)
    L, W, x = 0.22, 0.085, 0.015
    answer = generate(exact_x, L, W, x=x)
    moved = certify_trajectory(answer.trajectory, arm, answer.obstacle, tolerance_m=1e-4).certified_clearance_m
    centred = generate(exact_x, L, W, x=0.0).obstacle
    unmoved = certify_trajectory(answer.trajectory, arm, centred, tolerance_m=1e-4).certified_clearance_m
    assert abs(moved - unmoved) > 1e-3
    try:
        result = generate_certified(exact_x, L, W, arm, x=x, config=config)
    except NoCertifiedTrajectoryError as exc:
        assert exc.certified_clearance_m == pytest.approx(moved, abs=1e-12)
        return
    assert result.generated.obstacle.centre_x_m == x
    assert result.certificate.certified_clearance_m == pytest.approx(moved, abs=1e-12)
    points = result.generated.path.points_m
    tips = arm.to_plane(arm.end_effector_positions(result.trajectory.q(np.array([0.0, result.trajectory.duration_s]))))
    assert np.linalg.norm(tips - points[[0, -1]], axis=1).max() <= 1e-9


def test_a_repair_with_x_works_on_the_moved_obstacle(exact_x, arm) -> None:
    """At (0.22, 0.085, 0.015) the regression's answer misses the margin; the repair, run on the
    moved obstacle's objective from the regression at (L, W, x), clears it and keeps the tip
    pinned to the moved P1 and P5."""
    answer = generate_certified(exact_x, 0.22, 0.085, arm, x=0.015)
    margin = exact_x.scene.margin_m
    assert answer.repaired and answer.regression_certificate.certified_clearance_m < margin
    assert answer.generated.obstacle.centre_x_m == 0.015
    tight = certify_trajectory(answer.trajectory, arm, answer.generated.obstacle, tolerance_m=1e-5)
    assert tight.certified_clearance_m >= margin
    points = answer.generated.path.points_m
    tips = arm.to_plane(arm.end_effector_positions(answer.trajectory.q(np.array([0.0, answer.trajectory.duration_s]))))
    assert np.linalg.norm(tips - points[[0, -1]], axis=1).max() <= 1e-9
    assert max(answer.endpoint_errors_m) <= 1e-9


def test_d_replaces_the_scenes_far_edge(paper, rounding) -> None:
    """Coefficients over (L, W, d) with the d terms zero answer as (L, W) coefficients whose
    scene has top_y_m = d, and the batch agrees."""
    lwd = Variables(("L", "W", "d"))
    lifted = {}
    for name, b in paper.parameters.items():
        row = np.zeros(lwd.basis_size)
        row[[0, 1, 2, 4, 5, 7]] = b
        lifted[name] = tuple(row.tolist())
    over_d = replace(
        paper, parameters=lifted, fitted_range_m={**paper.fitted_range_m, "d": (0.54, 0.58)}, variables=lwd
    )
    for d in (0.545, 0.56, 0.575):
        reference = generate(replace(paper, scene=replace(paper.scene, top_y_m=d)), 0.25, 0.1)
        answer = generate(over_d, 0.25, 0.1, d=d)
        assert answer.scene.top_y_m == d and answer.obstacle.top_y_m == d
        assert answer.duration_s == reference.duration_s
        assert np.array_equal(answer.path.points_m, reference.path.points_m)
        np.testing.assert_allclose(answer.trajectory.parameters, reference.trajectory.parameters, rtol=0, atol=1e-14)
        batch = generate_batch(over_d, [0.25], [0.1], d=d)  # the NumPy route
        numpy_duration, bound = rounding.duration(answer.scene, 0.25, 0.1)
        assert batch.durations_s[0] == numpy_duration
        assert abs(answer.duration_s - numpy_duration) <= bound
        np.testing.assert_allclose(batch.parameters[0], answer.trajectory.parameters, rtol=0, atol=1e-15)
    with pytest.raises(InvalidParameterError, match=r"^x = 0\.0 is invalid"):
        generate(over_d, 0.25, 0.1, d=0.56, x=0.0)


def test_certify_batch_certifies_the_moved_obstacles(paper_x, arm) -> None:
    """The batch certificate places each obstacle at its own x: its bounds equal the scalar
    certificate of the moved obstacle, and differ from the unmoved one's."""
    from pipeline.geometry.sinusoid_certificate import certify_trajectory
    from pipeline.online.batch import generate_batch
    from pipeline.online.batch_certify import certify_batch

    L, W, x = np.array([0.25, 0.27]), np.array([0.09, 0.10]), np.array([0.03, -0.03])
    batch = generate_batch(paper_x, L, W, x=x)
    result = certify_batch(paper_x, batch, arm)
    for i in range(2):
        answer = generate(paper_x, float(L[i]), float(W[i]), x=float(x[i]))
        moved = certify_trajectory(answer.trajectory, arm, answer.obstacle).certified_clearance_m
        unmoved = certify_trajectory(
            answer.trajectory, arm, generate(paper_x, float(L[i]), float(W[i]), x=0.0).obstacle
        ).certified_clearance_m
        assert result.certified_clearance_m[i] == pytest.approx(moved, abs=1e-12)
        assert abs(moved - unmoved) > 1e-4


@pytest.mark.parametrize("names", [("L", "W", "x"), ("L", "W", "d"), ("L", "W", "x", "d")])
@pytest.mark.parametrize("start_y", [None, 0.5])
def test_the_moved_route_answers_as_the_definitions_say(paper, rounding, names, start_y) -> None:
    """Over any extra variables, with y1 = d or a fixed y1: the answer's scene is the
    coefficients' scene with the values replaced (dataclasses.replace), its parameters the
    regression at the values, T the centred path's, ``extrapolated`` the fitted box's verdict,
    and NumPy numbers give the float's answer."""
    variables = Variables(names)
    position = {term: i for i, term in enumerate(variables.basis)}
    keep = [position[term] for term in ("1", "L", "W", "L^2", "L*W", "W^2")]
    rng = np.random.default_rng(3)
    lifted = {}
    for name, b in paper.parameters.items():
        row = rng.normal(0.0, 0.02, variables.basis_size)
        row[keep] = b
        lifted[name] = tuple(row.tolist())
    ranges = {"x": (-0.03, 0.03), "d": (0.54, 0.58)}
    scene = replace(paper.scene, start_y_m=start_y)
    coefficients = replace(
        paper,
        parameters=lifted,
        fitted_range_m={**paper.fitted_range_m, **{name: ranges[name] for name in variables.extra}},
        variables=variables,
        scene=scene,
        region_map=None,
    )
    fields = {name: VOCABULARY[name][1] for name in ("x", "d")}  # the Scene field each sets
    for L, W, x, d in [(0.25, 0.1, 0.02, 0.57), (0.21, 0.085, -0.03, 0.54), (0.29, 0.121, 0.031, 0.575)]:
        given = {name: value for name, value in (("x", x), ("d", d)) if name in variables.extra}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OutOfFittedRangeWarning)
            answer = generate(coefficients, L, W, **given)
            numpy = generate(coefficients, np.float64(L), W, **{name: np.float64(v) for name, v in given.items()})
        assert repr(numpy) == repr(answer) and numpy.variables == answer.variables
        moved = replace(scene, **{fields[name]: value for name, value in given.items()})
        assert answer.scene == moved and repr(answer.scene) == repr(moved)
        assert answer.variables == tuple(given.items())
        reference, bound = rounding.regression(coefficients, L, W, **given)
        assert np.all(np.abs(np.subtract(answer.trajectory.parameters, reference)) <= bound)
        centred = generate(replace(paper, scene=replace(moved, centre_x_m=0.0)), L, W, out_of_range="ignore")
        assert answer.duration_s == centred.duration_s
        assert answer.extrapolated == (not coefficients.in_range(L, W, **given))


def test_out_of_range_warnings_point_at_the_caller_on_both_routes(paper, paper_x) -> None:
    """An extrapolated query warns from the line that called generate, over (L, W) and (L, W, x)."""
    with pytest.warns(OutOfFittedRangeWarning) as flat:
        generate(paper, 0.35, 0.1)
    with pytest.warns(OutOfFittedRangeWarning) as moved:
        generate(paper_x, 0.25, 0.1, x=0.05)
    assert [w.filename for w in flat] == [__file__]
    assert [w.filename for w in moved] == [__file__]


def test_the_moved_scene_is_built_on_first_access(paper_x) -> None:
    """The answer over (L, W, x) keeps the coefficients' scene and x, and builds its scene when
    read: the coefficients' scene with x in place, also after pickling."""
    answer = generate(paper_x, 0.25, 0.1, x=0.02)
    assert "scene" not in answer.__dict__
    copy = pickle.loads(pickle.dumps(answer))
    assert answer.scene == replace(paper_x.scene, centre_x_m=0.02) == copy.scene
    assert answer.scene is answer.scene and answer.obstacle.centre_x_m == 0.02
    with pytest.raises(AttributeError, match="no attribute 'sceen'"):
        answer.sceen  # noqa: B018


class _NeverExact(ExactEndpointsFamily):
    """The exact-endpoints family, reporting that it could not pin the tip (A1 clamped)."""

    def endpoints_exact(self, free, context):
        return np.zeros(np.shape(free)[:-1], dtype=bool)


def test_the_inexact_endpoints_warning_points_at_the_caller_on_both_routes(exact, exact_x) -> None:
    for coefficients, given_values in ((exact, {}), (exact_x, {"x": 0.01})):
        never = replace(coefficients, family=_NeverExact())
        with pytest.warns(InexactEndpointsWarning) as caught:
            generate(never, 0.25, 0.1, **given_values)
        assert [w.filename for w in caught] == [__file__]
