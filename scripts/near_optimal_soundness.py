"""Dense audit of the near time-optimal timing and its execution certificate on many random obstacles.

For N random (L, W) of the coefficients' fitted range (the same obstacles for every limit set),
each limit set builds the near time-optimal timing
(:func:`pipeline.motion.near_optimal.near_optimal_timing`), and the executed motion is audited
independently of the certificate's interval arithmetic:

* **Dense samples.** ``--samples`` uniform instants over [0, T'] plus every breakpoint of the timing
  and the instants 1e-12 s either side of it (clipped to [0, T']): q, dq, ddq and the jerk from the
  executed trajectory, the torques from the closed-form dynamics.
* **Refined maxima.** Around the ``--top`` largest sampled local maxima of each quantity (the
  largest and smallest angle, |dq_i|, |ddq_i|, |jerk_i|, |tau_i|), ``scipy.optimize.minimize_scalar``
  (bounded, over the two neighbouring sample intervals) maximises it with this script's own
  evaluation of the motion (sigma's cubic pieces and the sinusoids' derivatives by the chain rule,
  the torques in closed form); the optimiser's instants are then evaluated by the executed
  trajectory itself (and the torques by Pinocchio's RNEA too, the larger kept), so every refined
  maximum is a value the motion takes. The script's evaluation is compared with the executed
  trajectory's on a subsample, and the closed-form torques with RNEA (``rnea_torques``).
* **Checks** (each failure is a violation): a refined maximum above its certified bound (beyond
  1e-12 relative) or above its limit (likewise); an angle outside the certified angle range or the
  position limits; the acceleration discontinuous at a breakpoint
  (``|ddq(t+) - ddq(t-)| > jerk_bound * gap + 1e-9`` over the 2e-12 s gap); dq or ddq not exactly 0
  at t = 0 and t = T'; between consecutive samples, a change of q, dq or ddq larger than the
  certified bound of its derivative allows (mean value theorem, ``bound * dt + 1e-9``); the
  script's evaluation off the executed trajectory's (beyond 1e-9 relative), or the closed-form
  torques off RNEA (beyond 1e-9 N m).

Limit sets, each with the servo defaults (jerk = acceleration / 50 ms): (a) the URDF's limits and
5 rad/s^2 per joint; (b) (a) with 0.3 rad/s per joint; (c) (a) with 0.05 N m per joint.

It prints per set the obstacles, refusals, violations (0 expected), the largest and median ratio of
refined maximum to certified bound and the largest ratio to the limit per quantity, T' (median, min,
max) and the wall time per obstacle; ``--json`` writes all of it (and every violation and refusal).
Exit status: 0 no violation, 1 a violation, 2 bad input.

``--from-map`` audits the timing the map holds instead (:mod:`pipeline.certify.near_optimal_cells`):
per limit set the cells are made for it (every cell of the grid), and each obstacle executes its
cell's timing scaled to its path's T, checked against the cell's certificate.

    python scripts/near_optimal_soundness.py --coefficients results/coefficients.json --n 10000 --jobs 2
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from bisect import bisect_right
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

#: The limit sets: name -> what replaces the URDF's limits with 5 rad/s^2 (module docstring).
SETS = {
    "a": "URDF limits, 5 rad/s^2",
    "b": "URDF limits, 5 rad/s^2, 0.3 rad/s",
    "c": "URDF limits, 5 rad/s^2, 0.05 N m",
}
_ACCELERATION_RAD_S2 = 5.0
_SPEED_B_RAD_S = 0.3
_EFFORT_C_N_M = 0.05
#: Instants either side of a breakpoint [s].
_SIDE_S = 1e-12
#: Relative tolerance of a value against a bound or a limit.
_RELATIVE = 1e-12
#: Absolute tolerance of a change between samples (continuity, mean value) and of RNEA [unit of the quantity].
_ABSOLUTE = 1e-9
#: Relative tolerance of this script's evaluation against the executed trajectory's.
_EVALUATION_RELATIVE = 1e-9
#: Samples of the executed motion compared with this script's evaluation and with RNEA, per obstacle.
_CROSS_CHECKS = 64
#: The audited magnitudes, in column order of :func:`_values` (after the two angles).
MAGNITUDES = ("dq1", "dq2", "ddq1", "ddq2", "jerk1", "jerk2", "tau1", "tau2")
_UNITS = {"dq": "rad/s", "ddq": "rad/s^2", "jerk": "rad/s^3", "tau": "N m"}

_WORKER: dict = {}


def limit_sets(arm) -> dict:
    """The three limit sets of the module docstring (:class:`pipeline.model.limits.ArmLimits`)."""
    from pipeline.model.limits import ArmLimits

    base = ArmLimits.from_arm(arm, acceleration_rad_s2=(_ACCELERATION_RAD_S2, _ACCELERATION_RAD_S2))
    return {
        "a": base.with_servo_defaults(),
        "b": replace(base, velocity_rad_s=(_SPEED_B_RAD_S, _SPEED_B_RAD_S)).with_servo_defaults(),
        "c": replace(base, effort_n_m=(_EFFORT_C_N_M, _EFFORT_C_N_M)).with_servo_defaults(),
    }


def _init_worker(coefficients_source: str) -> None:
    """Load the coefficients, the arm, its dynamics and the limit sets once per process."""
    from pipeline import load_coefficients
    from pipeline.online.arm_check import arm_for
    from pipeline.online.execution import dynamics_of

    coefficients = load_coefficients(coefficients_source, region_map=None)
    arm = arm_for(coefficients)
    _WORKER.update(coefficients=coefficients, arm=arm, dynamics=dynamics_of(arm), limits=limit_sets(arm))


class _Motion:
    """This script's own evaluation of the executed motion at one instant (module docstring).

    sigma is the timing's cubic on the segment holding t (the right-hand one at a breakpoint; at
    and after T', sigma = T at rest), theta_i = A_i sin(w_i s + phi_i) + gamma_i, and the torques
    those of ``M(q2) ddq + h(q2) (2 dq1 dq2 + dq2^2, -dq1^2)``.
    """

    def __init__(self, executed, dynamics) -> None:
        timing = executed.timing
        self.knots = [float(v) for v in timing.breakpoints_s]
        self.start = timing.start.tolist()
        self.jerk = timing.jerk.tolist()
        self.end_s = float(timing.duration_s)
        self.path_end_s = float(timing.path_duration_s)
        p = [float(v) for v in executed.parameters]
        self.joints = (tuple(p[0:4]), tuple(p[4:8]))
        self.m0, self.mc, self.ms = dynamics.m0, dynamics.mc, dynamics.ms

    def at(self, t: float) -> tuple[float, ...]:
        """(q1, q2, dq1, dq2, ddq1, ddq2, jerk1, jerk2, tau1, tau2) at executed time t [s]."""
        if t >= self.end_s:
            s, d1, d2, d3 = self.path_end_s, 0.0, 0.0, 0.0
        else:
            t = max(t, 0.0)
            j = min(max(bisect_right(self.knots, t) - 1, 0), len(self.jerk) - 1)
            h = t - self.knots[j]
            c0, c1, c2 = self.start[j]
            k = self.jerk[j]
            s = min(max(c0 + h * (c1 + h * (c2 / 2.0 + h * k / 6.0)), 0.0), self.path_end_s)
            d1, d2, d3 = c1 + h * (c2 + h * k / 2.0), c2 + h * k, k
        q, dq, ddq, jerk = [], [], [], []
        for amplitude, w, phi, gamma in self.joints:
            sin, cos = math.sin(w * s + phi), math.cos(w * s + phi)
            t0, t1, t2, t3 = (
                amplitude * sin + gamma,
                amplitude * w * cos,
                -amplitude * w * w * sin,
                -amplitude * w**3 * cos,
            )
            q.append(t0)
            dq.append(t1 * d1)
            ddq.append(t2 * d1 * d1 + t1 * d2)
            jerk.append(t3 * d1**3 + 3.0 * t2 * d1 * d2 + t1 * d3)
        c, sn = math.cos(q[1]), math.sin(q[1])
        m = [[self.m0[i][j] + self.mc[i][j] * c + self.ms[i][j] * sn for j in (0, 1)] for i in (0, 1)]
        h = 0.5 * (-self.mc[0][0] * sn + self.ms[0][0] * c)
        tau1 = m[0][0] * ddq[0] + m[0][1] * ddq[1] + h * (2.0 * dq[0] * dq[1] + dq[1] ** 2)
        tau2 = m[1][0] * ddq[0] + m[1][1] * ddq[1] - h * dq[0] ** 2
        return (*q, *dq, *ddq, *jerk, tau1, tau2)


def _values(executed, dynamics, t: np.ndarray) -> np.ndarray:
    """(m, 10) q1, q2, dq1, dq2, ddq1, ddq2, jerk1, jerk2, tau1, tau2 at times t [s], as executed."""
    q, dq, ddq = executed.states(t)
    return np.hstack([q, dq, ddq, executed.jerk(t), dynamics.torque(q, dq, ddq)])


def _peaks(v: np.ndarray, top: int) -> np.ndarray:
    """Indices of the ``top`` largest local maxima of the samples v (ends included)."""
    left = np.concatenate([[-np.inf], v[:-1]])
    right = np.concatenate([v[1:], [-np.inf]])
    peaks = np.flatnonzero((v >= left) & (v >= right))
    return peaks[np.argsort(-v[peaks], kind="stable")[:top]]


def _sample_times(timing, samples: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sorted unique sample times, breakpoints' left instants, right instants) [s]."""
    end = timing.duration_s
    knots = np.asarray(timing.breakpoints_s, dtype=float)
    left, right = np.clip(knots - _SIDE_S, 0.0, end), np.clip(knots + _SIDE_S, 0.0, end)
    times = np.unique(np.concatenate([np.linspace(0.0, end, samples), knots, left, right]))
    return times, left, right


