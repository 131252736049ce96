"""``python -m pipeline.generate --L 0.27 --W 0.09``: the online step from the command line.

Prints which coefficients it uses, the eight sinusoid parameters and T for the obstacle L x W,
and, where the region map beside the coefficients covers (L, W), its certified clearance and
endpoint-error bounds over the whole of [0, T]. With ``--certify``, the answer must keep the
margin: a cell of the map certified to keep it answers at once; elsewhere the trajectory is
certified per query with Coal (and repaired if needed, unless ``--no-repair``). With ``--out FILE`` it writes the
trajectory sampled at ``--rate`` (t = 0, 1/rate, 2/rate, ... and T itself as the last sample), in
the format the suffix names:

* ``.csv``: one row per sample, columns ``t_s, q1_rad, q2_rad, dq1_rad_s, dq2_rad_s,
  ddq1_rad_s2, ddq2_rad_s2`` (units in the names);
* ``.npz``: arrays ``t_s`` (n,), ``q_rad``, ``dq_rad_s``, ``ddq_rad_s2`` (n, 2), and ``parameters``
  (8,) with ``parameter_names``, ``duration_s``, ``joint_names``;
* ``.json``: a ROS ``trajectory_msgs/JointTrajectory`` (``header``, ``joint_names`` from the URDF,
  ``points`` with ``positions`` [rad], ``velocities`` [rad/s], ``accelerations`` [rad/s^2] and
  ``time_from_start`` as ``{"sec", "nanosec"}``).

The file is written atomically (a temporary file in the same folder, then a rename), only after
everything else succeeded. Exit status: 0 done; 1 certification refused (the reason on stderr, no
file written); 2 bad input (one line on stderr, no file written); 130 interrupted.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pipeline.cli import (
    DEFAULT_COEFFICIENTS,
    EXIT_FAILED,
    EXIT_OK,
    Parser,
    arm_for_cli,
    check_output_file,
    describe_coefficients,
    load_coefficients_for_cli,
    run_cli,
)
from pipeline.exceptions import InvalidParameterError, NoCertifiedTrajectoryError
from pipeline.io.jsonio import dumps, write_bytes_atomic
from pipeline.model.arm import PlanarArm
from pipeline.motion.trajectory import PARAMETER_NAMES, PARAMETER_UNITS, JointTrajectory
from pipeline.online.generator import OUT_OF_RANGE_POLICIES, generate
from pipeline.online.repair import RepairConfig, generate_certified

PROG = "python -m pipeline.generate"
#: Output formats, by file suffix.
FORMATS = (".csv", ".npz", ".json")
#: Default sampling rate of the written trajectory [Hz].
DEFAULT_RATE_HZ = 100.0
#: Most samples a written trajectory may hold (about 56 MB as NPZ, more as JSON).
MAX_SAMPLES = 1_000_000
#: Tolerance of the certificate the CLI prints [m]: the bound is within this of the sampled minimum.
CLI_CERTIFICATE_TOLERANCE_M = 1e-5
#: Columns of the CSV file (units in the names).
CSV_COLUMNS = ("t_s", "q1_rad", "q2_rad", "dq1_rad_s", "dq2_rad_s", "ddq1_rad_s2", "ddq2_rad_s2")


def sample_times(duration_s: float, rate_hz: float) -> np.ndarray:
    """t = 0, 1/rate, 2/rate, ... below T, then T itself [s] (each k / rate computed directly)."""
    count = math.floor(duration_s * rate_hz)
    times = np.arange(count + 1) / rate_hz
    times = times[times < duration_s]
    return np.append(times, duration_s)


def ros_duration(t_s: float) -> dict[str, int]:
    """A ROS 2 ``builtin_interfaces/Duration``: {"sec", "nanosec"} with 0 <= nanosec < 1e9."""
    total = round(t_s * 1e9)
    return {"sec": int(total // 1_000_000_000), "nanosec": int(total % 1_000_000_000)}


def joint_names(arm: PlanarArm | None) -> list[str]:
    """The URDF's names of the two joints (``joint1``, ``joint2`` without an arm)."""
    if arm is None:
        return ["joint1", "joint2"]
    return [str(arm.model.names[1]), str(arm.model.names[2])]


