"""The exact-endpoints family (pipeline.motion.families.exact_endpoints) when P1 and P5 are no
mirror images (the obstacle off the y axis): joint 2's phase phi2 = arccos(r) - w2 T / 2 pins
theta2 at both ends, the tip reaches P1 and P5, and with theta2_s == theta2_e every number is
the symmetric formula's."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.families import EXACT_ENDPOINTS, EndpointContext, endpoint_context
from pipeline.motion.families.exact_endpoints import MIN_DENOMINATOR
from pipeline.motion.path import QuarticPath, desired_path
from pipeline.motion.trajectory import joint_angles

#: (L, W, centre x) [m].
CASES = [(0.30, 0.12, 0.05), (0.25, 0.10, -0.03), (0.20, 0.08, 0.02), (0.27, 0.09, -0.05)]

#: expand((0.9, 0.3, 1.2, 0.8)) in the paper's scene by the symmetric formula, as float.hex.
GOLDEN = {
    (0.30, 0.12): (
        "-0x1.1eb2606af07c9p+0 0x1.ccccccccccccdp-1 0x1.3333333333333p-2 0x1.21bf070355925p+0 "
        "0x1.3333333333333p+0 0x1.999999999999ap-1 0x1.25858768319a0p-4 0x1.04434cc26e687p-1"
    ),
    (0.25, 0.10): (
        "-0x1.d147208fee0e6p+0 0x1.ccccccccccccdp-1 0x1.3333333333333p-2 0x1.51c88129f900ap+0 "
        "0x1.3333333333333p+0 0x1.999999999999ap-1 0x1.e5cf598229fb8p-3 0x1.a82f65c72b0eap-2"
    ),
    (0.20, 0.08): (
        "-0x1.ded6b041d590dp+2 0x1.ccccccccccccdp-1 0x1.3333333333333p-2 0x1.7e4ae91d3df8cp+1 "
        "0x1.3333333333333p+0 0x1.999999999999ap-1 0x1.94c916d64bbacp-2 0x1.4415c62feef12p-2"
    ),
    (0.27, 0.09): (
        "-0x1.da263e134dd34p+0 0x1.ccccccccccccdp-1 0x1.3333333333333p-2 0x1.55e08e1ee280ap+0 "
        "0x1.3333333333333p+0 0x1.999999999999ap-1 0x1.decfc5aba0ac0p-3 0x1.855bcd15fa86dp-2"
    ),
}


def path_for(length: float, width: float, centre: float) -> QuarticPath:
    scene = Scene(centre_x_m=centre)
    return desired_path(Obstacle.in_scene(length, width, scene), scene)


def random_free(rng: np.random.Generator, count: int) -> np.ndarray:
    lower, upper = EXACT_ENDPOINTS.search_bounds()
    return lower + rng.random((count, lower.size)) * (upper - lower)


def r_of(free: np.ndarray, context: EndpointContext) -> np.ndarray:
    """r = (theta2_e - theta2_s) / (2 A2 sin(w2 T / 2)) of the module's derivation."""
    change = context.theta_end_rad[1] - context.theta_start_rad[1]
    with np.errstate(divide="ignore", over="ignore"):  # A2 sin(w2 T / 2) = 0 or subnormal: r = +-inf
        return change / (2.0 * free[..., 2] * np.sin(free[..., 3] * context.duration_s / 2.0))


@pytest.mark.parametrize("size", list(GOLDEN))
def test_centre_0_gives_the_symmetric_formula_bit_for_bit(arm: PlanarArm, size: tuple[float, float]) -> None:
    path = path_for(*size, 0.0)
    context = endpoint_context(path, arm.link_lengths_m, 1)
    assert context.theta_start_rad[1] == context.theta_end_rad[1]
    full = EXACT_ENDPOINTS.expand(np.array([0.9, 0.3, 1.2, 0.8]), context)
    # GOLDEN holds to 1e-13 relative: NumPy's dot products in T may differ in the last bit between
    # builds, and A1 = (th1_e - th1_s) / (sin(w1 T + phi1) - sin(phi1)) amplifies that (16 ulp seen);
    # the symmetric formula's phi2 and the free parameters hold to the bit.
    np.testing.assert_allclose(full, [float.fromhex(v) for v in GOLDEN[size].split()], rtol=1e-13, atol=0.0)
    assert full[6] == (math.pi - 0.8 * context.duration_s) / 2.0
    assert full[[1, 2, 4, 5]].tolist() == [0.9, 0.3, 1.2, 0.8]


