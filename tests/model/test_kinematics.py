"""Closed-form 2R kinematics (pipeline.model.kinematics): the vectorised inverse kinematics
against the scalar one and through Eq. 2, on both elbow branches, and its clipping outside the
reach annulus. (The scalar inverse kinematics' own tests are in tests/motion/test_family.py.)"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pipeline.model.kinematics import (
    forward_kinematics,
    inverse_kinematics,
    inverse_kinematics_batch,
    reach_annulus_m,
)

LINKS = [(0.30, 0.35), (0.35, 0.30)]


def reachable_points(rng: np.random.Generator, links: tuple[float, float], count: int) -> np.ndarray:
    """``count`` points (count, 2) [m] strictly inside the reach annulus, uniform in radius and angle."""
    inner, outer = reach_annulus_m(links)
    radius = rng.uniform(inner + 1e-6, outer - 1e-6, count)
    angle = rng.uniform(-np.pi, np.pi, count)
    return np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])


@pytest.mark.parametrize("links", LINKS)
@pytest.mark.parametrize("elbow", [1, -1])
def test_batch_inverse_kinematics_equals_the_scalar_one(links: tuple[float, float], elbow: int) -> None:
    points = reachable_points(np.random.default_rng(3), links, 2000)
    batch = inverse_kinematics_batch(points, links, elbow)
    scalar = np.array([inverse_kinematics(p, links, elbow) for p in points])
    assert batch.shape == (2000, 2)
    # cos(theta2) from x*x + y*y (batch) or hypot(x, y)**2 (scalar): equal to rounding only.
    assert_allclose(batch, scalar, rtol=0, atol=1e-12)
    assert np.all(elbow * batch[:, 1] >= 0.0)


@pytest.mark.parametrize("links", LINKS)
@pytest.mark.parametrize("elbow", [1, -1])
def test_batch_inverse_kinematics_round_trips_through_eq2(links: tuple[float, float], elbow: int) -> None:
    points = reachable_points(np.random.default_rng(4), links, 2000)
    assert_allclose(
        forward_kinematics(inverse_kinematics_batch(points, links, elbow), links), points, rtol=0, atol=1e-12
    )


def test_batch_inverse_kinematics_broadcasts_over_leading_axes() -> None:
    links = LINKS[0]
    points = reachable_points(np.random.default_rng(5), links, 24).reshape(4, 6, 2)
    batch = inverse_kinematics_batch(points, links, 1)
    assert batch.shape == (4, 6, 2)
    assert np.array_equal(batch.reshape(-1, 2), inverse_kinematics_batch(points.reshape(-1, 2), links, 1))


@pytest.mark.parametrize("links", LINKS)
@pytest.mark.parametrize("elbow", [1, -1])
def test_batch_inverse_kinematics_clips_outside_the_annulus(links: tuple[float, float], elbow: int) -> None:
    """Beyond l1 + l2 the stretched pose (theta2 = 0), inside |l1 - l2| the folded one (|theta2| = pi),
    both with the tip on the point's ray at the annulus' edge; no error."""
    inner, outer = reach_annulus_m(links)
    angle = np.linspace(-np.pi, np.pi, 13)
    ray = np.column_stack([np.cos(angle), np.sin(angle)])
    stretched = inverse_kinematics_batch((outer + 1e-3) * ray, links, elbow)
    assert_allclose(stretched[:, 1], 0.0, rtol=0, atol=0)
    assert_allclose(forward_kinematics(stretched, links), outer * ray, rtol=0, atol=1e-12)
    folded = inverse_kinematics_batch(0.5 * inner * ray, links, elbow)
    assert_allclose(folded[:, 1], elbow * np.pi, rtol=0, atol=0)
    assert_allclose(forward_kinematics(folded, links), inner * ray, rtol=0, atol=1e-12)