def _audit(executed, certificate, limits, dynamics, arm, samples: int, top: int, rng) -> dict:
    """The checks of the module docstring on one certified timing: maxima, ratios and violations."""
    from scipy.optimize import minimize_scalar

    from pipeline.model.dynamics import rnea_torques

    end = executed.duration_s
    times, left, right = _sample_times(executed.timing, samples)
    values = _values(executed, dynamics, times)
    motion = _Motion(executed, dynamics)
    violations: list[dict] = []

    def violation(kind: str, quantity: str, t: float, value: float, reference: float) -> None:
        violations.append({"kind": kind, "quantity": quantity, "t_s": float(t), "value": value, "reference": reference})

    # This script's evaluation against the executed trajectory's, and the closed form against RNEA.
    pick = np.unique(np.concatenate([rng.choice(times.size, _CROSS_CHECKS), np.argmax(np.abs(values), axis=0)]))
    own = np.array([motion.at(float(t)) for t in times[pick]])
    scale = np.maximum(np.abs(values[pick]), 1.0)
    evaluation_error = float((np.abs(own - values[pick]) / scale).max())
    if evaluation_error > _EVALUATION_RELATIVE:
        k = int(np.argmax((np.abs(own - values[pick]) / scale).max(1)))
        violation("evaluation", "all", times[pick][k], evaluation_error, _EVALUATION_RELATIVE)
    rnea = rnea_torques(arm, values[pick, 0:2], values[pick, 2:4], values[pick, 4:6])[:, :2]
    rnea_error = float(np.abs(rnea - values[pick, 8:10]).max())
    if rnea_error > _ABSOLUTE:
        violation("rnea", "tau", times[pick][int(np.argmax(np.abs(rnea - values[pick, 8:10]).max(1)))], rnea_error, 0)

    # Refined extremes: (column, sign) for q_i max, q_i min, and |x| for the magnitudes.
    targets = [("q1 max", 0, 1.0), ("q2 max", 1, 1.0), ("q1 min", 0, -1.0), ("q2 min", 1, -1.0)]
    targets += [(name, 2 + k, 0.0) for k, name in enumerate(MAGNITUDES)]
    refined_at: list[tuple[int, float]] = []  # (target, instant)
    for index, (_, column, sign) in enumerate(targets):
        v = values[:, column] * sign if sign else np.abs(values[:, column])
        for k in _peaks(v, top):
            a, b = times[max(k - 1, 0)], times[min(k + 1, times.size - 1)]
            if sign:
                result = minimize_scalar(
                    lambda t, c=column, s=sign: -s * motion.at(t)[c], bounds=(a, b), method="bounded",
                    options={"xatol": 1e-13},
                )  # fmt: skip
            else:
                result = minimize_scalar(
                    lambda t, c=column: -abs(motion.at(t)[c]), bounds=(a, b), method="bounded",
                    options={"xatol": 1e-13},
                )  # fmt: skip
            refined_at.append((index, float(result.x)))
    at = np.array([t for _, t in refined_at])
    refined_values = _values(executed, dynamics, at)
    refined_tau = np.maximum(
        np.abs(refined_values[:, 8:10]),
        np.abs(rnea_torques(arm, refined_values[:, 0:2], refined_values[:, 2:4], refined_values[:, 4:6])[:, :2]),
    )
    extreme: dict[str, tuple[float, float]] = {}  # target -> (value, instant): the largest taken
    for index, (name, column, sign) in enumerate(targets):
        v = values[:, column] * sign if sign else np.abs(values[:, column])
        k = int(np.argmax(v))
        best = (float(v[k]), float(times[k]))
        for (target, t), row, tau in zip(refined_at, refined_values, refined_tau, strict=True):
            if target != index:
                continue
            value = row[column] * sign if sign else (tau[column - 8] if column >= 8 else abs(row[column]))
            if value > best[0]:
                best = (float(value), t)
        extreme[name] = best

    # Bounds and limits.
    bound_of = {
        "dq": certificate.speed_bound_rad_s,
        "ddq": certificate.acceleration_bound_rad_s2,
        "jerk": certificate.jerk_bound_rad_s3,
        "tau": certificate.torque_bound_n_m,
    }
    limit_of = {
        "dq": limits.velocity_rad_s,
        "ddq": limits.acceleration_rad_s2,
        "jerk": limits.jerk_rad_s3,
        "tau": limits.effort_n_m,
    }
    ratios: dict[str, dict[str, float]] = {}
    for name in MAGNITUDES:
        kind, joint = name[:-1], int(name[-1]) - 1
        value, t = extreme[name]
        bound, limit = float(bound_of[kind][joint]), float(limit_of[kind][joint])
        ratios[name] = {
            "max": value,
            "bound": bound,
            "limit": limit,
            "to_bound": value / bound,
            "to_limit": value / limit,
        }
        if value > bound * (1.0 + _RELATIVE):
            violation("above bound", name, t, value, bound)
        if value > limit * (1.0 + _RELATIVE):
            violation("above limit", name, t, value, limit)
    angles = {}
    for joint in (0, 1):
        lo, hi = (float(v) for v in certificate.angle_range_rad[joint])
        p_lo, p_hi = limits.position_rad[joint]
        q_hi, t_hi = extreme[f"q{joint + 1} max"]
        q_lo, t_lo = extreme[f"q{joint + 1} min"]
        q_lo = -q_lo
        angles[f"q{joint + 1}"] = {"min": q_lo, "max": q_hi, "bound": [lo, hi], "limit": [p_lo, p_hi]}
        if q_hi > hi + _RELATIVE * abs(hi):
            violation("above bound", f"q{joint + 1} max", t_hi, q_hi, hi)
        if q_lo < lo - _RELATIVE * abs(lo):
            violation("below bound", f"q{joint + 1} min", t_lo, q_lo, lo)
        if q_hi > p_hi + _RELATIVE * abs(p_hi):
            violation("above limit", f"q{joint + 1} max", t_hi, q_hi, p_hi)
        if q_lo < p_lo - _RELATIVE * abs(p_lo):
            violation("below limit", f"q{joint + 1} min", t_lo, q_lo, p_lo)

    # Acceleration continuity at every breakpoint, over the gap either side of it.
    sides = _values(executed, dynamics, np.concatenate([left, right]))
    jumps = np.abs(sides[right.size :, 4:6] - sides[: left.size, 4:6])
    gaps = (right - left)[:, None]
    allowed = np.asarray(certificate.jerk_bound_rad_s3)[None, :] * gaps + _ABSOLUTE
    for k, joint in zip(*np.nonzero(jumps > allowed), strict=True):
        violation(
            "acceleration step", f"ddq{joint + 1}", float(left[k]), float(jumps[k, joint]), float(allowed[k, joint])
        )
    continuity = float((jumps / allowed).max())

    # At rest, exactly, at 0 and T'.
    ends = np.array([0.0, end])
    for quantity, rest in (("dq", executed.dq(ends)), ("ddq", executed.ddq(ends))):
        for k, joint in zip(*np.nonzero(rest != 0.0), strict=True):
            violation("not at rest", f"{quantity}{joint + 1}", float(ends[k]), float(rest[k, joint]), 0.0)

    # Mean value theorem between consecutive samples: a change within the derivative's bound.
    dt = np.diff(times)[:, None]
    for column, (quantity, derivative_bound) in enumerate(
        (("q", certificate.speed_bound_rad_s), ("dq", certificate.acceleration_bound_rad_s2),
         ("ddq", certificate.jerk_bound_rad_s3))
    ):  # fmt: skip
        change = np.abs(np.diff(values[:, 2 * column : 2 * column + 2], axis=0))
        allowed = np.asarray(derivative_bound)[None, :] * dt * (1.0 + _RELATIVE) + _ABSOLUTE
        for k, joint in zip(*np.nonzero(change > allowed), strict=True):
            violation(
                "mean value",
                f"{quantity}{joint + 1}",
                float(times[k]),
                float(change[k, joint]),
                float(allowed[k, joint]),
            )

    return {
        "duration_s": end,
        "breakpoints": int(executed.timing.breakpoints_s.size),
        "samples": int(times.size),
        "ratios": ratios,
        "angles": angles,
        "continuity_to_allowed": continuity,
        "evaluation_error": evaluation_error,
        "rnea_error_n_m": rnea_error,
        "violations": violations,
    }


