"""The closed-form planar dynamics against Pinocchio (CRBA and RNEA, an independent route), its
suprema against dense sampling, and the refusal of an arm that gravity would load."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pipeline.exceptions import RobotModelError
from pipeline.model.arm import DEFAULT_URDF, load_planar_arm
from pipeline.model.dynamics import identify_dynamics
from pipeline.model.limits import ArmLimits

states = st.lists(st.floats(-20.0, 20.0, allow_nan=False), min_size=6, max_size=6)


@pytest.fixture(scope="module")
def dynamics(arm):
    return identify_dynamics(arm)


@settings(max_examples=200, deadline=None)
@given(states)
def test_torques_equal_rnea(arm, dynamics, state) -> None:
    q, dq, ddq = np.array(state[:2]), np.array(state[2:4]), np.array(state[4:])
    reference = pin.rnea(arm.model, arm.model.createData(), q, dq, ddq)
    assert_allclose(dynamics.torque(q, dq, ddq), reference, rtol=1e-12, atol=1e-12)


def test_mass_matrix_equals_crba_and_vectorises(arm, dynamics) -> None:
    rng = np.random.default_rng(0)
    q2 = rng.uniform(-4, 4, 50)
    batch = dynamics.mass_matrix(q2)
    for k, angle in enumerate(q2):
        mass = pin.crba(arm.model, arm.model.createData(), np.array([0.3, angle]))
        assert_allclose(batch[k], np.triu(mass) + np.triu(mass, 1).T, rtol=1e-12, atol=1e-15)
    q, dq, ddq = rng.uniform(-3, 3, (3, 50, 2))
    single = np.array([dynamics.torque(q[k], dq[k], ddq[k]) for k in range(50)])
    assert_allclose(dynamics.torque(q, dq, ddq), single, rtol=0, atol=0)


def test_suprema_bound_dense_sampling_and_are_reached(dynamics) -> None:
    q2 = np.linspace(-np.pi, np.pi, 100001)
    sampled = np.abs(dynamics.mass_matrix(q2)).max(0)
    assert np.all(sampled <= dynamics.mass_matrix_sup() + 1e-15)
    assert_allclose(sampled, dynamics.mass_matrix_sup(), rtol=1e-8)
    h = np.abs(dynamics.coriolis_coefficient(q2)).max()
    assert h <= dynamics.coriolis_sup() + 1e-15 and h >= dynamics.coriolis_sup() * (1 - 1e-8)


def test_an_arm_in_a_vertical_plane_is_refused(tmp_path) -> None:
    text = DEFAULT_URDF.read_text(encoding="utf-8").replace('<axis xyz="0 0 1"/>', '<axis xyz="0 1 0"/>')
    path = tmp_path / "vertical.urdf"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(RobotModelError, match="not parallel to gravity") as info:
        identify_dynamics(load_planar_arm(path))
    assert "\n" not in str(info.value)


def test_limits_come_from_the_urdf(arm) -> None:
    limits = ArmLimits.from_arm(arm, (2.0, 3.0))
    assert limits.position_rad == ((-3.14159, 3.14159), (-3.14159, 3.14159))
    assert limits.velocity_rad_s == (3.0, 3.0) and limits.effort_n_m == (10.0, 10.0)
    assert limits.acceleration_rad_s2 == (2.0, 3.0)
    assert ArmLimits.from_arm(arm).acceleration_rad_s2 == (np.inf, np.inf)


@pytest.mark.parametrize(
    ("field", "value"),
    [("velocity_rad_s", (0.0, 1.0)), ("effort_n_m", (1.0, float("nan"))), ("position_rad", ((1.0, 0.0), (0, 1)))],
)
def test_bad_limits_are_refused(field, value) -> None:
    from pipeline.exceptions import InvalidParameterError

    with pytest.raises(InvalidParameterError, match=field):
        ArmLimits(**{field: value})
