"""Path constraints: on a real path, the enclosures of theta', theta'', theta''' over each piece hold
dense samples; the torque is a u + b x with the true (a, b) inside the enclosures; every (x, u) that
keeps a piece's rows keeps the true accelerations and torques within the limits anywhere in the
piece; and the speed cap keeps the speeds.

References: the sinusoids' derivatives (:mod:`pipeline.motion.trajectory`) sampled densely, and the
torque from :meth:`pipeline.model.dynamics.PlanarDynamics.torque` at the executed state.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline import generate, load_coefficients, load_planar_arm
from pipeline.exceptions import InvalidParameterError
from pipeline.model.limits import ArmLimits
from pipeline.motion.interval_arithmetic import magnitude
from pipeline.motion.path_constraints import enclose_path, piece_constraints
from pipeline.motion.trajectory import joint_accelerations, joint_angles, joint_jerks, joint_velocities
from pipeline.online.execution import dynamics_of

#: Relative tolerance of a limit checked against values computed in floating point.
_RTOL = 1e-9


@functools.cache
def _path():
    trajectory = generate(load_coefficients("paper"), 0.27, 0.09, out_of_range="ignore").trajectory
    return trajectory, dynamics_of(load_planar_arm())


@functools.cache
def _limits() -> ArmLimits:
    return ArmLimits.from_arm(load_planar_arm(), acceleration_rad_s2=(10.0, 7.0))


def _edges(pieces: int, jitter: float, seed: int) -> np.ndarray:
    """Increasing edges over [0, T], equal ones moved by up to ``jitter`` of a piece."""
    trajectory, _ = _path()
    edges = np.linspace(0.0, trajectory.duration_s, pieces + 1)
    moves = np.random.default_rng(seed).uniform(-jitter, jitter, pieces - 1) * (edges[1] - edges[0])
    edges[1:-1] += moves
    return edges


def _inside(values: np.ndarray, lo: np.ndarray, hi: np.ndarray, atol: float) -> bool:
    return bool(np.all(values >= lo - atol) and np.all(values <= hi + atol))


def _coefficients(params, dynamics, s: np.ndarray):
    """(q, theta', theta'', a, b) at path times s: tau = a u + b x, a and b from the torque itself."""
    q = joint_angles(params, s)
    d1, d2 = joint_velocities(params, s), joint_accelerations(params, s)
    a = dynamics.torque(q, np.zeros_like(d1), d1)  # x = 0, u = 1
    b = dynamics.torque(q, d1, d2)  # x = 1, u = 0
    return q, d1, d2, a, b


@settings(max_examples=15, deadline=None)
@given(st.integers(2, 300), st.floats(0.0, 0.45), st.integers(0, 2**32 - 1))
def test_derivative_enclosures_hold_dense_samples(pieces, jitter, seed) -> None:
    trajectory, dynamics = _path()
    params = trajectory.parameters
    edges = _edges(pieces, jitter, seed)
    enclosures = enclose_path(params, edges, dynamics)
    assert np.array_equal(enclosures.edges_s, edges)
    local = np.linspace(0.0, 1.0, 41)
    s = (edges[:-1, None] + local[None, :] * np.diff(edges)[:, None]).ravel()
    piece = np.repeat(np.arange(pieces), local.size)
    for derivative, (lo, hi) in zip(
        (joint_velocities, joint_accelerations, joint_jerks), (enclosures.d1, enclosures.d2, enclosures.d3), strict=True
    ):
        assert lo.shape == (pieces, 2) and hi.shape == (pieces, 2)
        values = derivative(params, s)
        assert _inside(values, lo[piece], hi[piece], 1e-12)
    # accel_u, accel_x are theta', theta'' (ddq = theta'' x + theta' u).
    for got, want in ((enclosures.accel_u, enclosures.d1), (enclosures.accel_x, enclosures.d2)):
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])


@pytest.mark.parametrize("pieces", [50, 400])
def test_derivative_enclosures_are_tight(pieces) -> None:
    """Not only sound: over a piece of length ds an enclosure exceeds the sampled range by at most
    the next derivative's bound times ds (and a rounding slack)."""
    trajectory, dynamics = _path()
    params = np.asarray(trajectory.parameters).reshape(2, 4)
    edges = np.linspace(0.0, trajectory.duration_s, pieces + 1)
    ds = edges[1] - edges[0]
    enclosures = enclose_path(trajectory.parameters, edges, dynamics)
    amplitude, w = np.abs(params[:, 0]), np.abs(params[:, 1])
    for order, (lo, hi) in enumerate((enclosures.d1, enclosures.d2, enclosures.d3), start=1):
        assert np.all(hi - lo <= amplitude * w ** (order + 1) * ds * (1 + 1e-9) + 1e-9)


