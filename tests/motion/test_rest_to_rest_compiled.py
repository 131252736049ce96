"""shortest_rest_to_rest (plain floats and a compiled grid search) against the canonical NumPy
route rest_to_rest_scales, and the trajectory's cached closed-form peaks against their definitions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.exceptions import InvalidParameterError
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.rest_to_rest import _widened, rest_to_rest_scales, shortest_rest_to_rest
from pipeline.motion.trajectory import JointTrajectory, joint_accelerations, joint_angles, joint_velocities

DYNAMICS = PlanarDynamics(
    m0=((0.35, 0.08), (0.08, 0.05)), mc=((0.12, 0.06), (0.06, 0.0)), ms=((0.03, 0.015), (0.015, 0.0))
)


def _random(rng):
    p = rng.normal(size=8)
    p[1], p[5] = abs(p[1]) * 2, abs(p[5]) * 2
    limits = ArmLimits(
        velocity_rad_s=tuple(rng.uniform(0.2, 5.0, 2)),
        acceleration_rad_s2=tuple(rng.choice([math.inf, 1.0, 5.0], 2)),
        effort_n_m=tuple(rng.uniform(0.01, 3.0, 2)),
    )
    return JointTrajectory(tuple(p), float(rng.uniform(0.5, 5.0))), limits


def test_shortest_rest_to_rest_equals_the_canonical_route() -> None:
    rng = np.random.default_rng(3)
    refused = 0
    for _ in range(1500):
        trajectory, limits = _random(rng)
        V = _widened(trajectory.peak_velocity_rad_s())
        acc = _widened(trajectory.peak_acceleration_rad_s2())
        c, r = rest_to_rest_scales(np.array([trajectory.duration_s]), V[None], acc[None], DYNAMICS, limits)
        if not np.isfinite(c[0]):
            refused += 1
            with pytest.raises(InvalidParameterError):
                shortest_rest_to_rest(trajectory, DYNAMICS, limits)
            continue
        timing = shortest_rest_to_rest(trajectory, DYNAMICS, limits)
        # Same grid point; the constraint terms in plain floats may differ from NumPy's matmul in the last ulp.
        assert timing.speed_scale == pytest.approx(c[0], rel=1e-14, abs=0)
        assert timing.ramp_s == pytest.approx(r[0], rel=1e-13, abs=0)
    assert refused < 1500
    trajectory, _ = _random(rng)
    binding = ArmLimits(velocity_rad_s=(1.0, 1.0), effort_n_m=(1e-12, 1.0))  # binds at rest
    V, acc = _widened(trajectory.peak_velocity_rad_s()), _widened(trajectory.peak_acceleration_rad_s2())
    assert np.isnan(rest_to_rest_scales(np.array([trajectory.duration_s]), V[None], acc[None], DYNAMICS, binding)[0][0])
    with pytest.raises(InvalidParameterError):
        shortest_rest_to_rest(trajectory, DYNAMICS, binding)


def test_cached_peaks_are_the_closed_forms() -> None:
    rng = np.random.default_rng(5)
    for _ in range(200):
        trajectory, _ = _random(rng)
        t = np.linspace(0.0, trajectory.duration_s, 20001)
        p = trajectory.parameters
        peaks = trajectory.peaks
        assert trajectory.peaks is peaks  # computed once
        for sampled, exact in (
            (np.abs(joint_velocities(p, t)).max(0), peaks.velocity_rad_s),
            (np.abs(joint_accelerations(p, t)).max(0), peaks.acceleration_rad_s2),
        ):
            assert np.all(sampled <= np.array(exact) * (1 + 1e-12))
            assert np.allclose(sampled, exact, rtol=1e-6)
        q = joint_angles(p, t)
        for i in (0, 1):
            lo, hi = peaks.angle_ranges_rad[i]
            assert lo <= q[:, i].min() + 1e-12 and q[:, i].max() <= hi + 1e-12
            assert q[:, i].min() == pytest.approx(lo, abs=1e-6) and q[:, i].max() == pytest.approx(hi, abs=1e-6)
            assert peaks.third_rad_s3[i] == abs(p[4 * i]) * abs(p[4 * i + 1]) ** 3
