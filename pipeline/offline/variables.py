"""The scene variables a regression can vary, and the quadratic basis over them.

A fit maps the values of k scene variables to the family's free parameters with a full
quadratic. The vocabulary, in its canonical order:

====  ==========================  ===================
name  meaning                     field
====  ==========================  ===================
L     obstacle length [m]         the obstacle's L
W     obstacle width [m]          the obstacle's W
x     obstacle centre x [m]       ``Scene.centre_x_m``
d     obstacle far edge y [m]     ``Scene.top_y_m``
====  ==========================  ===================

:class:`Variables` names the variables of one fit, always in that order whatever order they
were given in. Its quadratic basis is 1, v1..vk, then v_i v_j for i <= j in lexicographic order
(1 + k + k (k + 1) / 2 terms): for (L, W) exactly the paper's (1, L, W, L^2, LW, W^2).

A scene variable's value replaces its field of the coefficients' scene for one answer: the
obstacle for (L, W, x) is ``Obstacle.in_scene(L, W, replace(scene, centre_x_m=x))``
(:meth:`Variables.scene_for`).
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from functools import cached_property
from types import MappingProxyType

import numpy as np

from pipeline.exceptions import DataFileError, InvalidParameterError, PipelineError
from pipeline.model.scene import Scene

#: Every variable a fit may vary, in the canonical order: name -> (meaning, Scene field or None).
VOCABULARY: Mapping[str, tuple[str, str | None]] = MappingProxyType(
    {
        "L": ("obstacle length [m]", None),
        "W": ("obstacle width [m]", None),
        "x": ("obstacle centre x, Scene.centre_x_m [m]", "centre_x_m"),
        "d": ("obstacle far edge y, Scene.top_y_m [m]", "top_y_m"),
    }
)
#: The names of :data:`VOCABULARY` in the canonical order.
NAMES: tuple[str, ...] = tuple(VOCABULARY)
#: The obstacle's size, which every coefficients file varies.
SIZE: tuple[str, str] = ("L", "W")


def check_name(name: object, valid: Iterable[str] = NAMES, what: str = "variable") -> str:
    """``name`` if it is one of ``valid``, else a one-line InvalidParameterError naming it, the
    valid names and the closest one."""
    valid = tuple(valid)
    if isinstance(name, str) and name in valid:
        return name
    close = []
    if isinstance(name, str):  # the same letter in the other case first ("X" for "x"), then difflib
        close = [v for v in valid if v.lower() == name.lower()] or difflib.get_close_matches(name, valid, n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise InvalidParameterError(what, name, f"one of {', '.join(valid)}{hint}")


@dataclass(frozen=True)
class Variables:
    """The scene variables of one fit, in the canonical order of :data:`NAMES`.

    ``Variables(("x", "L", "W"))`` is ``Variables(("L", "W", "x"))``.

    Attributes:
        names: The variables' names, canonical order, each once.

    Raises:
        InvalidParameterError: no names, an unknown or misspelt name (the message names it and
            the valid ones, with the closest), or a name given twice.
    """

    names: tuple[str, ...] = SIZE

    def __post_init__(self) -> None:
        given = (self.names,) if isinstance(self.names, str) else tuple(self.names)
        if not given:
            raise InvalidParameterError("variables", self.names, f"at least one of {', '.join(NAMES)}")
        for name in given:
            check_name(name)
        if len(set(given)) != len(given):
            raise InvalidParameterError("variables", given, "each name once")
        object.__setattr__(self, "names", tuple(sorted(given, key=NAMES.index)))

    @classmethod
    def of(cls, names: Variables | Iterable[str] | None) -> Variables:
        """``names`` as Variables (None: (L, W))."""
        if names is None:
            return DEFAULT_VARIABLES
        return names if isinstance(names, Variables) else cls(tuple(names))

    @property
    def k(self) -> int:
        """Number of variables."""
        return len(self.names)

    @property
    def is_size_only(self) -> bool:
        """True for exactly (L, W): the paper's regression."""
        return self.names == SIZE

    @property
    def extra(self) -> tuple[str, ...]:
        """The variables beyond L and W, canonical order."""
        return tuple(name for name in self.names if name not in SIZE)

    def index(self, name: str) -> int:
        """Column of ``name`` in a points array (n, k)."""
        return self.names.index(check_name(name, self.names))

    @cached_property
    def pairs(self) -> tuple[tuple[int, int], ...]:
        """The (i, j), i <= j, of the quadratic terms, lexicographic."""
        return tuple((i, j) for i in range(self.k) for j in range(i, self.k))

    @cached_property
    def basis(self) -> tuple[str, ...]:
        """Names of the basis terms: "1", the variables, then "v^2" or "v*u" (for (L, W) the
        paper's ("1", "L", "W", "L^2", "L*W", "W^2"))."""
        names = self.names
        squares = tuple(f"{names[i]}^2" if i == j else f"{names[i]}*{names[j]}" for i, j in self.pairs)
        return ("1", *names, *squares)

    @property
    def basis_size(self) -> int:
        """1 + k + k (k + 1) / 2."""
        return 1 + self.k + self.k * (self.k + 1) // 2

    def design(self, points: np.ndarray) -> np.ndarray:
        """The basis at ``points`` (..., k): shape (..., basis_size)."""
        return quadratic_design(points, self.k)

    def scene_for(self, scene: Scene, values: Mapping[str, float]) -> Scene:
        """``scene`` with the scene fields of the variables in ``values`` (extra variables by
        name) replaced by their values; ``scene`` itself when there are none."""
        if not values:
            return scene
        return replace(scene, **{VOCABULARY[name][1]: float(value) for name, value in values.items()})

    def values_of(self, scene: Scene) -> dict[str, float]:
        """The extra variables' values read off ``scene`` (an answer's moved scene): name -> value."""
        return {name: float(getattr(scene, VOCABULARY[name][1])) for name in self.extra}

    def take(self, values: Mapping[str, object], what: str = "variable") -> dict[str, object]:
        """The extra variables' values from ``values`` (name -> value or None), in canonical order.

        Raises:
            InvalidParameterError: a variable of these coefficients without a value, or a value
                for one they do not vary (the message names it).
        """
        taken = {}
        for name, value in values.items():
            if value is None:
                continue
            if name not in self.extra:
                varied = ", ".join(self.names)
                raise InvalidParameterError(
                    name, value, f"no value: the coefficients vary {varied} only ({name} is not one of their {what}s)"
                )
            taken[name] = value
        missing = [name for name in self.extra if name not in taken]
        if missing:
            raise InvalidParameterError(
                missing[0], None, f"a value: the coefficients vary {', '.join(self.names)} ({missing[0]}= is required)"
            )
        return {name: taken[name] for name in self.extra}