def _from_cells(cells_path: str, trajectory, length: float, width: float):
    """The map's near-optimal timing of the obstacle's cell (``--from-map``), as the online step
    executes it: the cell's timing scaled to the path's T, with the cell's certificate."""
    from types import SimpleNamespace

    from pipeline.certify.near_optimal_cells import load_near_optimal_cells
    from pipeline.exceptions import TimingRefusedError
    from pipeline.motion.timed_trajectory import TimedTrajectory

    cells = _WORKER.get(cells_path)
    if cells is None:
        cells = _WORKER[cells_path] = load_near_optimal_cells(cells_path)
    cell = cells.cell_of(length, width)
    if cell is None:
        raise TimingRefusedError(("no certified cell holds the obstacle",))
    executed = TimedTrajectory(trajectory, cells.timing(cell, trajectory.duration_s))
    return SimpleNamespace(executed=executed, certificate=cells.certificate(cell), attempts=0, limit_share=math.nan)


def _audit_chunk(task: tuple) -> list[dict]:
    """Build and audit the timings of one chunk of obstacles for one limit set (in a worker)."""
    from pipeline import generate
    from pipeline.exceptions import PipelineError, TimingRefusedError
    from pipeline.motion.near_optimal import near_optimal_timing

    name, obstacles, samples, top, seed, cells_path = task
    coefficients, arm, dynamics = _WORKER["coefficients"], _WORKER["arm"], _WORKER["dynamics"]
    limits = _WORKER["limits"][name]
    out = []
    for index, length, width in obstacles:
        rng = np.random.default_rng([seed, index])
        record: dict = {"set": name, "index": index, "L_m": length, "W_m": width}
        start = time.perf_counter()
        try:
            trajectory = generate(coefficients, length, width, region_map=None).trajectory
            if cells_path is None:
                result = near_optimal_timing(trajectory, dynamics, limits)
            else:
                result = _from_cells(cells_path, trajectory, length, width)
        except TimingRefusedError as error:
            record.update(status="refused", reason=str(error), seconds=time.perf_counter() - start)
            out.append(record)
            continue
        except PipelineError as error:
            record.update(
                status="error", reason=f"{type(error).__name__}: {error}", seconds=time.perf_counter() - start
            )
            out.append(record)
            continue
        built = time.perf_counter()
        record.update(status="audited", attempts=result.attempts, limit_share=result.limit_share)
        record.update(_audit(result.executed, result.certificate, limits, dynamics, arm, samples, top, rng))
        record.update(timing_seconds=built - start, seconds=time.perf_counter() - start)
        out.append(record)
    return out


