"""The sweep's sampled checks, vectorised over a batch of cases: joint states of many trajectories
at once, and the largest |value| of each joint quantity found coarse first, then refined where
the coarse grid puts a peak.

A sampled check compares a certified bound with the largest value the sweep can find; it fails
(and catches a certificate that lies) when a sample exceeds the bound. Sampling every instant
densely spends almost all its evaluations where the value is far below its peak, where no sample
can exceed the bound if the peak's sample does not. :func:`refined_maxima` therefore samples a
coarse grid, then, around each of the :data:`REFINED_PEAKS` highest local maxima of the coarse
samples per quantity (a local maximum's neighbourhood [t_(i-1), t_(i+1)] holds the true local
peak), a fine uniform grid: the refined maximum is at least every coarse sample and as close to
the true peak as a uniform grid whose spacing is the fine one (finer than the former dense grids,
:data:`PAPER_GRID` and :data:`REST_TO_REST_GRID`). Given the bounds the maxima are checked
against, it refines only the quantities whose coarse maximum reaches within a room of their
bound (:data:`PAPER_ROOM`, :data:`REST_TO_REST_ROOM`, each many times the most a refinement lifts
a coarse maximum): the others are decided by the coarse grid, and report its maximum.

Units: times in s, angles in rad, speeds in rad/s, accelerations in rad/s^2.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from pipeline.motion.path import QuarticPath
from pipeline.motion.timing import RestToRestTiming, Timing
from pipeline.validation import check_positive_int

#: Paper timing: (coarse uniform instants over [0, T], fine instants per refined peak). The fine
#: spacing, 2 T / (128 * 64) = T / 4096, is finer than the former dense grid's T / 2000.
PAPER_GRID: tuple[int, int] = (129, 65)
#: Rest-to-rest timing: (coarse instants per ramp, coarse instants over the middle, fine instants
#: per refined peak). The peaks of |ddq| and |tau| lie in the ramps (a few hundredths of a second
#: of a T' of seconds): the fine spacing there, r / 192, is finer than the former grid's r / 40,
#: and in the middle (T' - 2 r) / 384 against (T' - 2 r) / 320.
REST_TO_REST_GRID: tuple[int, int, int] = (17, 33, 25)
#: Least segments of a path's arc-length sum (as the path's own panel table).
MIN_PATH_SEGMENTS = 64
#: Gauss-Legendre nodes and weights of each segment's arc length: 4 nodes integrate the arc
#: length of a quartic's segment of a few mm exactly to rounding (the path's own sum uses 10; the
#: times agree to about 1e-15 s, tested).
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(4)
#: Relative room below a bound: a coarse maximum below (1 - room) times its bound decides the
#: check (the refinement could not lift it past the bound), above it the quantity is refined. On
#: 100 cases of the default build and of the paper's Eq. 9, the refinement lifts a coarse maximum
#: by at most 0.035 % on the paper timing's grid (PAPER_GRID) and 0.45 % on the rest-to-rest
#: timing's (REST_TO_REST_GRID, joint 2's torque in the ramps): rooms of about 30 and 11 times
#: that (tests/verifier/test_sampling.py checks the lifts stay within a third of them).
PAPER_ROOM = 0.01
REST_TO_REST_ROOM = 0.05
#: Local maxima of the coarse samples refined per quantity and joint (the highest ones).
REFINED_PEAKS = 2

#: Evaluates |quantities| of the cases ``rows`` (w,) (indices into the batch) at their times
#: (w, m) [s]: (w, m, k) non-negative values.
Evaluator = Callable[[np.ndarray, np.ndarray], np.ndarray]


def sinusoid_states(parameters: np.ndarray, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """theta, theta', theta'' (Eq. 1) of n trajectories at their own times: parameters (n, 8)
    (A1, w1, phi1, gamma1, A2, w2, phi2, gamma2), times (n, m) [s]; each result (n, m, 2) [rad,
    rad/s, rad/s^2], the same floats as :func:`pipeline.motion.trajectory.joint_angles` (and its
    velocities and accelerations) row by row."""
    p = np.asarray(parameters, dtype=float).reshape(-1, 1, 2, 4)
    a, w, phi, gamma = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    phase = w * np.asarray(t_s, dtype=float)[..., None] + phi
    sine, cosine = np.sin(phase), np.cos(phase)
    return a * sine + gamma, (a * w) * cosine, -(a * w * w) * sine


def sinusoid_angles(parameters: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """theta (Eq. 1) of n trajectories at their own times: parameters (n, 8), times (n, m) [s];
    (n, m, 2) [rad], the first result of :func:`sinusoid_states` without the derivatives."""
    p = np.asarray(parameters, dtype=float).reshape(-1, 1, 2, 4)
    return p[..., 0] * np.sin(p[..., 1] * np.asarray(t_s, dtype=float)[..., None] + p[..., 2]) + p[..., 3]


def path_samples(paths: Sequence[QuarticPath], counts: Sequence[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`pipeline.motion.path.QuarticPath.uniform_samples` of n paths at once: ``counts[k]``
    points uniform in x from P1 to P5 of the k-th path and their times t = S(x) / v, the arc length
    summed segment by segment (4-point Gauss-Legendre per segment, at least
    :data:`MIN_PATH_SEGMENTS` segments per path, each sample gap split evenly).

    Returns:
        (times (n, M) [s], positions (n, M, 2) [m], valid (n, M)): M = max(counts); the k-th row
        holds ``counts[k]`` samples, then copies of P5's (``valid`` False).
    """
    counts_array = np.array([check_positive_int("counts", int(m), minimum=2) for m in counts])
    split = -(-MIN_PATH_SEGMENTS // (counts_array - 1))  # segments per sample gap
    size = int(((counts_array - 1) * split).max()) + 1
    start = np.array([p.start_x_m for p in paths])[:, None]
    end = np.array([p.end_x_m for p in paths])[:, None]
    segments = ((counts_array - 1) * split)[:, None]
    column = np.arange(size)[None, :]
    fine = start + (end - start) * (np.minimum(column, segments) / segments)  # x of the fine points, then P5's
    slope = np.array([np.polyder(p.coefficients) for p in paths])[:, None, None, :]  # (n, 1, 1, 4)
    mid, half = (fine[:, :-1] + fine[:, 1:]) / 2.0, (fine[:, 1:] - fine[:, :-1]) / 2.0
    nodes = mid[..., None] + half[..., None] * _GL_NODES
    dydx = ((slope[..., 0] * nodes + slope[..., 1]) * nodes + slope[..., 2]) * nodes + slope[..., 3]
    lengths = np.zeros_like(fine)
    np.cumsum(np.abs(half) * (np.sqrt(1.0 + dydx**2) @ _GL_WEIGHTS), axis=1, out=lengths[:, 1:])
    width = int(counts_array.max())
    index = np.minimum(np.arange(width)[None, :] * split[:, None], segments)
    x = np.take_along_axis(fine, index, axis=1)
    x[np.arange(x.shape[0]), counts_array - 1] = end[:, 0]
    coefficients = np.array([p.coefficients for p in paths])[:, None, :]
    y = (((coefficients[..., 0] * x + coefficients[..., 1]) * x + coefficients[..., 2]) * x + coefficients[..., 3]) * x
    y += coefficients[..., 4]
    speed = np.array([p.speed_m_s for p in paths])[:, None]
    times = np.take_along_axis(lengths, index, axis=1) / speed
    return times, np.stack([x, y], -1), np.arange(width)[None, :] < counts_array[:, None]


def timing_derivatives(timings: Sequence[Timing], tau_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """sigma, sigma', sigma'' of n timings at their own executed times tau (n, m) [s], each (n, m):
    for rest-to-rest timings in one vectorised expression of their closed form
    (:class:`pipeline.motion.timing.RestToRestTiming`), for any other timing row by row through
    its own methods."""
    tau = np.asarray(tau_s, dtype=float)
    if not all(type(t) is RestToRestTiming for t in timings):
        rows = [(t.sigma(row), t.dsigma(row), t.ddsigma(row)) for t, row in zip(timings, tau, strict=True)]
        return tuple(np.array([r[k] for r in rows]).reshape(tau.shape) for k in range(3))  # type: ignore[return-value]
    c = np.array([t.speed_scale for t in timings])[:, None]
    r = np.array([t.ramp_s for t in timings])[:, None]
    total = np.array([t.path_duration_s for t in timings])[:, None]
    end = total / c + r
    u_in, u_out = np.clip(tau / r, 0.0, 1.0), np.clip((end - tau) / r, 0.0, 1.0)
    first, last = tau < r, tau > end - r
    sigma = np.where(
        first,
        c * r * (u_in**3 - 0.5 * u_in**4),
        np.where(last, total - c * r * (u_out**3 - 0.5 * u_out**4), c * r / 2.0 + c * (tau - r)),
    )
    ramp_in, ramp_out = u_in * u_in * (3.0 - 2.0 * u_in), u_out * u_out * (3.0 - 2.0 * u_out)
    dsigma = c * np.where(first, ramp_in, np.where(last, ramp_out, 1.0))
    slope_in, slope_out = 6.0 * u_in * (1.0 - u_in), 6.0 * u_out * (1.0 - u_out)
    ddsigma = (c / r) * np.where(first, slope_in, np.where(last, -slope_out, 0.0))
    return np.clip(sigma, 0.0, total), dsigma, ddsigma


def timed_states(
    parameters: np.ndarray, timings: Sequence[Timing], tau_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q, dq, ddq (n, m, 2) of n paths under their timings at executed times tau (n, m) [s]:
    ``theta(sigma)``, ``theta'(sigma) sigma'``, ``theta''(sigma) sigma'^2 + theta'(sigma) sigma''``
    (as :meth:`pipeline.motion.timed_trajectory.TimedTrajectory.states`)."""
    sigma, d1, d2 = timing_derivatives(timings, tau_s)
    total = np.array([t.path_duration_s for t in timings])[:, None]
    q, speed, acceleration = sinusoid_states(parameters, np.clip(sigma, 0.0, total))
    d1, d2 = d1[..., None], d2[..., None]
    return q, speed * d1, acceleration * d1 * d1 + speed * d2


def uniform_grid(duration_s: np.ndarray, count: int) -> np.ndarray:
    """``count`` uniform instants over [0, T] per case: (n, count) [s], both ends exact."""
    check_positive_int("count", count, minimum=2)
    duration = np.asarray(duration_s, dtype=float)[:, None]
    grid = duration * np.linspace(0.0, 1.0, count)
    grid[:, -1] = duration[:, 0]
    return grid


def piecewise_grid(duration_s: np.ndarray, ramp_s: np.ndarray, ramp: int, middle: int) -> np.ndarray:
    """Per case, ``ramp`` uniform instants over each ramp [0, r] and [T' - r, T'] and ``middle``
    over [r, T' - r], the shared ends once: (n, 2 ramp + middle - 2) [s], sorted."""
    check_positive_int("ramp", ramp, minimum=2)
    check_positive_int("middle", middle, minimum=2)
    end, r = np.asarray(duration_s, dtype=float)[:, None], np.asarray(ramp_s, dtype=float)[:, None]
    u_ramp, u_middle = np.linspace(0.0, 1.0, ramp), np.linspace(0.0, 1.0, middle)[1:-1]
    grid = np.concatenate([r * u_ramp, r + (end - 2.0 * r) * u_middle, (end - r) + r * u_ramp], axis=1)
    grid[:, -1] = end[:, 0]
    return grid


def _top_local_maxima(values: np.ndarray, count: int) -> np.ndarray:
    """Indices (n, k, count) along axis 1 of the ``count`` highest local maxima (ends included;
    repeated when there are fewer) of values (n, m, k)."""
    padded = np.pad(values, ((0, 0), (1, 1), (0, 0)), constant_values=-np.inf)
    local = (values >= padded[:, :-2]) & (values >= padded[:, 2:])
    ranked = np.where(local, values, -np.inf)
    order = np.argsort(-ranked, axis=1, kind="stable")[:, :count]  # (n, count, k)
    best = order[:, :1]
    order = np.where(np.take_along_axis(ranked, order, axis=1) > -np.inf, order, best)
    return np.moveaxis(order, 1, 2)


def refined_maxima(
    evaluate: Evaluator,
    grid_s: np.ndarray,
    fine: int,
    bounds: np.ndarray | None = None,
    room: float = REST_TO_REST_ROOM,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The largest value of each quantity of n cases, coarse then refined (module docstring).

    Args:
        evaluate: |quantities| (w, m, k) of the cases ``rows`` (w,) at their times (w, m) [s].
        grid_s: The coarse grid (n, m), sorted per case [s].
        fine: Uniform instants over [t_(i-1), t_(i+1)] around each refined coarse maximum t_i.
        bounds: The bounds (n, k) the maxima are checked against, if the refinement is to be
            spent only where the coarse samples leave the check undecided: where the coarse
            maximum reaches ``(1 - room)`` times the bound (or is not finite). None: refine every
            quantity of every case.
        room: The relative room below a bound within which a quantity is refined.

    Returns:
        (maxima (n, k), their instants (n, k) [s], instants evaluated per case (n,)).
    """
    check_positive_int("fine", fine, minimum=3)
    n, m = grid_s.shape
    coarse = evaluate(np.arange(n), grid_s)  # (n, m, k)
    k = coarse.shape[2]
    best_coarse = coarse.argmax(axis=1)  # (n, k)
    maxima = np.take_along_axis(coarse, best_coarse[:, None, :], axis=1)[:, 0, :]
    where = np.take_along_axis(grid_s, best_coarse, axis=1)
    undecided = np.ones((n, k), dtype=bool)
    if bounds is not None:
        undecided = ~(maxima < (1.0 - room) * np.asarray(bounds, dtype=float))
    case, quantity = np.nonzero(undecided)
    evaluated = np.full(n, m)
    if case.size == 0:
        return maxima, where, evaluated
    peaks = _top_local_maxima(coarse, REFINED_PEAKS)[case, quantity]  # (w, p)
    lo = grid_s[case[:, None], np.maximum(peaks - 1, 0)]
    hi = grid_s[case[:, None], np.minimum(peaks + 1, m - 1)]
    windows = (lo[..., None] + (hi - lo)[..., None] * np.linspace(0.0, 1.0, fine)).reshape(case.size, -1)
    values = evaluate(case, windows)[np.arange(case.size), :, quantity]  # (w, p fine): each window's own quantity
    best = values.argmax(axis=1)
    refined = values[np.arange(case.size), best]
    higher = refined >= maxima[case, quantity]
    maxima[case[higher], quantity[higher]] = refined[higher]
    where[case[higher], quantity[higher]] = windows[np.arange(case.size), best][higher]
    np.add.at(evaluated, case, windows.shape[1])
    return maxima, where, evaluated