def trajectory_document(trajectory: JointTrajectory, times: np.ndarray, names: Sequence[str]) -> dict:
    """The trajectory as a ROS ``trajectory_msgs/JointTrajectory`` message (plain JSON)."""
    q, dq, ddq = trajectory.q(times), trajectory.dq(times), trajectory.ddq(times)
    return {
        "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},
        "joint_names": list(names),
        "points": [
            {
                "positions": q[i].tolist(),
                "velocities": dq[i].tolist(),
                "accelerations": ddq[i].tolist(),
                "effort": [],
                "time_from_start": ros_duration(float(t)),
            }
            for i, t in enumerate(times)
        ],
    }


def encode(path: Path, trajectory: JointTrajectory, times: np.ndarray, names: Sequence[str]) -> bytes:
    """The file's bytes in the format of ``path``'s suffix."""
    suffix = path.suffix.lower()
    if suffix == ".json":
        return dumps(trajectory_document(trajectory, times, names)).encode("utf-8")
    q, dq, ddq = trajectory.q(times), trajectory.dq(times), trajectory.ddq(times)
    if suffix == ".npz":
        buffer = io.BytesIO()
        np.savez(
            buffer,
            t_s=times,
            q_rad=q,
            dq_rad_s=dq,
            ddq_rad_s2=ddq,
            parameters=np.array(trajectory.parameters),
            parameter_names=np.array(PARAMETER_NAMES),
            duration_s=np.array(trajectory.duration_s),
            joint_names=np.array(list(names)),
        )
        return buffer.getvalue()
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for row in np.column_stack([times, q, dq, ddq]):
        writer.writerow([repr(float(v)) for v in row])
    return text.getvalue().encode("utf-8")


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface of ``python -m pipeline.generate``."""
    p = Parser(
        prog=PROG,
        description="The online step: the trajectory for the obstacle L x W from the regression coefficients, "
        "optionally certified (and repaired), printed and written sampled at a rate (CSV, NPZ or ROS JSON).",
    )
    p.add_argument("--L", type=float, required=True, metavar="M", help="obstacle length L [m]")
    p.add_argument("--W", type=float, required=True, metavar="M", help="obstacle width W [m]")
    p.add_argument(
        "--coefficients",
        metavar="FILE",
        default=DEFAULT_COEFFICIENTS,
        help="coefficients file, or 'paper' for the paper's Eq. 9",
    )
    p.add_argument(
        "--urdf",
        metavar="U",
        default=None,
        help="the arm's URDF (default: the one recorded with the coefficients; given, it must match them)",
    )
    p.add_argument(
        "--certify",
        action="store_true",
        help="certify the clearance over all of [0, T] (Coal); repair the trajectory if it is below the margin",
    )
    p.add_argument("--no-repair", action="store_true", help="with --certify: refuse instead of repairing")
    p.add_argument(
        "--margin",
        type=float,
        default=None,
        metavar="M",
        help="with --certify: clearance to certify [m] (default: the coefficients' scene margin)",
    )
    p.add_argument(
        "--out-of-range",
        choices=OUT_OF_RANGE_POLICIES,
        default="warn",
        help="outside the fitted range: warn, refuse (error) or ignore",
    )
    p.add_argument(
        "--rate",
        type=float,
        default=DEFAULT_RATE_HZ,
        metavar="HZ",
        help=f"sampling rate of --out [Hz], at most {MAX_SAMPLES:,} samples in all",
    )
    p.add_argument(
        "--out",
        metavar="FILE",
        default=None,
        help="write the sampled trajectory; the suffix picks the format: .csv, .npz or .json (ROS JointTrajectory)",
    )
    return p


def _check_inputs(args: argparse.Namespace) -> Path | None:
    """Every check that needs no work: rate, margin, output path and format. Returns the output path."""
    if not (math.isfinite(args.rate) and args.rate > 0.0):
        raise InvalidParameterError("--rate", args.rate, "a positive finite rate [Hz]")
    if args.margin is not None and not (math.isfinite(args.margin) and args.margin >= 0.0):
        raise InvalidParameterError("--margin", args.margin, "a non-negative finite clearance [m]")
    if args.no_repair and not args.certify:
        raise InvalidParameterError("--no-repair", True, "used with --certify")
    if args.out is None:
        return None
    out = Path(args.out)
    if out.suffix.lower() not in FORMATS:
        raise InvalidParameterError("--out", str(out), f"a file name ending in one of {', '.join(FORMATS)}")
    out = check_output_file(args.out, "--out")  # probes the folder: /proc is refused now, not after the work
    return out


def _range_line(generated) -> str:
    """What the region map certifies for this answer, in one line."""
    if generated.certificate_source is None:
        return "range certificate: none for this answer (no region map beside the coefficients, or outside its range)"
    return (
        f"range certificate: clearance >= {generated.certified_clearance_m * 1e3:.3f} mm over all of [0, T], "
        f"endpoint error <= {generated.endpoint_error_bound_m * 1e3:.3f} mm (map cell: {generated.range_status})"
    )


def work(args: argparse.Namespace) -> int:
    """Generate (and certify), print, write; see the module docstring for the exit status."""
    out = _check_inputs(args)
    coefficients = load_coefficients_for_cli(args.coefficients)
    print(describe_coefficients(coefficients))
    needs_arm = args.certify or args.urdf is not None or (out is not None and out.suffix.lower() == ".json")
    arm = arm_for_cli(coefficients, args.urdf) if needs_arm else None
    started = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        generated = generate(coefficients, args.L, args.W, out_of_range=args.out_of_range)
    for warning in caught:
        print(f"{PROG}: warning: {warning.message}", file=sys.stderr)
    trajectory = generated.trajectory
    certified = None
    if args.certify:
        config = RepairConfig(
            margin_m=args.margin, repair=not args.no_repair, certificate_tolerance_m=CLI_CERTIFICATE_TOLERANCE_M
        )
        try:
            certified = generate_certified(coefficients, args.L, args.W, arm, out_of_range="ignore", config=config)
        except NoCertifiedTrajectoryError as exc:
            print(f"{PROG}: certification refused: {exc}", file=sys.stderr)
            return EXIT_FAILED
        trajectory = certified.trajectory
    elapsed = time.perf_counter() - started

    print(
        f"obstacle L = {generated.length_m!r} m, W = {generated.width_m!r} m"
        + (" (outside the fitted range: extrapolated)" if generated.extrapolated else "")
    )
    for name, value in trajectory.as_dict().items():
        print(f"  {name:<7s}= {value: .9f} {PARAMETER_UNITS[name]}")
    print(f"T = {trajectory.duration_s:.9f} s")
    print(_range_line(generated))
    if certified is not None and certified.certificate is None:
        print(
            f"certificate: the region map's cell keeps the margin {certified.margin_m * 1e3:.3f} mm "
            f"(clearance >= {certified.certified_clearance_m * 1e3:.3f} mm over all of [0, T]): the regression's "
            "answer, unchanged"
        )
    elif certified is not None:
        certificate = certified.certificate
        source = (
            f"repaired in {certified.repair_seconds * 1e3:.1f} ms (the regression's answer: "
            f"{certified.regression_certificate.certified_clearance_m * 1e3:.3f} mm)"
            if certified.repaired
            else "the regression's answer, unchanged"
        )
        print(
            f"certificate: clearance >= {certificate.certified_clearance_m * 1e3:.3f} mm over all of [0, T] "
            f"(rigorous lower bound, link {certificate.bound_link} at t = {certificate.bound_time_s:.4f} s; "
            f"margin {certified.margin_m * 1e3:.3f} mm; {certificate.evaluations} Coal configurations): {source}"
        )
    if certified is not None:
        print(f"repair_seconds = {certified.repair_seconds:.6f}")
    print(f"time: {elapsed * 1e3:.3f} ms")
    if out is not None:
        if trajectory.duration_s * args.rate + 1.0 > MAX_SAMPLES:
            raise InvalidParameterError(
                "--rate",
                args.rate,
                f"a rate giving at most {MAX_SAMPLES:,} samples over T = {trajectory.duration_s:.3f} s",
            )
        times = sample_times(trajectory.duration_s, args.rate)
        try:
            write_bytes_atomic(out, encode(out, trajectory, times, joint_names(arm)))
        except OSError as exc:
            raise InvalidParameterError("--out", str(out), f"a writable file ({exc.strerror})") from None
        print(f"wrote {out} ({times.size} samples at {args.rate:g} Hz, the last at T)")
    return EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    return run_cli(build_parser(), work, argv)


if __name__ == "__main__":
    sys.exit(main())
