"""The scene of the paper: where the obstacle stands and how the path is laid around it.

All lengths in metres, speeds in metres per second. Defaults follow the paper and
``shared/paper/NOTES.md`` (y1 = y5 = d, v = 0.2 m/s).
"""

from __future__ import annotations

import difflib
import json
import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path

from pipeline.exceptions import DataFileError
from pipeline.validation import check_finite, check_non_negative, check_positive

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib


@dataclass(frozen=True)
class Scene:
    """Fixed geometry and motion settings shared by every obstacle size.

    Attributes:
        top_y_m: d, the y of the obstacle's far edge [m]; footprint y in [d - W, d].
        start_y_m: y1 = y5, the height of the start and goal points [m]; None means d.
        speed_m_s: v, the end effector's constant speed along the path [m/s].
        margin_m: Safety margin between links and obstacle [m].
        corner_radius_m: Corner radius of the rounded obstacle [m].
        obstacle_height_m: Extent of the obstacle along z, centred on the arm's plane [m].
        start_dx_m: P1.x - L/2 [m] (paper: 0.12).
        approach_dx_m: P2.x - L/2 [m] (paper: 0.03).
        approach_dy_m: (d - W) - P2.y [m] (paper: 0.03).
        apex_dy_m: (d - W) - P3.y [m] (paper: 0.10).
        centre_x_m: x of the obstacle's centre [m] (paper: 0); footprint x in
            [x_c - L/2, x_c + L/2], and P1..P5 keep their offsets from it. Stored only when not 0
            (:data:`OPTIONAL_SCENE_FIELDS`).
    """

    top_y_m: float = 0.56
    start_y_m: float | None = None
    speed_m_s: float = 0.2
    margin_m: float = 0.01
    corner_radius_m: float = 0.01
    obstacle_height_m: float = 1.0
    start_dx_m: float = 0.12
    approach_dx_m: float = 0.03
    approach_dy_m: float = 0.03
    apex_dy_m: float = 0.10
    centre_x_m: float = 0.0

    def __post_init__(self) -> None:
        check_finite("top_y_m", self.top_y_m)
        if self.start_y_m is not None:
            check_finite("start_y_m", self.start_y_m)
        check_positive("speed_m_s", self.speed_m_s)
        check_non_negative("margin_m", self.margin_m)
        check_non_negative("corner_radius_m", self.corner_radius_m)
        check_positive("obstacle_height_m", self.obstacle_height_m)
        check_positive("start_dx_m", self.start_dx_m)
        check_non_negative("approach_dx_m", self.approach_dx_m)
        check_non_negative("approach_dy_m", self.approach_dy_m)
        check_positive("apex_dy_m", self.apex_dy_m)
        check_finite("centre_x_m", self.centre_x_m)

    def with_checked(self, centre_x_m: float | None = None, top_y_m: float | None = None) -> Scene:
        """This scene with the obstacle's centre x and far edge y (d) [m] in place where given (not
        None), without re-running the checks: for callers that have checked them (the online
        generator's moved scene, whose x and d are finite floats). Equal to
        ``dataclasses.replace(self, centre_x_m=..., top_y_m=...)`` with the values given."""
        scene = object.__new__(Scene)
        fields = scene.__dict__
        fields.update(self.__dict__)
        if centre_x_m is not None:
            fields["centre_x_m"] = centre_x_m
        if top_y_m is not None:
            fields["top_y_m"] = top_y_m
        return scene

    @property
    def y1_m(self) -> float:
        """Height of the start and goal points P1, P5 [m] (d unless set)."""
        return self.top_y_m if self.start_y_m is None else self.start_y_m

    def to_dict(self) -> dict[str, float | None]:
        """Plain-JSON form, as stored in coefficients and DOE files: every field, except those of
        :data:`OPTIONAL_SCENE_FIELDS` that are 0 (a scene that does not use them is written as it
        was before they existed, to the byte)."""
        return {k: v for k, v in asdict(self).items() if not (k in OPTIONAL_SCENE_FIELDS and v == 0.0)}

    @classmethod
    def from_dict(cls, data: dict) -> Scene:
        """Inverse of :meth:`to_dict` (a missing optional field is 0); unknown keys are ignored (a
        coefficients file's scene block also holds the arm's data). :func:`read_scene_file` is the
        strict reader."""
        names = {f for f in cls.__dataclass_fields__}
        return cls(**{k: v for k, v in data.items() if k in names})

    def is_close(self, other: Scene) -> bool:
        """True if both scenes agree to 1e-12 in every field."""
        a, b = asdict(self), asdict(other)
        return all(
            (a[k] is None and b[k] is None)
            or (a[k] is not None and b[k] is not None and math.isclose(a[k], b[k], abs_tol=1e-12))
            for k in a
        )


#: Scene fields written into a coefficients file's scene block only when they are not 0.
OPTIONAL_SCENE_FIELDS: tuple[str, ...] = ("centre_x_m",)
#: The scene's other fields: the keys every coefficients file's scene block holds.
SCENE_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(Scene) if f.name not in OPTIONAL_SCENE_FIELDS)
#: The keys of a scene file: every field of the scene.
SCENE_KEYS: tuple[str, ...] = SCENE_FIELDS + OPTIONAL_SCENE_FIELDS
#: Keys of a coefficients file's scene block that come from the arm, not from the scene.
ARM_KEYS: tuple[str, ...] = ("link_lengths_m", "link_radii_m", "elbow")


def read_scene_file(path: str | Path) -> dict[str, float | None]:
    """Scene values from a TOML (``.toml``) or JSON (``.json``) file whose keys are
    :data:`SCENE_KEYS` (e.g. ``top_y_m = 0.54``), lengths in metres, speeds in m/s.

    Only the keys present are returned; the caller fills in the rest (defaults, options).
    ``start_y_m`` may be null in JSON (y1 = d); in TOML leave it out.

    Raises:
        DataFileError: the file is missing, unreadable, neither TOML nor JSON, not a table of
            keys, has an unknown (misspelt) or arm key, or a value that is not a number.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".toml", ".json"):
        raise DataFileError(path, f"a scene file must end in .toml or .json, not {suffix or 'nothing'!r}")
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise DataFileError(path, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(path, f"cannot be read ({exc.__class__.__name__})") from None
    try:
        document = tomllib.loads(text) if suffix == ".toml" else json.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DataFileError(path, f"not valid TOML ({exc})") from None
    except json.JSONDecodeError as exc:
        raise DataFileError(path, f"not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None
    if not isinstance(document, dict):
        raise DataFileError(path, f"expected a table of scene keys, found {type(document).__name__}")
    values: dict[str, float | None] = {}
    for key, value in document.items():
        if key in ARM_KEYS:
            raise DataFileError(path, f"key {key!r} comes from the arm's URDF, not from the scene file; remove it")
        if key not in SCENE_KEYS:
            close = difflib.get_close_matches(key, SCENE_KEYS, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise DataFileError(path, f"unknown key {key!r}{hint}; the scene's keys are {', '.join(SCENE_KEYS)}")
        if value is None and key == "start_y_m":
            values[key] = None
            continue
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise DataFileError(path, f"{key} = {value!r} is not a number")
        values[key] = float(value)
    return values
