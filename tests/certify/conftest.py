"""Fixtures of the certificate tests: the sampling of boxes, cells and points over a range
model's k axes, and the dense sampling of end poses, shared by the tests over (L, W, x) and
(L, W, x, d). Each fixture is the function below it; randomness comes only from the
``numpy.random.Generator`` passed in."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pipeline.certify.range_model import RangeModel
from pipeline.geometry.clearance import analytic_link_clearance
from pipeline.model.kinematics import inverse_kinematics_batch
from pipeline.motion.path import constraint_points


@pytest.fixture(scope="session")
def random_leaves():
    """The function drawing the leaves of a random subpaving (:func:`_random_leaves`)."""
    return _random_leaves


def _random_leaves(k: int, cuts: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``cuts`` times, a random leaf cut at the midpoint of a random axis; the leaves' levels and
    indices (n, k), shuffled."""
    leaves = [(np.zeros(k, dtype=np.int64), np.zeros(k, dtype=np.int64))]
    for _ in range(cuts):
        level, index = leaves.pop(int(rng.integers(len(leaves))))
        a = int(rng.integers(k))
        for half in (0, 1):
            child_level, child_index = level.copy(), index.copy()
            child_level[a] += 1
            child_index[a] = 2 * index[a] + half
            leaves.append((child_level, child_index))
    order = rng.permutation(len(leaves))
    return np.array([leaves[i][0] for i in order]), np.array([leaves[i][1] for i in order])


@pytest.fixture(scope="session")
def random_boxes():
    """The function drawing random boxes of (the model's axes, s) (:func:`_random_boxes`)."""
    return _random_boxes


