"""``python -m pipeline.scene --urdf FILE``: the window of the obstacle's far edge d that an arm
can be built for, the reason at each edge, the value to use and the build command to run.

The command loads the arm, asks :func:`pipeline.build.arm_scene.window_for_build` for the window
over the build's (L, W) range (and x's, with ``--vary x``), checks the recommended value with the
build's own pre-check, and prints the lot. A window narrower than 1 cm is valid but a poor build
(:mod:`pipeline.offline.scene_window`): the range is shrunk for a wider one where one exists.
Exit status: 0 a window was found; 2 bad input, or no d fits (one line naming the constraints
that close the window); 130 interrupted.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from dataclasses import replace
from types import MappingProxyType
from typing import TextIO

from pipeline.build.arm_scene import check_before_work, config_at, window_for_build
from pipeline.build.config import SCENE_OPTIONS, BuildConfig, scene_from_options, vary_name
from pipeline.build.options import BUILD_OPTIONS
from pipeline.cli import EXIT_OK, Parser, run_cli
from pipeline.commands.build import add_option
from pipeline.exceptions import InvalidParameterError
from pipeline.model.arm import load_planar_arm
from pipeline.offline.designs import DEFAULT_RANGES_M

PROG = "python -m pipeline.scene"
#: The build's options this command takes, as the build declares them.
_BUILD_FLAGS = ("--urdf", "--L-range", "--W-range", "--scene", "--start-y", "--margin", "--corner-radius")
_DECLARED = MappingProxyType(
    {
        option.flag: replace(option, details="") if option.flag == "--urdf" else option  # nothing is copied here
        for option in BUILD_OPTIONS
        if option.flag in _BUILD_FLAGS
    }
)
#: Scene options besides --top-y (the value this command finds) that change the window.
_SCENE_FLAGS = MappingProxyType(
    {name: flag for name, flag in SCENE_OPTIONS.items() if name in ("start_y_m", "margin_m", "corner_radius_m")}
)


def parser() -> Parser:
    """The command line's options: the arm, ranges and scene as ``python -m pipeline.build``
    declares them (:data:`pipeline.build.options.BUILD_OPTIONS`), and this command's own."""
    p = Parser(
        prog=PROG,
        description="Find the window of d, the y of the obstacle's far edge (--top-y of python -m pipeline.build), "
        "over which every obstacle of the build's range keeps P1..P5 inside the arm's reach and the arm's poses at "
        "P1 and P5 at least the margin from the obstacle; print the reason at each edge, the recommended d and the "
        "build command.",
        epilog="Exit status: 0 window found, 2 bad input or no d fits (one line naming the constraints), 130 "
        "interrupted.",
    )
    settings = BuildConfig().settings()
    for flag in _BUILD_FLAGS[:3]:
        add_option(p, _DECLARED[flag], settings)
    p.add_argument(
        "--vary",
        nargs="+",
        default=None,
        metavar="x [MIN MAX]",
        help=f"the build varies the obstacle's centre x over [MIN, MAX] [m] too (default range: "
        f"{' '.join(f'{v:g}' for v in DEFAULT_RANGES_M['x'])})",
    )
    for flag in _BUILD_FLAGS[3:]:
        add_option(p, _DECLARED[flag], settings)
    p.add_argument(
        "--end-pose-clearance",
        type=float,
        default=None,
        metavar="M",
        help="clearance the poses at P1 and P5 must keep [m] (default: the margin; 0: only no collision, as the "
        "build's own pre-check)",
    )
    p.add_argument(
        "--no-shrink",
        action="store_true",
        help="when no d fits the range, refuse, and when only a window narrower than 1 cm does, print it with a "
        "caution, rather than shrink the L, then the W range (to at least half) for a window at least 1 cm wide",
    )
    return p


def _vary(item: list[str] | None) -> tuple[tuple[str, float, float], ...]:
    """``--vary x [MIN MAX]`` as the build's ``vary``; () without it.

    Raises:
        InvalidParameterError: a name other than x, or not x MIN MAX with numbers.
    """
    if item is None:
        return ()
    name = vary_name(item[0])
    if name != "x":
        raise InvalidParameterError("--vary", name, "x (d is what this command chooses)")
    if len(item) == 1:
        return (("x", *DEFAULT_RANGES_M["x"]),)
    try:
        low, high = (float(text) for text in item[1:])
    except ValueError:
        raise InvalidParameterError("--vary x", " ".join(item[1:]), "MIN MAX [m]") from None
    return (("x", low, high),)


def build_command(args: argparse.Namespace, config: BuildConfig) -> str:
    """The ``python -m pipeline.build`` line for ``config`` (the chosen d and range) and the
    scene options given here."""
    words = ["python", "-m", "pipeline.build", "--urdf", str(args.urdf), "--top-y", f"{config.scene.top_y_m:.3f}"]
    default = BuildConfig().design
    for flag, value, default_value in (
        ("--L-range", config.design.length_range_m, default.length_range_m),
        ("--W-range", config.design.width_range_m, default.width_range_m),
    ):
        if tuple(value) != tuple(default_value):
            words += [flag, *(f"{v:g}" for v in value)]
    for factor in config.design.vary:
        words += ["--vary", factor.name, *(f"{v:g}" for v in factor.range_m)]
    if args.scene is not None:
        words += ["--scene", str(args.scene)]
    for name, flag in _SCENE_FLAGS.items():
        if getattr(args, name) is not None:
            words += [flag, f"{getattr(args, name):g}"]
    return shlex.join(words)


def run(args: argparse.Namespace, out: TextIO | None = None) -> int:
    """Find and print the window for parsed options; returns the exit status.

    Raises:
        PipelineError: bad input, or no d fits (``main`` prints it as one line).
    """
    out = sys.stdout if out is None else out
    scene = scene_from_options(args.scene, **{name: getattr(args, name) for name in _SCENE_FLAGS})
    config = BuildConfig.from_settings(
        length_range_m=tuple(args.L_range),
        width_range_m=tuple(args.W_range),
        vary=_vary(args.vary),
        urdf_path=args.urdf,
        scene=scene,
        jobs=1,
    )
    if args.end_pose_clearance is not None and not args.end_pose_clearance >= 0.0:
        raise InvalidParameterError("--end-pose-clearance", args.end_pose_clearance, "a clearance >= 0 [m]")
    arm = load_planar_arm(config.urdf_path)
    window = window_for_build(arm, config, shrink=not args.no_shrink, end_pose_clearance_m=args.end_pose_clearance)
    chosen = config_at(config, window)
    check_before_work(chosen, arm)
    (low, high), (l1, l2) = arm.reach_m, arm.link_lengths_m
    print(f"arm: {args.urdf} (l1 = {l1:.3f} m, l2 = {l2:.3f} m, reach [{low:.4f}, {high:.4f}] m)", file=out)
    print("\n".join(window.lines()), file=out)
    print(f"the build's pre-checks pass at d = {window.recommended_m:.3f} m", file=out)
    print(f"build: {build_command(args, chosen)}", file=out)
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Entry point: parse ``argv``, run, one line per usage error; returns the exit status."""
    return run_cli(parser(), run, argv)


if __name__ == "__main__":
    sys.exit(main())