#: The paper's variables, (L, W).
DEFAULT_VARIABLES = Variables(SIZE)


def variables_in(document: Mapping, source: str) -> Variables:
    """The ``variables`` key of a coefficients or DOE file (absent: (L, W)) as Variables.

    Raises:
        DataFileError: not a list of names, or names that are not a valid set (naming ``source``).
    """
    if "variables" not in document:
        return DEFAULT_VARIABLES
    names = document["variables"]
    if not isinstance(names, list) or not all(isinstance(name, str) for name in names):
        raise DataFileError(source, f"'variables' must be a list of names, found {names!r}")
    try:
        return Variables(tuple(names))
    except PipelineError as exc:
        raise DataFileError(source, f"variables: {exc}") from None


def quadratic_design(points: np.ndarray, k: int | None = None) -> np.ndarray:
    """Rows (1, v1..vk, v_i v_j for i <= j lexicographic) at ``points`` (..., k): (..., 1 + k + k (k + 1) / 2).

    For k = 2 the columns are (1, L, W, L L, L W, W W), the same floats as
    :func:`pipeline.offline.regression.design_matrix`.
    """
    P = np.asarray(points, dtype=float)
    if P.ndim < 1 or (k is not None and P.shape[-1] != k):
        columns = "k" if k is None else k
        raise InvalidParameterError("points", P.shape, f"an array (..., {columns}) of variable values")
    k = P.shape[-1]
    columns = [P[..., i] for i in range(k)]
    squares = [columns[i] * columns[j] for i in range(k) for j in range(i, k)]
    return np.stack([np.ones_like(columns[0]), *columns, *squares], -1)