@settings(max_examples=20, deadline=None)
@given(st.integers(2, 200), st.floats(0.0, 0.45), st.integers(0, 2**32 - 1))
def test_torque_is_linear_in_x_and_u_with_coefficients_inside_their_enclosures(pieces, jitter, seed) -> None:
    trajectory, dynamics = _path()
    params = trajectory.parameters
    edges = _edges(pieces, jitter, seed)
    enclosures = enclose_path(params, edges, dynamics)
    rng = np.random.default_rng(seed)
    piece = rng.integers(0, pieces, 400)
    s = edges[piece] + rng.uniform(0.0, 1.0, piece.size) * np.diff(edges)[piece]
    s[:pieces] = edges[piece[:pieces]]  # some samples exactly on a piece's start
    q, d1, d2, a, b = _coefficients(params, dynamics, s)
    x = rng.uniform(0.0, 4.0, piece.size)[:, None]
    u = rng.uniform(-10.0, 10.0, piece.size)[:, None]
    torque = dynamics.torque(q, d1 * np.sqrt(x), d2 * x + d1 * u)
    scale_ = np.abs(a * u).max() + np.abs(b * x).max()
    assert np.allclose(torque, a * u + b * x, rtol=0.0, atol=1e-12 * scale_)
    for (lo, hi), true in ((enclosures.torque_u, a), (enclosures.torque_x, b)):
        assert lo.shape == (pieces, 2) and np.all(lo <= hi)
        assert _inside(true, lo[piece], hi[piece], 1e-12)


def _u_interval(cu: np.ndarray, cx: np.ndarray, rhs: np.ndarray, x: float) -> tuple[float, float]:
    """The u for which every row ``cu u + cx x <= rhs`` holds at this x (possibly empty)."""
    room = rhs - cx * x
    up = np.where(cu > 0.0, room / np.where(cu > 0.0, cu, 1.0), np.inf)
    down = np.where(cu < 0.0, room / np.where(cu < 0.0, cu, 1.0), -np.inf)
    if np.any((cu == 0.0) & (room < 0.0)):
        return math.inf, -math.inf
    return float(down.max(initial=-np.inf)), float(up.min(initial=np.inf))


@settings(max_examples=12, deadline=None)
@given(st.integers(2, 200), st.floats(0.0, 0.45), st.floats(0.3, 1.0), st.integers(0, 2**32 - 1))
def test_rows_keep_the_true_accelerations_and_torques_within_the_limits(pieces, jitter, share, seed) -> None:
    trajectory, dynamics = _path()
    params = trajectory.parameters
    limits = _limits()
    edges = _edges(pieces, jitter, seed)
    rows = piece_constraints(enclose_path(params, edges, dynamics), limits, share)
    assert rows.cu.shape == rows.cx.shape == rows.rhs.shape == (pieces, 16)  # 4 rows x 2 joints x (accel, effort)
    assert np.array_equal(rows.edges_s, edges)
    limit_a = share * np.asarray(limits.acceleration_rad_s2)
    limit_t = share * np.asarray(limits.effort_n_m)
    assert np.allclose(np.sort(np.unique(rows.rhs)), np.sort(np.unique(np.concatenate([limit_a, limit_t]))))
    rng = np.random.default_rng(seed)
    worst = 0.0
    for k in rng.choice(pieces, size=min(pieces, 25), replace=False):
        cu, cx, rhs = rows.cu[k], rows.cx[k], rows.rhs[k]
        # x up to where the rows leave no u (doubling, then sampled below), u at both ends of its
        # interval (the binding rows) and inside it.
        top = 1.0
        while _u_interval(cu, cx, rhs, top)[0] <= _u_interval(cu, cx, rhs, top)[1] and top < 1e6:
            top *= 2.0
        xs = np.concatenate([[0.0], rng.uniform(0.0, top, 30)])
        samples = []
        for x in xs:
            u_lo, u_hi = _u_interval(cu, cx, rhs, x)
            if u_lo <= u_hi:
                samples += [(x, u_lo), (x, u_hi), (x, rng.uniform(u_lo, u_hi))]
        assert samples, "x = u = 0 keeps every row (every limit is positive)"
        x, u = (np.array(v)[:, None, None] for v in zip(*samples, strict=True))  # (m, 1, 1)
        assert np.all(cu * u[..., 0] + cx * x[..., 0] <= rhs * (1 + 1e-12))
        s = np.concatenate([edges[k : k + 2], rng.uniform(edges[k], edges[k + 1], 60)])
        q, d1, d2, _, _ = _coefficients(params, dynamics, s)  # (p, 2)
        acceleration = d2 * x + d1 * u  # (m, p, 2)
        torque = dynamics.torque(np.broadcast_to(q, acceleration.shape), d1 * np.sqrt(x), acceleration)
        assert np.all(np.abs(acceleration) <= limit_a * (1 + _RTOL))
        assert np.all(np.abs(torque) <= limit_t * (1 + _RTOL))
        worst = max(worst, float(np.max(np.abs(torque) / limit_t)), float(np.max(np.abs(acceleration) / limit_a)))
    # The rows bind: at the binding u some limit is nearly reached (they are not vacuous).
    assert worst >= 0.5