@pytest.mark.parametrize("elbow", [1, -1])
@pytest.mark.parametrize("case", CASES)
def test_off_centre_the_tip_reaches_p1_and_p5(arm: PlanarArm, case: tuple[float, float, float], elbow: int) -> None:
    path = path_for(*case)
    context = endpoint_context(path, arm.link_lengths_m, elbow)
    assert abs(context.theta_end_rad[1] - context.theta_start_rad[1]) > 1e-3  # no longer mirror images
    rng = np.random.default_rng(abs(hash((case, elbow))) % 2**32)
    free = random_free(rng, 400)
    exact = EXACT_ENDPOINTS.endpoints_exact(free, context)
    assert exact.mean() > 0.7
    full = EXACT_ENDPOINTS.expand(free[exact], context)
    q = joint_angles(full, np.array([0.0, path.duration_s]))
    tips = arm.end_effector_planar(q)
    assert_allclose(tips[:, 0], np.broadcast_to(path.points_m[0], tips[:, 0].shape), rtol=0, atol=1e-9)
    assert_allclose(tips[:, 1], np.broadcast_to(path.points_m[-1], tips[:, 1].shape), rtol=0, atol=1e-9)
    assert np.all(elbow * q[:, :, 1] > 0)
    assert_allclose(full[:, [1, 2, 4, 5]], free[exact], rtol=0, atol=0)


@settings(max_examples=200, deadline=None)
@given(
    st.floats(-0.6, 0.6),  # theta2_e - theta2_s
    st.floats(2.0, 5.0),  # T
    st.floats(-3.0, 3.0),  # A2
    st.floats(0.2, 2.5),  # w2
    st.floats(0.2, 2.5),  # w1
    st.floats(-1.5, 1.5),  # phi1
)
def test_joint_2_reaches_both_ends_wherever_r_is_not_clamped(
    change: float, duration_s: float, a2: float, w2: float, w1: float, phi1: float
) -> None:
    context = EndpointContext((1.1, 0.4), (2.0, 0.4 + change), duration_s)
    change = context.theta_end_rad[1] - 0.4  # as stored (a tiny change may round away)
    free = np.array([w1, phi1, a2, w2])
    full = EXACT_ENDPOINTS.expand(free, context)
    q = joint_angles(full, np.array([0.0, duration_s]))
    assert q[0, 1] == pytest.approx(0.4, abs=1e-12)  # the start is exact either way (gamma2 follows phi2)
    r = float(r_of(free, context)) if change != 0.0 else 0.0  # theta2_s == theta2_e: the symmetric form
    joint1_exact = abs(math.sin(w1 * duration_s + phi1) - math.sin(phi1)) >= MIN_DENOMINATOR
    assert bool(EXACT_ENDPOINTS.endpoints_exact(free, context)) == (joint1_exact and abs(r) <= 1.0)
    if abs(r) <= 1.0:
        assert q[1, 1] == pytest.approx(0.4 + change, abs=1e-9)
        assert math.cos(full[6] + w2 * duration_s / 2.0) == pytest.approx(r, abs=1e-12)
    else:  # joint 2 gets as near theta2_e as its amplitude allows: |2 A2 sin(w2 T / 2)| short of it
        reach = abs(2.0 * a2 * math.sin(w2 * duration_s / 2.0))
        assert abs(q[1, 1] - (0.4 + change)) == pytest.approx(abs(change) - reach, abs=1e-9)


def test_a_small_amplitude_is_reported_as_not_exact(arm: PlanarArm) -> None:
    context = endpoint_context(path_for(0.25, 0.10, 0.05), arm.link_lengths_m, 1)
    change = context.theta_end_rad[1] - context.theta_start_rad[1]
    tiny = abs(change) / 10.0
    free = np.array([[0.9, 0.3, tiny, 1.0], [0.9, 0.3, 1.2, 1.0]])
    assert EXACT_ENDPOINTS.endpoints_exact(free, context).tolist() == [False, True]
    assert np.all(np.isfinite(EXACT_ENDPOINTS.expand(free, context)))
    # A2 sin(w2 T / 2) = 0, or so small that r overflows: joint 2 cannot move between the ends;
    # finite, not exact, and no floating-point warning.
    for a2 in (0.0, 5e-324, -1e-308):
        stuck = np.array([0.9, 0.3, a2, 1.0])
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert np.all(np.isfinite(EXACT_ENDPOINTS.expand(stuck, context)))
            assert not EXACT_ENDPOINTS.endpoints_exact(stuck, context)


