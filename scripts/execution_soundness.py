"""Soundness and tightness of the execution certificate on many random obstacles.

For N random (L, W) of the coefficients' fitted range, each with the paper timing and the shortest
rest-to-rest timing within the arm's URDF limits (and an acceleration limit), it certifies tight
bounds on |dq|, |ddq| and |tau| (:func:`pipeline.motion.execution_certificate.certify_execution`)
and compares them with the maxima of a sampling 100 times denser than the certificate's final
partition. The dense torques come from the closed-form dynamics (tests/model/test_dynamics.py
proves it equal to Pinocchio's RNEA to 1e-12); at each maximising sample Pinocchio's RNEA is
evaluated too and the larger value kept. It reports every bound that lies below a sampled value
(there must be none) and the ratio bound / sampled maximum (median, largest).

    python scripts/execution_soundness.py --coefficients results/coefficients.json --n 10000
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--coefficients", default="results/coefficients.json", help="coefficients file, or 'paper'")
    parser.add_argument("--n", type=int, default=10000, help="random obstacles [count] (default: 10000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    parser.add_argument(
        "--acceleration-limit", type=float, default=5.0, help="acceleration limit of both joints [rad/s^2] (default: 5)"
    )
    args = parser.parse_args(argv)

    import pinocchio as pin

    from pipeline import PipelineError, generate, load_coefficients
    from pipeline.model.limits import ArmLimits
    from pipeline.motion.execution_certificate import certify_execution
    from pipeline.motion.rest_to_rest import shortest_rest_to_rest
    from pipeline.motion.timed_trajectory import TimedTrajectory
    from pipeline.motion.timing import PAPER_TIMING
    from pipeline.online.arm_check import arm_for
    from pipeline.online.execution import dynamics_of

    try:
        coefficients = load_coefficients(args.coefficients, region_map=None)
        arm = arm_for(coefficients)
    except PipelineError as error:
        print(f"execution_soundness: {error}", file=sys.stderr)
        return 2
    dynamics = dynamics_of(arm)
    limits = ArmLimits.from_arm(arm, (args.acceleration_limit, args.acceleration_limit))
    rng = np.random.default_rng(args.seed)
    (l_lo, l_hi), (w_lo, w_hi) = coefficients.fitted_range_m["L"], coefficients.fitted_range_m["W"]
    data = arm.model.createData()
    ratios: dict[str, list[float]] = {"dq": [], "ddq": [], "tau": []}
    below = 0
    for k in range(args.n):
        L, W = float(rng.uniform(l_lo, l_hi)), float(rng.uniform(w_lo, w_hi))
        trajectory = generate(coefficients, L, W, region_map=None).trajectory
        paper = certify_execution(TimedTrajectory(trajectory, PAPER_TIMING), dynamics)
        retimed = shortest_rest_to_rest(trajectory, dynamics, limits)
        for timed in (TimedTrajectory(trajectory, PAPER_TIMING), TimedTrajectory(trajectory, retimed)):
            certificate = paper if timed.timing is PAPER_TIMING or timed.timing.name == "paper" else None
            certificate = certify_execution(timed, dynamics) if certificate is None else certificate
            t = np.linspace(0.0, timed.duration_s, 100 * certificate.intervals + 1)
            q, dq, ddq = timed.q(t), timed.dq(t), timed.ddq(t)
            tau = dynamics.torque(q, dq, ddq)
            for k_max in set(np.argmax(np.abs(tau), axis=0).tolist()):
                tau[k_max] = pin.rnea(arm.model, data, q[k_max], dq[k_max], ddq[k_max])
            for key, bound, values in (
                ("dq", certificate.speed_bound_rad_s, dq),
                ("ddq", certificate.acceleration_bound_rad_s2, ddq),
                ("tau", certificate.torque_bound_n_m, tau),
            ):
                sampled = np.abs(values).max(0)
                below += int(np.sum(bound < sampled))
                ratios[key].extend((bound / np.maximum(sampled, 1e-300)).tolist())
        if (k + 1) % 500 == 0:
            print(f"{k + 1} / {args.n} obstacles, {below} bounds below a sampled value", file=sys.stderr, flush=True)
    print(f"{args.n} obstacles x 2 timings x 2 joints: {below} bounds below a sampled value (must be 0)")
    for key, values in ratios.items():
        r = np.array(values)
        print(f"  |{key}|: bound / sampled maximum: median {np.median(r):.8f}, largest {r.max():.8f}")
    return 0 if below == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