@settings(max_examples=15, deadline=None)
@given(st.integers(2, 300), st.floats(0.0, 0.45), st.floats(0.1, 1.0), st.integers(0, 2**32 - 1))
def test_speed_cap_keeps_the_speeds(pieces, jitter, share, seed) -> None:
    trajectory, dynamics = _path()
    params = trajectory.parameters
    limits = _limits()
    edges = _edges(pieces, jitter, seed)
    rows = piece_constraints(enclose_path(params, edges, dynamics), limits, share)
    assert rows.speed_cap.shape == (pieces,) and np.all(rows.speed_cap > 0.0)
    local = np.linspace(0.0, 1.0, 41)
    s = (edges[:-1, None] + local[None, :] * np.diff(edges)[:, None]).ravel()
    cap = np.repeat(rows.speed_cap, local.size)[:, None]
    speed = np.abs(joint_velocities(params, s)) * np.sqrt(cap)
    velocity = share * np.asarray(limits.velocity_rad_s)
    assert np.all(speed <= velocity * (1 + _RTOL))
    # And the cap is the largest: some joint reaches its speed limit within the piece up to the
    # enclosure's looseness (theta'' ds of theta').
    params_ = np.asarray(params).reshape(2, 4)
    slack = np.abs(params_[:, 0]) * params_[:, 1] ** 2 * np.max(np.diff(edges)) * np.sqrt(rows.speed_cap)[:, None]
    reached = (speed.reshape(pieces, local.size, 2).max(1) + slack) / velocity
    assert np.all(reached.max(1) >= 1.0 - 1e-9)


def test_only_speed_limits_give_no_rows_but_a_finite_cap() -> None:
    trajectory, dynamics = _path()
    enclosures = enclose_path(trajectory.parameters, np.linspace(0.0, trajectory.duration_s, 11), dynamics)
    rows = piece_constraints(enclosures, ArmLimits(velocity_rad_s=(3.0, 2.0)))
    assert rows.cu.shape == (10, 0) and np.all(np.isfinite(rows.speed_cap))
    one_joint = piece_constraints(enclosures, ArmLimits(effort_n_m=(math.inf, 5.0)))
    assert one_joint.cu.shape == (10, 4) and np.all(one_joint.rhs == 5.0) and np.all(np.isinf(one_joint.speed_cap))


def test_no_limit_at_all_is_refused() -> None:
    trajectory, dynamics = _path()
    enclosures = enclose_path(trajectory.parameters, np.linspace(0.0, trajectory.duration_s, 11), dynamics)
    with pytest.raises(InvalidParameterError):
        piece_constraints(enclosures, ArmLimits())


@settings(max_examples=10, deadline=None)
@given(st.integers(2, 300), st.floats(0.0, 0.45), st.floats(0.3, 1.0), st.floats(0.3, 1.0), st.integers(0, 2**32 - 1))
def test_compiled_rows_equal_the_interval_arithmetic(pieces, jitter, share, speed_share, seed) -> None:
    from pipeline.motion.path_constraints import compiled_piece_constraints

    trajectory, dynamics = _path()
    edges = _edges(pieces, jitter, seed)
    enclosures = enclose_path(trajectory.parameters, edges, dynamics)
    want = piece_constraints(enclosures, _limits(), share, speed_share)
    got, peaks = compiled_piece_constraints(trajectory.parameters, edges, dynamics, _limits(), share, speed_share)
    for name in ("edges_s", "cu", "cx", "rhs", "speed_cap"):
        a, b = getattr(got, name), getattr(want, name)
        assert a.shape == b.shape and np.allclose(a, b, rtol=1e-13, atol=1e-15), name
    for k, d in enumerate((enclosures.d1, enclosures.d2, enclosures.d3)):
        assert np.allclose(peaks[k], magnitude(d), rtol=1e-13, atol=1e-15)
