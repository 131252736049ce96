"""``python -m pipeline.build``: DOE -> PSO per experiment -> regression -> coefficients.

Writes ``DIR/doe.json`` and ``DIR/coefficients.json`` atomically (deterministic for a seed:
no timestamps, independent of --jobs) and ``DIR/build_timing.json`` (wall times and query
counts, which vary run to run). Prints our Table 2 and Eq. 9 beside the paper's.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
from tqdm import tqdm

from pipeline.exceptions import OutputExistsError, PipelineError
from pipeline.io.jsonio import dumps, write_json_atomic, write_text_atomic
from pipeline.io.provenance import package_versions, sha256_file
from pipeline.model.arm import DEFAULT_URDF, load_planar_arm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.families import FAMILY_NAMES, PAPER, PAPER_SOURCE, family_from_name
from pipeline.motion.path import desired_path
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline import report
from pipeline.offline.coefficients import fit_coefficients, load_coefficients, paper_data_path
from pipeline.offline.doe import Design, doe_document, doe_from_json, load_doe, run_doe
from pipeline.offline.endpoint_regression import EndpointConstraint
from pipeline.offline.experiment import SolverConfig, score_parameters
from pipeline.offline.fitness import FitnessConfig
from pipeline.offline.pso import PsoConfig
from pipeline.regress import add_regression_arguments, endpoint_constraint


def parser() -> argparse.ArgumentParser:
    defaults_pso, defaults_fit, defaults_scene = PsoConfig(), FitnessConfig(), Scene()
    p = argparse.ArgumentParser(
        prog="python -m pipeline.build",
        description="Run the DOE (PSO + exact Coal clearance per obstacle) and regress the coefficients.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument(
        "--out",
        type=Path,
        default=Path("results"),
        help="output folder (doe.json, coefficients.json, build_timing.json)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="master random seed [integer]; the same seed gives byte-identical coefficients",
    )
    p.add_argument("--levels", type=int, default=3, help="levels per factor [count], K x K design, K >= 3")
    p.add_argument("--L-range", nargs=2, type=float, default=[0.20, 0.30], metavar=("MIN", "MAX"), help="L range [m]")
    p.add_argument("--W-range", nargs=2, type=float, default=[0.08, 0.12], metavar=("MIN", "MAX"), help="W range [m]")
    p.add_argument("--family", choices=FAMILY_NAMES, default=PAPER.name, help="trajectory family")
    p.add_argument("--jobs", type=int, default=1, help="worker processes [count]; does not change the result")
    p.add_argument("--urdf", type=Path, default=DEFAULT_URDF, help="URDF of the arm")
    p.add_argument("--swarm-size", type=int, default=defaults_pso.swarm_size, help="PSO particles per swarm [count]")
    p.add_argument("--iterations", type=int, default=defaults_pso.iterations, help="PSO iterations per restart [count]")
    p.add_argument(
        "--restarts", type=int, default=defaults_pso.restarts, help="independent PSO swarms [count], each polished"
    )
    p.add_argument("--no-polish", action="store_true", help="skip the least_squares polish after PSO")
    p.add_argument(
        "--n-points", type=int, default=defaults_fit.n_points, help="path points n of Eq. 5 [count], uniform in x"
    )
    p.add_argument(
        "--endpoint-weight",
        type=float,
        default=defaults_fit.endpoint_weight,
        help="weight of the first and last 3 path points in Eq. 5 [-]",
    )
    p.add_argument(
        "--penalty-weight",
        type=float,
        default=defaults_fit.penalty_weight,
        help="clearance penalty weight [1/m^2 relative to Eq. 5's m^2]",
    )
    p.add_argument("--margin", type=float, default=defaults_scene.margin_m, help="safety margin [m]")
    p.add_argument(
        "--margin-buffer",
        type=float,
        default=defaults_fit.margin_buffer_m,
        help="extra clearance the optimiser aims for beyond the margin [m]",
    )
    p.add_argument(
        "--corner-radius", type=float, default=defaults_scene.corner_radius_m, help="obstacle corner radius [m]"
    )
    p.add_argument(
        "--speed", type=float, default=defaults_scene.speed_m_s, help="end-effector speed v along the path [m/s]"
    )
    add_regression_arguments(p, default_tolerance_m=EndpointConstraint.tolerance_m)
    p.add_argument("--quiet", action="store_true", help="no progress bar or tables")
    return p


def write_pair(first: Path, first_text: str, second: Path, second_text: str) -> tuple[bool, bool]:
    """Write two files atomically as a pair: if the second write fails, the first file is put
    back as it was (or removed if it was new), so doe.json and coefficients.json always match.

    Returns:
        Whether each file replaced an existing one.
    """
    previous = first.read_bytes() if first.is_file() else None
    first_replaced = write_text_atomic(first, first_text)
    try:
        second_replaced = write_text_atomic(second, second_text)
    except BaseException:
        if previous is None:
            first.unlink(missing_ok=True)
        else:
            write_text_atomic(first, previous.decode("utf-8"))
        raise
    return first_replaced, second_replaced


def check_output_folder(folder: Path) -> None:
    """Fail early (before minutes of PSO) if ``folder`` cannot hold the outputs."""
    if folder.exists() and not folder.is_dir():
        raise OutputExistsError(f"--out {folder} exists and is not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputExistsError(f"--out {folder} cannot be created ({exc.strerror})") from None
    if not os.access(folder, os.W_OK):
        raise OutputExistsError(f"--out {folder} is not writable")


def build(args: argparse.Namespace, out=None) -> int:
    """Run the whole offline pipeline for parsed arguments; returns the exit status."""
    out = sys.stdout if out is None else out
    started = time.perf_counter()
    check_output_folder(args.out)
    arm = load_planar_arm(args.urdf)
    scene = Scene(margin_m=args.margin, corner_radius_m=args.corner_radius, speed_m_s=args.speed)
    design = Design(args.levels, tuple(args.L_range), tuple(args.W_range))
    family = family_from_name(args.family)
    constraint = endpoint_constraint(args, family)
    config = SolverConfig(
        family=family,
        fitness=FitnessConfig(
            n_points=args.n_points,
            endpoint_weight=args.endpoint_weight,
            penalty_weight=args.penalty_weight,
            margin_buffer_m=args.margin_buffer,
        ),
        pso=PsoConfig(swarm_size=args.swarm_size, iterations=args.iterations, restarts=args.restarts),
        polish=not args.no_polish,
    )
    # Check every experiment's geometry before spending minutes on PSO.
    for L, W in design.points():
        desired_path(Obstacle.in_scene(L, W, scene), scene, arm.reach_m)

    bar = tqdm(total=len(design.points()), desc="DOE", unit="exp", disable=args.quiet, file=sys.stderr)
    results = run_doe(arm, design, scene, config, args.seed, args.jobs, progress=lambda _: bar.update())
    bar.close()

    provenance = {
        "seed": args.seed,
        "levels": args.levels,
        "family": family.name,
        "urdf": arm.urdf_path.name,
        "urdf_sha256": sha256_file(arm.urdf_path),
        "pso": asdict(config.pso),
        "fitness": config.fitness.to_json(),
        "polish": config.polish,
        "versions": package_versions(),
    }
    document = doe_document(results, design, scene, arm, config, provenance, config.fitness.elbow)
    paper_rows = _paper_rows(arm, scene, config, design)
    if paper_rows is not None:
        for row, paper in zip(document["experiments"], paper_rows, strict=True):
            row["paper_table2"] = {k: paper[k] for k in ("fitness", "clearance_m")}
            row["beats_paper"] = bool(row["fitness"] < paper["fitness"])

    doe_path, coefficients_path = args.out / "doe.json", args.out / "coefficients.json"
    doe_text = dumps(document)
    doe = doe_from_json(json.loads(doe_text), str(doe_path))
    coefficients, _ = fit_coefficients(
        doe,
        {"provenance": {**provenance, "doe_sha256": hashlib.sha256(doe_text.encode()).hexdigest()}},
        constraint,
    )
    doe_replaced, coefficients_replaced = write_pair(
        doe_path, doe_text, coefficients_path, dumps(coefficients.to_json())
    )

    total = time.perf_counter() - started
    timing = {
        "total_s": total,
        "jobs": args.jobs,
        "experiments": [
            {
                "test": i + 1,
                "L": r.length_m,
                "W": r.width_m,
                "seconds": r.seconds,
                "coal_queries": r.coal_queries,
                "objective_evaluations": r.objective_evaluations,
            }
            for i, r in enumerate(results)
        ],
        "coal_queries": int(sum(r.coal_queries for r in results)),
        "objective_evaluations": int(sum(r.objective_evaluations for r in results)),
    }
    write_json_atomic(args.out / "build_timing.json", timing)

    if not args.quiet:
        print("Table 2 (ours, with the paper's row below where the design matches it):", file=out)
        print(report.table2(document["experiments"], paper_rows), file=out)
        paper_eq9 = load_coefficients(PAPER_SOURCE).parameters if family == PAPER else None
        print("\nEq. 9 (ours, paper below):", file=out)
        print(report.equation9(coefficients.parameters, paper_eq9, coefficients.extra["fit"]), file=out)
        print(report.regression_method(coefficients.extra["fit"]), file=out)
        print(
            f"\nTiming: {total:.1f} s total, "
            + ", ".join(f"{r.seconds:.1f}" for r in results)
            + f" s per experiment; {timing['coal_queries']} Coal distance queries, "
            f"{timing['objective_evaluations']} objective evaluations (analytic route)",
            file=out,
        )
    for path, replaced in ((doe_path, doe_replaced), (coefficients_path, coefficients_replaced)):
        print(f"{'replaced' if replaced else 'wrote'} {path}", file=out)
    solvers = sorted({r.solver for r in results})
    print(f"solver: {', '.join(solvers)}", file=out)
    return 0


def _paper_rows(arm, scene: Scene, config: SolverConfig, design: Design) -> list[dict] | None:
    """The paper's Table 2 rows scored on our fitness, if our design is the paper's grid.

    The fitness is a function of the 8 parameters, so the comparison holds for either family."""
    paper = load_doe(paper_data_path("paper_table2_doe.json"))
    points = design.points()
    if len(points) != len(paper.lengths_m) or not np.allclose(points, np.c_[paper.lengths_m, paper.widths_m]):
        return None
    rows = []
    for (L, W), params in zip(points, paper.parameters, strict=True):
        score = score_parameters(arm, L, W, scene, config, params)
        rows.append({"L": L, "W": W, "parameters": dict(zip(PARAMETER_NAMES, params, strict=True)), **score})
    return rows


def main(argv: list[str] | None = None) -> int:
    """Entry point: parse ``argv``, run, print one line per error; returns the exit status."""
    args = parser().parse_args(argv)
    try:
        return build(args)
    except PipelineError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted: outputs are either the previous pair or the new pair, never half-written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