def summarize(name: str, records: list[dict]) -> dict:
    """Per limit set: counts, the ratios' largest and median, T' and the wall time per obstacle."""
    audited = [r for r in records if r["status"] == "audited"]
    summary: dict = {
        "set": name,
        "description": SETS[name],
        "obstacles": len(records),
        "audited": len(audited),
        "refused": sum(r["status"] == "refused" for r in records),
        "errors": sum(r["status"] == "error" for r in records),
        "violations": sum(len(r["violations"]) for r in audited),
        "seconds_per_obstacle": float(np.mean([r["seconds"] for r in records])) if records else math.nan,
    }
    if not audited:
        return summary
    durations = np.array([r["duration_s"] for r in audited])
    summary["duration_s"] = {"median": float(np.median(durations)), "min": durations.min(), "max": durations.max()}
    summary["timing_seconds_median"] = float(np.median([r["timing_seconds"] for r in audited]))
    summary["samples_median"] = float(np.median([r["samples"] for r in audited]))
    summary["ratios"] = {}
    for quantity in MAGNITUDES:
        to_bound = np.array([r["ratios"][quantity]["to_bound"] for r in audited])
        to_limit = np.array([r["ratios"][quantity]["to_limit"] for r in audited])
        summary["ratios"][quantity] = {
            "to_bound_max": to_bound.max(),
            "to_bound_median": float(np.median(to_bound)),
            "to_limit_max": to_limit.max(),
        }
    summary["angle_gap_rad"] = {}
    for joint in ("q1", "q2"):
        # Certified range minus the range taken, at the nearer end (>= 0: within the certificate).
        gaps = [
            min(r["angles"][joint]["bound"][1] - r["angles"][joint]["max"],
                r["angles"][joint]["min"] - r["angles"][joint]["bound"][0])
            for r in audited
        ]  # fmt: skip
        summary["angle_gap_rad"][joint] = {"min": float(np.min(gaps)), "median": float(np.median(gaps))}
    summary["continuity_to_allowed_max"] = max(r["continuity_to_allowed"] for r in audited)
    summary["evaluation_error_max"] = max(r["evaluation_error"] for r in audited)
    summary["rnea_error_max_n_m"] = max(r["rnea_error_n_m"] for r in audited)
    return summary