def test_w2_sign_is_the_same_motion_off_centre(arm: PlanarArm) -> None:
    """r is odd in w2 and arccos(-r) = pi - arccos(r): (A2, w2) and (A2, -w2) move joint 2 alike,
    so canonical_free's w2 -> |w2| still keeps the motion."""
    path = path_for(0.25, 0.10, -0.04)
    context = endpoint_context(path, arm.link_lengths_m, 1)
    free = np.array([0.99, 0.46, 1.45, 0.86])
    mirrored = free * np.array([1.0, 1.0, 1.0, -1.0])
    t = np.linspace(0.0, context.duration_s, 101)
    before = joint_angles(EXACT_ENDPOINTS.expand(mirrored, context), t)
    assert_allclose(before, joint_angles(EXACT_ENDPOINTS.expand(free, context), t), rtol=0, atol=1e-12)
    canonical = EXACT_ENDPOINTS.canonical_free(mirrored)
    assert_allclose(joint_angles(EXACT_ENDPOINTS.expand(canonical, context), t), before, rtol=0, atol=1e-12)


def test_the_other_arccos_branch_is_the_motion_of_minus_a2() -> None:
    """phi2 + w2 T / 2 = -arccos(r) also solves the end condition; it is the motion of (-A2, w2)
    on the branch the family takes, so the PSO's A2 in [-3, 3] reaches both."""
    context = EndpointContext((1.1, 0.4), (2.0, 0.55), 3.4)
    w1, phi1, a2, w2 = 0.9, 0.3, 1.3, 0.8
    r = 0.15 / (2.0 * a2 * math.sin(w2 * 3.4 / 2.0))
    phi2 = -math.acos(r) - w2 * 3.4 / 2.0
    t = np.linspace(0.0, 3.4, 51)
    other = a2 * np.sin(w2 * t + phi2) + 0.4 - a2 * math.sin(phi2)
    full = EXACT_ENDPOINTS.expand(np.array([w1, phi1, -a2, w2]), context)
    assert_allclose(joint_angles(full, t)[:, 1], other, rtol=0, atol=1e-12)


def _central_difference(function, x: np.ndarray, step: float) -> np.ndarray:
    columns = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = step
        columns.append((function(x + e) - function(x - e)) / (2 * step))
    return np.stack(columns, -1)


@pytest.mark.parametrize("case", CASES[:2])
def test_expand_jacobians_match_finite_differences_off_centre(arm: PlanarArm, case: tuple[float, float, float]) -> None:
    context = endpoint_context(path_for(*case), arm.link_lengths_m, 1)
    free_batch = random_free(np.random.default_rng(5), 60)
    # Well away from both clamps, where expand is smooth and central differences resolve it.
    w1, phi1 = free_batch[:, 0], free_batch[:, 1]
    keep = (np.abs(r_of(free_batch, context)) < 0.9) & (
        np.abs(np.sin(w1 * context.duration_s + phi1) - np.sin(phi1)) > 0.05
    )
    free_batch = free_batch[keep]
    assert len(free_batch) > 20
    j_free, j_context = EXACT_ENDPOINTS.expand_jacobians(free_batch, context)
    base = context.as_array()

    def with_context(values: np.ndarray) -> EndpointContext:
        return EndpointContext((values[0], values[1]), (values[2], values[3]), values[4])

    for row, free in enumerate(free_batch):
        numeric_free = _central_difference(lambda x: EXACT_ENDPOINTS.expand(x, context), free, 1e-6)
        numeric_context = _central_difference(lambda c, f=free: EXACT_ENDPOINTS.expand(f, with_context(c)), base, 1e-6)
        assert_allclose(j_free[row], numeric_free, rtol=1e-6, atol=1e-5)
        assert_allclose(j_context[row], numeric_context, rtol=1e-6, atol=1e-5)
