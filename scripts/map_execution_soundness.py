"""Soundness and tightness of the region map's execution bounds on many random obstacles.

For N random (L, W) of the fitted range, the bounds of the map's leaf holding each obstacle
(:mod:`pipeline.certify.execution_bounds`) are compared with a dense sampling of that obstacle's
trajectory: with the paper timing, the angles, |dq|, |ddq| and |tau|; with the leaf's rest-to-rest
timing, |dq|, |ddq| and |tau|. Torques come from the closed-form dynamics (equal to Pinocchio's
RNEA to 1e-12, tests/model/test_dynamics.py); at each obstacle's maximising sample RNEA itself
is evaluated and the larger value kept. It reports every bound below a sampled value (there must
be none) and the ratio bound / sampled maximum (median, largest).

    python scripts/map_execution_soundness.py --coefficients results/coefficients.json --n 10000
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--coefficients", default="results/coefficients.json", help="coefficients file (map beside)")
    parser.add_argument("--n", type=int, default=10000, help="random obstacles [count] (default: 10000)")
    parser.add_argument("--samples", type=int, default=2001, help="samples per trajectory [count] (default: 2001)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    args = parser.parse_args(argv)

    import pinocchio as pin

    from pipeline import REST_TO_REST, generate_batch, load_coefficients
    from pipeline.motion.timed_trajectory import TimedTrajectory
    from pipeline.motion.timing import RestToRestTiming
    from pipeline.online.arm_check import arm_for
    from pipeline.online.batch_execution import execution_batch
    from pipeline.online.execution import dynamics_of

    coefficients = load_coefficients(args.coefficients)
    region_map = coefficients.region_map
    if region_map is None or region_map.execution is None:
        print(f"{args.coefficients}: no region map with execution bounds beside it", file=sys.stderr)
        return 2
    arm = arm_for(coefficients)
    dynamics = dynamics_of(arm)
    model, data = arm.model, arm.model.createData()
    rng = np.random.default_rng(args.seed)
    (l_lo, l_hi), (w_lo, w_hi) = region_map.range_of("L"), region_map.range_of("W")
    L, W = rng.uniform(l_lo, l_hi, args.n), rng.uniform(w_lo, w_hi, args.n)
    batch = generate_batch(coefficients, L, W)
    bounds = region_map.execution
    leaf = batch.leaf

    def rnea(q, dq, ddq):
        pad = np.zeros(model.nq)
        full = [np.concatenate([x, pad[2:]]) for x in (q, dq, ddq)]
        return np.abs(pin.rnea(model, data, *full)[:2])

    def sampled_paper(i):
        trajectory = batch.trajectory(i)
        t = np.linspace(0.0, trajectory.duration_s, args.samples)
        q, dq, ddq = trajectory.q(t), trajectory.dq(t), trajectory.ddq(t)
        tau = np.abs(dynamics.torque(q, dq, ddq))
        k = np.argmax(tau, axis=0)
        peak_tau = np.maximum(tau.max(0), [rnea(q[k[j]], dq[k[j]], ddq[k[j]])[j] for j in (0, 1)])
        return q.min(0), q.max(0), np.abs(dq).max(0), np.abs(ddq).max(0), peak_tau

    def sampled_rest(i, c, r):
        trajectory = batch.trajectory(i)
        timed = TimedTrajectory(trajectory, RestToRestTiming(trajectory.duration_s, c, r))
        q, dq, ddq = timed.states(np.linspace(0.0, timed.duration_s, args.samples))
        tau = np.abs(dynamics.torque(q, dq, ddq))
        k = np.argmax(tau, axis=0)
        peak_tau = np.maximum(tau.max(0), [rnea(q[k[j]], dq[k[j]], ddq[k[j]])[j] for j in (0, 1)])
        return np.abs(dq).max(0), np.abs(ddq).max(0), peak_tau

    rest = execution_batch(coefficients, batch, REST_TO_REST)
    below = 0
    ratios: dict[str, list[np.ndarray]] = {
        k: [] for k in ("paper dq", "paper ddq", "paper tau", "r2r dq", "r2r ddq", "r2r tau")
    }
    for i in range(args.n):
        if leaf[i] < 0:
            continue
        lo, hi, v, a, tau = sampled_paper(i)
        angles = bounds.angle_range_rad[leaf[i]]
        below += int(np.sum(lo < angles[:, 0]) + np.sum(hi > angles[:, 1]))
        for name, bound, value in (
            ("paper dq", bounds.paper_speed_rad_s[leaf[i]], v),
            ("paper ddq", bounds.paper_acceleration_rad_s2[leaf[i]], a),
            ("paper tau", bounds.paper_torque_n_m[leaf[i]], tau),
        ):
            below += int(np.sum(bound < value))
            ratios[name].append(bound / value)
        if np.isfinite(rest.speed_scale[i]):
            v, a, tau = sampled_rest(i, float(rest.speed_scale[i]), float(rest.ramp_s[i]))
            for name, bound, value in (
                ("r2r dq", rest.speed_bound_rad_s[i], v),
                ("r2r ddq", rest.acceleration_bound_rad_s2[i], a),
                ("r2r tau", rest.torque_bound_n_m[i], tau),
            ):
                below += int(np.sum(bound < value))
                ratios[name].append(bound / value)
    print(f"{args.n} obstacles, {args.samples} samples each; bounds below a sampled value: {below}")
    for name, values in ratios.items():
        r = np.concatenate(values) if values else np.array([np.nan])
        print(f"  {name:10s} bound / sampled maximum: median {np.median(r):.7f}, largest {np.max(r):.7f}")
    return 1 if below else 0


if __name__ == "__main__":
    sys.exit(main())