def _print_summary(summary: dict, elapsed_s: float, jobs: int) -> None:
    s = summary
    print(f"set {s['set']} ({s['description']}): {s['obstacles']} obstacles, {s['audited']} audited, "
          f"{s['refused']} refused, {s['errors']} errors, violations {s['violations']} (must be 0)")  # fmt: skip
    if "duration_s" not in s:
        return
    d = s["duration_s"]
    print(f"  T' [s]: median {d['median']:.4f}, min {d['min']:.4f}, max {d['max']:.4f}; "
          f"{s['samples_median']:.0f} samples (median) per obstacle")  # fmt: skip
    print(f"  wall time per obstacle: {1e3 * s['seconds_per_obstacle']:.1f} ms in a worker "
          f"(timing {1e3 * s['timing_seconds_median']:.1f} ms median), {1e3 * elapsed_s / s['obstacles']:.1f} ms "
          f"elapsed with {jobs} jobs")  # fmt: skip
    print(f"  {'quantity':<8} {'max/bound largest':>18} {'max/bound median':>17} {'max/limit largest':>18}")
    for quantity, r in s["ratios"].items():
        print(f"  {quantity:<8} {r['to_bound_max']:>18.10f} {r['to_bound_median']:>17.10f} {r['to_limit_max']:>18.10f}")
    for joint, g in s["angle_gap_rad"].items():
        print(f"  {joint} certified range - range taken, at the nearer end [rad]: smallest {g['min']:.3e}, "
              f"median {g['median']:.3e} (>= 0)")  # fmt: skip
    print(f"  acceleration step at breakpoints / allowed: largest {s['continuity_to_allowed_max']:.3e} (<= 1); "
          f"own evaluation vs executed: {s['evaluation_error_max']:.1e} relative; "
          f"closed form vs RNEA: {s['rnea_error_max_n_m']:.1e} N m")  # fmt: skip


