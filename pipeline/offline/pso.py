"""Particle swarm optimisation, vectorised over particles.

Global-best PSO of Kennedy & Eberhart [8, 10] with the inertia weight of Shi & Eberhart [9]
decreasing linearly from ``inertia_start`` to ``inertia_end`` over the iterations, velocity
clamping to a fraction of the search box, positions clipped to the box, and independent
restarts: each restart's best point is kept (``restart_x``) so that a caller can polish
every one of them locally and keep the best polished result. All randomness comes from the
``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.validation import check_non_negative, check_positive, check_positive_int


@dataclass(frozen=True)
class PsoConfig:
    """PSO settings.

    Attributes:
        swarm_size: Particles per swarm.
        iterations: Iterations per restart.
        restarts: Independent swarms; the best result over all is kept.
        inertia_start: Inertia weight at the first iteration [9].
        inertia_end: Inertia weight at the last iteration [9].
        cognitive: c1, pull towards each particle's own best [8].
        social: c2, pull towards the swarm's best [8].
        max_velocity_fraction: Velocity clamp as a fraction of each dimension's range.
    """

    swarm_size: int = 40
    iterations: int = 200
    restarts: int = 4
    inertia_start: float = 0.9
    inertia_end: float = 0.4
    cognitive: float = 2.0
    social: float = 2.0
    max_velocity_fraction: float = 0.2

    def __post_init__(self) -> None:
        check_positive_int("swarm_size", self.swarm_size, minimum=2)
        check_positive_int("iterations", self.iterations)
        check_positive_int("restarts", self.restarts)
        check_non_negative("inertia_start", self.inertia_start)
        check_non_negative("inertia_end", self.inertia_end)
        check_non_negative("cognitive", self.cognitive)
        check_non_negative("social", self.social)
        check_positive("max_velocity_fraction", self.max_velocity_fraction)


@dataclass(frozen=True)
class PsoResult:
    """Outcome of :func:`minimize`.

    Attributes:
        x: Best point found.
        value: Objective at ``x``.
        evaluations: Number of objective evaluations (particles x iterations).
        history: Best value after each iteration, all restarts concatenated.
        restart_x: Best point of each restart, shape (restarts, k).
        restart_values: Objective at each of those points, shape (restarts,).
    """

    x: np.ndarray
    value: float
    evaluations: int
    history: np.ndarray
    restart_x: np.ndarray
    restart_values: np.ndarray


def minimize(
    objective: Callable[[np.ndarray], np.ndarray],
    lower: np.ndarray,
    upper: np.ndarray,
    rng: np.random.Generator,
    config: PsoConfig,
    initial: np.ndarray | None = None,
) -> PsoResult:
    """Minimise a batched objective over the box [lower, upper].

    Args:
        objective: Maps positions (P, k) to values (P,).
        lower, upper: Box bounds, shape (k,).
        rng: Source of all randomness.
        config: PSO settings.
        initial: Optional points (m, k) placed in the first swarm (e.g. a warm start).
    """
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    if lower.shape != upper.shape or lower.ndim != 1 or np.any(~(upper > lower)):
        raise InvalidParameterError("bounds", (lower, upper), "1-D arrays with upper > lower")
    span = upper - lower
    v_max = config.max_velocity_fraction * span
    evaluations = 0
    history = []
    restart_x, restart_f = [], []
    for restart in range(config.restarts):
        x = lower + rng.random((config.swarm_size, lower.size)) * span
        if restart == 0 and initial is not None:
            seeds = np.clip(np.atleast_2d(initial), lower, upper)[: config.swarm_size]
            x[: len(seeds)] = seeds
        v = (rng.random(x.shape) * 2 - 1) * v_max
        f = objective(x)
        evaluations += len(x)
        p_x, p_f = x.copy(), f.copy()
        g = int(np.argmin(p_f))
        for it in range(config.iterations):
            frac = it / max(config.iterations - 1, 1)
            inertia = config.inertia_start + (config.inertia_end - config.inertia_start) * frac
            r1 = rng.random(x.shape)
            r2 = rng.random(x.shape)
            v = inertia * v + config.cognitive * r1 * (p_x - x) + config.social * r2 * (p_x[g] - x)
            v = np.clip(v, -v_max, v_max)
            x = np.clip(x + v, lower, upper)
            f = objective(x)
            evaluations += len(x)
            better = f < p_f
            p_x[better] = x[better]
            p_f[better] = f[better]
            g = int(np.argmin(p_f))
            history.append(p_f[g])
        restart_x.append(p_x[g].copy())
        restart_f.append(float(p_f[g]))
    best = int(np.argmin(restart_f))
    return PsoResult(
        x=restart_x[best],
        value=restart_f[best],
        evaluations=evaluations,
        history=np.array(history),
        restart_x=np.array(restart_x),
        restart_values=np.array(restart_f),
    )