def _random_boxes(model: RangeModel, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """n random boxes of (the model's k axes, s) inside the fitted box times s in [0, 1]: centres
    and half widths, (n, k + 1) each ([m] on the model's axes, a fraction of T on s). Half widths
    uniform in [0, 1/32) of each side, then centres uniform where the box fits."""
    lo = np.append(model.range_lo, 0.0)
    size = np.append(model.range_size, 1.0)
    radius = rng.uniform(0.0, 1.0 / 32, (n, model.k + 1)) * size
    center = lo + radius + rng.uniform(0.0, 1.0, (n, model.k + 1)) * (size - 2 * radius)
    return center, radius


@pytest.fixture(scope="session")
def random_cells():
    """The function drawing random cells of the model's dyadic grids (:func:`_random_cells`)."""
    return _random_cells


def _random_cells(
    model: RangeModel, n: int, rng: np.random.Generator, depths: tuple[int, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """n cells of the dyadic grids of the model's fitted box over its k axes: centres and half
    widths [m], (n, k) each. Each cell's depth is drawn from ``depths`` (side / 2**depth on every
    axis), then its index on each axis uniformly among the 2**depth."""
    depth = rng.choice(depths, n)
    half = model.range_size / 2.0 ** (depth[:, None] + 1)
    index = np.floor(rng.uniform(0.0, 1.0, (n, model.k)) * 2.0 ** depth[:, None])
    return model.range_lo + (2 * index + 1) * half, half


@pytest.fixture(scope="session")
def points_in():
    """The function drawing corners, centre and random points of a cell (:func:`_points_in`)."""
    return _points_in


def _points_in(center: np.ndarray, radius: np.ndarray, rng: np.random.Generator, extra: int) -> np.ndarray:
    """Points of the cell ``center`` +- ``radius`` (k,) [m], (2**min(k, 3) + 1 + extra, k): the
    corners with every sign pattern on the first three axes and, on any further axis, the product
    of those three signs (k = 3: the 8 corners; k = 4: the 8 of even parity), the centre, and
    ``extra`` points uniform in the cell."""
    k = center.shape[-1]
    free = min(k, 3)
    corners = [[*s, *[int(np.prod(s))] * (k - free)] for s in itertools.product((-1, 1), repeat=free)]
    signs = np.vstack([np.array(corners, dtype=float), np.zeros((1, k)), rng.uniform(-1.0, 1.0, (extra, k))])
    return center + signs * radius


@pytest.fixture(scope="session")
def end_pose_clearance():
    """The function sampling the best end poses near P1 and P5 (:func:`_end_pose_clearance`)."""
    return _end_pose_clearance


def _end_pose_clearance(coefficients, arm, obstacle, scene, tolerance_m: float) -> np.ndarray:
    """Largest analytic clearance [m] over poses (the coefficients' elbow) whose tip lies within
    ``tolerance_m`` of P1 (entry 0) and of P5 (entry 1) of ``obstacle`` placed in ``scene``: a
    dense sampling of each disc (6 radii x 40 angles), the independent check of the end poses'
    upper bounds."""
    points = constraint_points(obstacle, scene)
    radii = np.linspace(0.0, tolerance_m, 6)
    angles = np.linspace(0.0, 2 * np.pi, 40, endpoint=False)
    disc = (radii[:, None, None] * np.stack([np.cos(angles), np.sin(angles)], -1)[None]).reshape(-1, 2)
    out = np.empty(2)
    for column, p in enumerate((points[0], points[-1])):
        q = inverse_kinematics_batch(p + disc, arm.link_lengths_m, coefficients.elbow)
        out[column] = analytic_link_clearance(q, arm, obstacle).min(axis=-1).max()
    return out


@pytest.fixture(scope="session")
def check_clearance_jacobian():
    """The function checking the certifiable regression's clearance Jacobian against central
    differences (:func:`_check_clearance_jacobian`)."""
    return _check_clearance_jacobian


def _check_clearance_jacobian(coefficients, points: np.ndarray, rng: np.random.Generator) -> None:
    """``clearance_jacobian`` at ``points`` (n, k + 1: the variables, then s) against central
    differences of ``clearance_at`` in 12 random coefficients (step 1e-7)."""
    from pipeline.certify.certifiable_regression import clearance_at, clearance_jacobian, clearance_points
    from pipeline.motion.trajectory import PARAMETER_NAMES

    data = clearance_points(coefficients, points)
    b = np.stack([coefficients.parameters[name] for name in PARAMETER_NAMES], -1).ravel()
    jacobian = clearance_jacobian(b, data, coefficients)
    assert jacobian.shape == (points.shape[0], 8 * coefficients.variables.basis_size)
    step = 1e-7
    for k in rng.choice(b.size, 12, replace=False):
        e = np.zeros(b.size)
        e[k] = step
        numeric = (clearance_at(b + e, data, coefficients) - clearance_at(b - e, data, coefficients)) / (2 * step)
        np.testing.assert_allclose(jacobian[:, k], numeric, rtol=1e-4, atol=1e-6)


@pytest.fixture(scope="session")
def check_clearance_against_generator():
    """The function checking the certifiable regression's clearance against the generator's
    answer (:func:`_check_clearance_against_generator`)."""
    return _check_clearance_against_generator


def _check_clearance_against_generator(coefficients, points: np.ndarray, arm) -> None:
    """``clearance_at`` at ``points`` (n, k + 1: the variables, then s) equals the analytic
    clearance of ``generate(coefficients, L, W, x=, d=)`` at s T against the answer's own (moved)
    obstacle, to 1e-9 m, and Coal's within its error."""
    from pipeline.certify.certifiable_regression import clearance_at, clearance_points
    from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance
    from pipeline.motion.trajectory import PARAMETER_NAMES
    from pipeline.online.generator import generate

    b = np.stack([coefficients.parameters[name] for name in PARAMETER_NAMES], -1).ravel()
    values = clearance_at(b, clearance_points(coefficients, points), coefficients)
    extra = coefficients.variables.extra
    for point, value in zip(points, values, strict=True):
        moved = dict(zip(extra, map(float, point[2:-1]), strict=True))
        answer = generate(coefficients, float(point[0]), float(point[1]), region_map=None, **moved)
        assert answer.obstacle.centre_x_m == moved.get("x", coefficients.scene.centre_x_m)
        assert answer.obstacle.top_y_m == moved.get("d", coefficients.scene.top_y_m)
        q = answer.q(point[-1] * answer.duration_s)
        np.testing.assert_allclose(value, analytic_link_clearance(q, arm, answer.obstacle).min(), rtol=0, atol=1e-9)
        coal = float(CoalClearance(arm, answer.obstacle).link_clearance(q).min())
        np.testing.assert_allclose(value, coal, rtol=0, atol=COAL_DISTANCE_ERROR_M)


@pytest.fixture(scope="session")
def check_strips_gain():
    """The function checking what strips along W add to a map (:func:`_check_strips_gain`)."""
    return _check_strips_gain


def _check_strips_gain(with_strips, without) -> np.ndarray:
    """Cut cells give area to "infeasible" (and none is taken from "margin") that the uncut map
    left below the margin, the fractions still add up, and some leaves are strips (cut along W
    more often than along L); returns which leaves of ``with_strips`` are strips."""
    fractions = [m.summary()["area_fraction"] for m in (with_strips, without)]
    assert fractions[0]["infeasible"] > fractions[1]["infeasible"]
    assert fractions[0]["margin"] >= fractions[1]["margin"]
    assert fractions[0]["collision_free"] < fractions[1]["collision_free"]
    assert sum(fractions[0].values()) == pytest.approx(1.0, abs=1e-12)
    levels = with_strips.subpaving.levels
    strips = levels[:, 1] > levels[:, 0]
    assert np.count_nonzero(strips) > 0
    return strips