def _write_cells(name: str, folder: str, jobs: int) -> str:
    """Make the near-optimal cells of limit set ``name`` and write them into ``folder``; their path."""
    from pipeline.certify.cell_timings import near_optimal_cells
    from pipeline.certify.near_optimal_cells import cells_files

    started = time.perf_counter()
    limits = _WORKER["limits"][name]
    cells = near_optimal_cells(_WORKER["coefficients"], _WORKER["dynamics"], limits, executor=jobs)
    header = Path(folder) / f"cells_{name}.json"
    for file_name, data in cells_files(cells, header.name).items():
        (Path(folder) / file_name).write_bytes(data)
    print(f"  set {name}: near-optimal cells made, {int(cells.certified.sum())} of {cells.table.size} certified, "
          f"{time.perf_counter() - started:.0f} s")  # fmt: skip
    return str(header)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--coefficients", default="results/coefficients.json", help="coefficients file, or 'paper'")
    parser.add_argument(
        "--sets", nargs="+", choices=sorted(SETS), default=sorted(SETS), help="limit sets (default: a b c)"
    )
    parser.add_argument("--n", type=int, default=10000, help="random obstacles per limit set [count] (default: 10000)")
    parser.add_argument(
        "--samples", type=int, default=20001, help="uniform samples of [0, T'] per obstacle [count] (default: 20001)"
    )
    parser.add_argument("--top", type=int, default=3, help="sampled maxima refined per quantity [count] (default: 3)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes [count] (default: 1: in this process)")
    parser.add_argument("--chunk", type=int, default=25, help="obstacles per task [count] (default: 25)")
    parser.add_argument("--json", default=None, help="write the summaries, violations and refusals to this JSON file")
    parser.add_argument(
        "--from-map",
        action="store_true",
        help="audit the map's near-optimal timing instead: per limit set, the near-optimal cells made for it "
        "(pipeline.certify.near_optimal_cells, every cell), each obstacle executing its cell's timing",
    )
    args = parser.parse_args(argv)
    for flag, value, least in (("--n", args.n, 1), ("--samples", args.samples, 2), ("--top", args.top, 1),
                               ("--jobs", args.jobs, 1), ("--chunk", args.chunk, 1)):  # fmt: skip
        if value < least:
            print(f"near_optimal_soundness: {flag} {value} must be >= {least}", file=sys.stderr)
            return 2

    from pipeline import PipelineError
    from pipeline.io.jsonio import write_json_atomic

    try:
        _init_worker(args.coefficients)
    except PipelineError as error:
        print(f"near_optimal_soundness: {error}", file=sys.stderr)
        return 2
    (l_lo, l_hi), (w_lo, w_hi) = (_WORKER["coefficients"].fitted_range_m[k] for k in ("L", "W"))
    rng = np.random.default_rng(args.seed)
    lengths, widths = rng.uniform(l_lo, l_hi, args.n), rng.uniform(w_lo, w_hi, args.n)
    obstacles = [(k, float(lengths[k]), float(widths[k])) for k in range(args.n)]
    sets = list(dict.fromkeys(args.sets))
    print(f"near-optimal timing audit: {args.n} obstacles of L in [{l_lo}, {l_hi}] m, W in [{w_lo}, {w_hi}] m "
          f"(seed {args.seed}), {args.samples} uniform samples + breakpoints each, top {args.top} maxima refined, "
          f"{args.jobs} jobs, coefficients {args.coefficients}")  # fmt: skip
    for name in sets:
        limits = _WORKER["limits"][name]
        print(f"  set {name}: speed {limits.velocity_rad_s} rad/s, acceleration {limits.acceleration_rad_s2} rad/s^2, "
              f"effort {limits.effort_n_m} N m, jerk {limits.jerk_rad_s3} rad/s^3")  # fmt: skip

    pool = (
        ProcessPoolExecutor(args.jobs, initializer=_init_worker, initargs=(args.coefficients,))
        if args.jobs > 1
        else None
    )
    summaries, violations, refusals = [], [], []
    folder = tempfile.TemporaryDirectory() if args.from_map else None
    try:
        for name in sets:
            cells_path = None if folder is None else _write_cells(name, folder.name, args.jobs)
            tasks = [
                (name, obstacles[k : k + args.chunk], args.samples, args.top, args.seed, cells_path)
                for k in range(0, args.n, args.chunk)
            ]
            started = time.perf_counter()
            chunks = pool.map(_audit_chunk, tasks) if pool else map(_audit_chunk, tasks)
            records: list[dict] = []
            for chunk in chunks:
                records.extend(chunk)
                if len(records) % 1000 < args.chunk and len(records) < args.n:
                    bad = sum(len(r.get("violations", ())) for r in records)
                    print(
                        f"  set {name}: {len(records)} / {args.n} obstacles, {bad} violations",
                        file=sys.stderr,
                        flush=True,
                    )
            elapsed = time.perf_counter() - started
            summary = summarize(name, records)
            summary["elapsed_s"] = elapsed
            summaries.append(summary)
            _print_summary(summary, elapsed, args.jobs)
            for r in records:
                for v in r.get("violations", ()):
                    violations.append({"set": name, "index": r["index"], "L_m": r["L_m"], "W_m": r["W_m"], **v})
                if r["status"] != "audited":
                    refusals.append({k: r[k] for k in ("set", "index", "L_m", "W_m", "status", "reason")})
    finally:
        if pool:
            pool.shutdown()
        if folder is not None:
            folder.cleanup()
    for v in violations[:20]:
        print(f"VIOLATION set {v['set']} obstacle {v['index']} (L = {v['L_m']!r} m, W = {v['W_m']!r} m): {v['kind']} "
              f"{v['quantity']} at t = {v['t_s']!r} s: {v['value']!r} vs {v['reference']!r}")  # fmt: skip
    for r in refusals[:10]:
        where = f"set {r['set']} obstacle {r['index']} (L = {r['L_m']!r} m, W = {r['W_m']!r} m)"
        print(f"{r['status']}: {where}: {r['reason']}")
    errors = sum(s["errors"] for s in summaries)
    total = len(violations)
    print(f"total: {total} violations, {errors} errors, {sum(s['refused'] for s in summaries)} refused")
    if args.json:
        report = {"arguments": vars(args), "summaries": summaries, "violations": violations, "refusals": refusals}
        write_json_atomic(args.json, report)
    return 1 if total or errors else 0


if __name__ == "__main__":
    sys.exit(main())
