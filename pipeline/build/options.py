"""Every setting of a build, declared once: :data:`BUILD_OPTIONS`.

Each :class:`Option` names a setting (a field of :class:`pipeline.build.config.BuildConfig`, of
one of its sections, or of the scene), its command-line flag, unit and help text, and how
argparse reads it. From this one table come

* :data:`OPTIONS` and :data:`SCENE_OPTIONS`, the flag of each setting, which the errors of
  :class:`~pipeline.build.config.BuildConfig` and :func:`scene_from_options` name;
* :meth:`pipeline.build.config.BuildConfig.from_settings`, which places each setting in its
  section;
* the parser of ``python -m pipeline.build`` and its conversion of parsed options into a
  ``BuildConfig`` (:mod:`pipeline.commands.build`), whose defaults are the dataclasses'.

Adding a setting: its dataclass field (with its default and its check) and one :class:`Option`.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

from pipeline.certify.region_map import DEFAULT_MAP_NAME
from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.model.scene import SCENE_FIELDS, Scene, read_scene_file
from pipeline.motion.families import FAMILY_NAMES
from pipeline.offline.designs import DEFAULT_RANGES_M, DESIGN_KINDS
from pipeline.offline.variables import NAMES, SIZE, check_name

__all__ = [
    "BUILD_OPTIONS",
    "GROUPS",
    "OPTIONS",
    "SCENE_OPTIONS",
    "SCENE_SECTION",
    "SETTINGS",
    "VARY_NAMES",
    "Option",
    "scene_from_options",
    "vary_item",
    "vary_name",
]

#: The section of the options that set a field of the scene (through :func:`scene_from_options`).
SCENE_SECTION = "scene"


@dataclass(frozen=True)
class Option:
    """One setting of a build and its command-line option.

    Attributes:
        flag: The option, e.g. ``--swarm-size``.
        name: The setting's name, as :meth:`BuildConfig.from_settings
            <pipeline.build.config.BuildConfig.from_settings>` takes it and :data:`OPTIONS`
            maps it ("" for an option that sets no field by itself, such as ``--plain``).
        section: Where the field is: "" for :class:`~pipeline.build.config.BuildConfig` itself,
            the name of its section attribute (``design``, ``optimiser``, ...), or
            :data:`SCENE_SECTION` for a field of :class:`pipeline.model.scene.Scene`.
        field: The field's name in its section (default: ``name``).
        help: What the setting is; the help text is ``help [unit]; details (default: ...)``.
        unit: Its unit ("m", "s", "count", ...), "" for a path, a name or a switch.
        details: Text after the unit.
        default_text: The default as the help states it; "": argparse's default, when it is a value.
        kind: How argparse reads one value: "int", "float", "text", "path", "count" (an integer
            >= 0), "jobs" (a count, 0: every CPU), "timeout" (a finite time > 0 [s]) or
            "positive" (a finite value > 0).
        nargs, action, metavar: As argparse's; ``action`` "store_true" makes a switch.
        choices: The accepted values, or None.
        cli_default: The default argparse gets; ``...``: the field's default, in its
            command-line form (a list for a tuple, a name for a family or a design kind).
        dest: The parsed options' attribute (default: argparse's, from the flag).
        read: The setting's value from the parsed options; None: the option's own value.
        group: The help's group ("" for none); default: ``section``.
    """

    flag: str
    name: str
    section: str = ""
    field: str = ""
    help: str = ""
    unit: str = ""
    details: str = ""
    default_text: str = ""
    kind: str = "text"
    nargs: int | str | None = None
    action: str | None = None
    metavar: str | tuple[str, ...] | None = None
    choices: tuple[str, ...] | None = None
    cli_default: Any = ...
    dest: str = ""
    read: Callable[[argparse.Namespace], Any] | None = None
    group: str | None = None

    @property
    def attribute(self) -> str:
        """The field's name in its section."""
        return self.field or self.name

    @property
    def is_setting(self) -> bool:
        """True for a setting of :class:`~pipeline.build.config.BuildConfig` (itself or a section)."""
        return bool(self.name) and self.section != SCENE_SECTION

    @property
    def destination(self) -> str:
        """The parsed options' attribute that holds this option."""
        return self.dest or self.flag.lstrip("-").replace("-", "_")

    @property
    def help_group(self) -> str:
        """The help's group of this option ("" for the ungrouped options)."""
        return self.section if self.group is None else self.group

    def help_text(self) -> str:
        """``help [unit]; details (default: default_text)``, each part where given."""
        text = self.help + (f" [{self.unit}]" if self.unit else "") + (f"; {self.details}" if self.details else "")
        return text + (f" (default: {self.default_text})" if self.default_text else "")

    def value(self, args: argparse.Namespace) -> Any:
        """The setting's value in parsed options."""
        return getattr(args, self.destination) if self.read is None else self.read(args)


#: The variables ``--vary`` takes (L and W have --L-range and --W-range).
VARY_NAMES: tuple[str, ...] = tuple(name for name in NAMES if name not in SIZE)
# Other spellings of the variables -> the name (the scene fields they set, other cases).
_ALIASES = MappingProxyType({"X": "x", "D": "d", "centre_x_m": "x", "center_x_m": "x", "top_y_m": "d"})


def _switched_off(dest: str) -> Callable[[argparse.Namespace], bool]:
    """The reader of a setting that a ``--no-...`` switch turns off."""
    return lambda args: not getattr(args, dest)


def _read_vary(args: argparse.Namespace) -> tuple[tuple[str, float, float], ...]:
    return tuple(vary_item(item) for item in args.vary)


def _read_tolerance(args: argparse.Namespace) -> float | None:
    return None if args.plain else args.endpoint_tolerance


def _read_scene(args: argparse.Namespace) -> Scene:
    values = {option.name: getattr(args, option.destination) for option in _SCENE_FIELD_OPTIONS}
    return scene_from_options(args.scene, **values)


_DEFAULT_RANGES = ", ".join(f"{name}: {lo:g} {hi:g}" for name, (lo, hi) in DEFAULT_RANGES_M.items())
_CONVERGENCE = (
    "the build exits 1 and writes nothing if a DOE optimum's dense Coal clearance is below the margin (for "
    "exact-endpoints: below the margin or its end poses' clearance, whichever is smaller), if a DOE optimum "
    "misses P1 or P5 by more than --max-doe-endpoint-error, or if the endpoint-constrained regression misses "
    "--endpoint-tolerance on its grid"
)
_SCENE = (
    "the scene is the defaults below, then the keys of --scene FILE, then these options; it is stored in "
    "coefficients.json and every later step reads it from there"
)

#: The help's groups: section -> (title, description).
GROUPS: Mapping[str, tuple[str, str | None]] = MappingProxyType(
    {
        "design": ("design of experiments", None),
        "execution": ("where it runs", "the files do not depend on these"),
        SCENE_SECTION: ("scene", _SCENE),
        "optimiser": ("optimiser", "the PSO per experiment and its objective (Eq. 5 with the clearance penalty)"),
        "regression": ("regression and convergence", _CONVERGENCE),
        "range_map": ("range map", None),
    }
)


def _scene_option(flag: str, name: str, text: str, unit: str) -> Option:
    """The option of a scene field: no default of its own, so that the scene file's holds."""
    default = getattr(Scene(), name)
    return Option(
        flag,
        name,
        SCENE_SECTION,
        help=text,
        unit=unit,
        default_text="d" if default is None else f"{default}, or the scene file's",
        kind="float",
        metavar="V" if unit == "m/s" else "M",
        cli_default=None,
        dest=name,
    )


_OUTPUT_FILES = "doe.json, coefficients.json, region_map.json and .npy, build_timing.json"

#: Every option of ``python -m pipeline.build`` but --quiet and --no-progress, in the help's order.
BUILD_OPTIONS: tuple[Option, ...] = (
    Option(
        "--out",
        "out_folder",
        help="output folder",
        kind="path",
        details=f"{_OUTPUT_FILES}; arm.urdf for a --urdf other than the shipped arm",
    ),
    Option(
        "--seed",
        "seed",
        help="master random seed",
        unit="integer >= 0",
        kind="int",
        details="the same seed, the same files",
    ),
    Option("--family", "family", help="trajectory family", choices=FAMILY_NAMES),
    Option(
        "--urdf",
        "urdf_path",
        help="URDF of the arm",
        kind="path",
        details="another URDF is copied beside the coefficients as arm.urdf, and later commands use it from there",
        default_text="the paper's arm, shipped with the package",
    ),
    Option(
        "--acceleration-limit",
        "acceleration_limits_rad_s2",
        help="the arm's joint acceleration limits",
        unit="rad/s^2",
        details="URDF carries none; recorded in the coefficients; python -m pipeline.generate and "
        "generate_certified hold answers to them",
        default_text="none",
        kind="positive",
        nargs=2,
        metavar=("A1", "A2"),
    ),
    Option(
        "--levels",
        "levels",
        "design",
        help="levels per factor of the full-factorial design",
        unit="count",
        details="K^k runs: K x K over (L, W), K >= 3",
        kind="int",
    ),
    Option(
        "--L-range", "length_range_m", "design", help="L range", unit="m", kind="float", nargs=2, metavar=("MIN", "MAX")
    ),
    Option(
        "--W-range", "width_range_m", "design", help="W range", unit="m", kind="float", nargs=2, metavar=("MIN", "MAX")
    ),
    Option(
        "--vary",
        "vary",
        "design",
        help="vary a scene variable beside L and W over [MIN, MAX]",
        unit="m",
        details=f"repeatable: {', '.join(VARY_NAMES)} (x: the obstacle's centre x, d: its far edge y, default "
        f"--top-y); a NAME alone takes its default range ({_DEFAULT_RANGES}; |x| < 0.06 m keeps P1..P5 of every "
        "corner of the default (L, W) range in reach; d: the arm's window of d over the range, where every "
        "obstacle is in reach and its end poses keep the margin, python -m pipeline.scene). The coefficients "
        "then vary these too (python -m "
        "pipeline.generate --x); the region map covers them (d only with y1 = d, i.e. without --start-y; "
        "otherwise none is written)",
        nargs="+",
        action="append",
        metavar="NAME [MIN MAX]",
        read=_read_vary,
    ),
    Option(
        "--design",
        "design_kind",
        "design",
        field="kind",
        help="the DOE",
        details="full-factorial (--levels per factor, the paper's 3 x 3 over (L, W)), box-behnken (3 or more "
        "factors: 2k(k-1)+1 runs) or central-composite (face-centred, 2^k+2k+1 runs); the last two from pyDOE, "
        "with one centre run",
        choices=tuple(DESIGN_KINDS),
    ),
    Option(
        "--jobs",
        "jobs",
        "execution",
        help="worker processes",
        unit="count",
        details="0 = every CPU",
        kind="jobs",
        cli_default="0",
    ),
    Option(
        "--scheduler",
        "scheduler",
        "execution",
        help="Dask scheduler address (tcp://host:port)",
        default_text="a local process pool of --jobs workers",
        metavar="ADDRESS",
    ),
    Option(
        "--worker-timeout",
        "worker_timeout_s",
        "execution",
        help="with --scheduler: how long to wait for its first worker before any work",
        unit="s",
        details="none by then is refused",
        kind="timeout",
        metavar="SECONDS",
    ),
    Option(
        "--scene",
        "scene",
        group=SCENE_SECTION,
        help="scene file, TOML (.toml) or JSON (.json), whose keys are the scene's fields as stored in "
        f"coefficients.json ({', '.join(SCENE_FIELDS)})",
        details="e.g. top_y_m = 0.54; an unknown key is refused",
        kind="path",
        metavar="FILE",
        cli_default=None,
        read=_read_scene,
    ),
    _scene_option("--top-y", "top_y_m", "d, the y of the obstacle's far edge", "m"),
    _scene_option("--start-y", "start_y_m", "y1 = y5, the height of the start and goal points", "m"),
    _scene_option("--speed", "speed_m_s", "end-effector speed v along the path", "m/s"),
    _scene_option("--margin", "margin_m", "safety margin between links and obstacle", "m"),
    _scene_option("--corner-radius", "corner_radius_m", "obstacle corner radius", "m"),
    Option("--swarm-size", "swarm_size", "optimiser", help="PSO particles per swarm", unit="count", kind="int"),
    Option("--iterations", "iterations", "optimiser", help="PSO iterations per restart", unit="count", kind="int"),
    Option(
        "--restarts",
        "restarts",
        "optimiser",
        help="independent PSO swarms",
        unit="count",
        details="each polished",
        kind="int",
    ),
    Option(
        "--no-polish",
        "polish",
        "optimiser",
        help="skip the least_squares polish after PSO",
        action="store_true",
        read=_switched_off("no_polish"),
    ),
    Option(
        "--n-points",
        "n_points",
        "optimiser",
        help="path points n of Eq. 5",
        unit="count",
        details="uniform in x",
        kind="int",
    ),
    Option(
        "--endpoint-weight",
        "endpoint_weight",
        "optimiser",
        help="weight of the first and last 3 path points in Eq. 5",
        unit="-",
        kind="float",
    ),
    Option(
        "--penalty-weight",
        "penalty_weight",
        "optimiser",
        help="clearance penalty weight",
        unit="1/m^2 relative to Eq. 5's m^2",
        kind="float",
    ),
    Option(
        "--margin-buffer",
        "margin_buffer_m",
        "optimiser",
        help="extra clearance the optimiser aims for beyond the margin",
        unit="m",
        kind="float",
        metavar="M",
    ),
    Option(
        "--endpoint-tolerance",
        "endpoint_tolerance_m",
        "regression",
        help="paper family: hold the regressed trajectory's endpoint errors within this over the fitted range",
        unit="m",
        kind="float",
        metavar="M",
        read=_read_tolerance,
    ),
    Option(
        "--plain",
        "",
        group="regression",
        help="plain least squares per parameter, as the paper's Eq. 9 (no endpoint constraint)",
        action="store_true",
    ),
    Option(
        "--max-doe-endpoint-error",
        "doe_endpoint_error_max_m",
        "regression",
        help="largest endpoint error of a DOE optimum",
        unit="m",
        details="the default build's optima: up to 6.1 mm, with top_y_m = 0.54: 27 mm, after a 2-iteration PSO: "
        "168 mm (the regression's own limit is --endpoint-tolerance)",
        kind="float",
        metavar="M",
    ),
    Option(
        "--allow-unconverged",
        "allow_unconverged",
        "regression",
        help='write the files anyway, marked "converged": false with the reasons; loading them warns',
        action="store_true",
    ),
    Option(
        "--clearance-rounds",
        "clearance_rounds",
        "regression",
        help="paper family with the endpoint constraint: rounds of the certifiable regression before the map "
        "(certify, constrain the worst point of every cell below the margin that is not proven infeasible, "
        "refit); 0: none",
        unit="count",
        kind="count",
        metavar="N",
    ),
    Option(
        "--no-range-map",
        "range_map",
        "range_map",
        field="enabled",
        help="do not certify the coefficients over their fitted range (by default "
        f"{DEFAULT_MAP_NAME} is written beside them, linked by their sha256; see python -m pipeline.certify_range)",
        action="store_true",
        read=_switched_off("no_range_map"),
    ),
    Option(
        "--near-optimal-cells",
        "near_optimal_cells",
        "range_map",
        help="cells per axis of the map's certified near-optimal timings (one timing per cell, read at lookup "
        "cost); 0: none",
        unit="count",
        default_text="64 over (L, W), 16 over three axes, 8 over four",
        kind="count",
        metavar="N",
    ),
)

#: The options that set a build's setting, by the setting's name.
SETTINGS: Mapping[str, Option] = MappingProxyType(
    {option.name: option for option in BUILD_OPTIONS if option.is_setting}
)
#: Command-line option of each :class:`~pipeline.build.config.BuildConfig` setting, named in error messages.
OPTIONS: Mapping[str, str] = MappingProxyType({name: option.flag for name, option in SETTINGS.items()})
_SCENE_FIELD_OPTIONS = tuple(option for option in BUILD_OPTIONS if option.section == SCENE_SECTION)
#: Command-line option of each scene field that has one; the others are set by ``--scene FILE``.
SCENE_OPTIONS: Mapping[str, str] = MappingProxyType({option.name: option.flag for option in _SCENE_FIELD_OPTIONS})


def vary_name(name: object) -> str:
    """A ``--vary`` name, or a one-line error naming the valid ones and the closest."""
    if name in SIZE:
        flag = OPTIONS["length_range_m" if name == "L" else "width_range_m"]
        raise InvalidParameterError(OPTIONS["vary"], name, f"one of {', '.join(VARY_NAMES)} ({name}'s range is {flag})")
    if isinstance(name, str) and name not in VARY_NAMES and name in _ALIASES:
        raise InvalidParameterError(
            OPTIONS["vary"], name, f"one of {', '.join(VARY_NAMES)} (did you mean {_ALIASES[name]!r}?)"
        )
    return check_name(name, VARY_NAMES, OPTIONS["vary"])


def vary_item(item: list[str]) -> tuple[str, float, float]:
    """One ``--vary NAME [MIN MAX]`` as (name, min, max) [m]; a NAME alone takes its default range.

    Raises:
        InvalidParameterError: not NAME or NAME MIN MAX, a bad name (with the closest valid one),
            no default range for NAME, or a bound that is not a number.
    """
    option = OPTIONS["vary"]
    if len(item) not in (1, 3):
        raise InvalidParameterError(option, " ".join(item), "NAME MIN MAX, or NAME alone for its default range")
    name = vary_name(item[0])
    if len(item) == 1:
        if name not in DEFAULT_RANGES_M:
            raise InvalidParameterError(option, name, f"NAME MIN MAX ({name} has no default range)")
        return (name, *DEFAULT_RANGES_M[name])
    bounds = []
    for text in item[1:]:
        try:
            bounds.append(float(text))
        except ValueError:
            raise InvalidParameterError(f"{option} {name}", text, "a number [m]") from None
    return (name, bounds[0], bounds[1])


def scene_from_options(scene_file: str | Path | None = None, **options: float | None) -> Scene:
    """The scene of a build: the defaults, then the keys of ``scene_file`` (TOML or JSON, keys
    as :data:`pipeline.model.scene.SCENE_FIELDS`), then the ``options`` that are not None
    (scene field name -> value, e.g. ``top_y_m=0.54``). Errors name the option or the file's key.

    Raises:
        DataFileError: the scene file is unreadable or has an unknown key or a non-number.
        InvalidParameterError: a value is out of its domain.
    """
    values: dict[str, float | None] = {}
    origin: dict[str, str] = {}
    if scene_file is not None:
        try:
            values.update(read_scene_file(scene_file))
        except DataFileError as exc:
            raise DataFileError(f"--scene {exc.path}", exc.reason) from None
        origin.update({key: f"--scene {scene_file}: {key}" for key in values})
    for key, value in options.items():
        if key not in SCENE_OPTIONS:
            raise InvalidParameterError("scene option", key, f"one of {', '.join(SCENE_OPTIONS)}")
        if value is not None:
            values[key], origin[key] = value, SCENE_OPTIONS[key]
    try:
        return Scene(**values)
    except InvalidParameterError as exc:
        raise InvalidParameterError(origin.get(exc.name, exc.name), exc.value, exc.expected) from None
