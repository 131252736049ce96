"""Shared fixtures of the test suite. Keep this small: put module-specific fixtures in the module."""

from __future__ import annotations

import importlib.metadata
import importlib.util
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pytest

from pipeline.model.arm import DEFAULT_URDF, PlanarArm, load_planar_arm
from pipeline.model.scene import Scene

_DOUBLE_PENDULUM = Path(
    "cmeel.prefix/share/example-robot-data/robots/double_pendulum_description/urdf/double_pendulum_simple.urdf"
)


def _example_robot_data_file(relative: Path) -> Path:
    """A file shipped by the installed example-robot-data distribution (it has no Python module)."""
    candidates = [Path(importlib.metadata.distribution("example-robot-data").locate_file(relative))]
    # Fallback: the cmeel prefix sits next to the ``cmeel`` package in site-packages.
    spec = importlib.util.find_spec("cmeel")
    if spec is not None and spec.origin is not None:
        candidates.append(Path(spec.origin).resolve().parent.parent / relative)
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise FileNotFoundError(f"example-robot-data file not found: {relative} (tried {candidates})")


@pytest.fixture(scope="session")
def arm() -> PlanarArm:
    """The paper's arm from the shipped URDF (l1 = 0.30 m, l2 = 0.35 m).

    Shared by the whole session: treat it as read-only.
    """
    return load_planar_arm()


@pytest.fixture(scope="session")
def double_pendulum_urdf() -> Path:
    """example-robot-data's double_pendulum_simple.urdf (links of 0.1 m and 0.2 m, box geometry)."""
    return _example_robot_data_file(_DOUBLE_PENDULUM)


@pytest.fixture(scope="session")
def ur5_urdf() -> Path:
    """example-robot-data's ur5_robot.urdf: a 6-joint spatial arm whose meshes are not resolvable here."""
    return _example_robot_data_file(
        Path("cmeel.prefix/share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    )


@pytest.fixture(scope="session")
def scene() -> Scene:
    """The paper's scene with the defaults of NOTES.md (d = 0.56, y1 = d, v = 0.2 m/s)."""
    return Scene()


# Table 2 of the paper: A1, w1, phi1, gamma1, A2, w2, phi2, gamma2, L, W for Test 1..9.
_TABLE2 = (
    (-0.816, 0.953, 0.378, 1.068, 1.633, 0.768, 0.131, 0.445, 0.30, 0.12),
    (-0.768, 0.999, 0.389, 1.053, 1.474, 0.836, 0.103, 0.586, 0.25, 0.12),
    (-0.736, 1.034, 0.408, 1.057, 1.362, 0.903, 0.090, 0.681, 0.20, 0.12),
    (-0.795, 0.971, 0.440, 1.106, 1.497, 0.820, 0.106, 0.500, 0.30, 0.10),
    (-0.781, 0.996, 0.467, 1.116, 1.449, 0.864, 0.131, 0.543, 0.25, 0.10),
    (-0.766, 1.017, 0.500, 1.135, 1.389, 0.914, 0.152, 0.587, 0.20, 0.10),
    (-0.801, 0.970, 0.504, 1.165, 1.522, 0.827, 0.158, 0.401, 0.30, 0.08),
    (-0.786, 0.992, 0.549, 1.178, 1.397, 0.895, 0.153, 0.514, 0.25, 0.08),
    (-0.797, 0.993, 0.602, 1.222, 1.323, 0.955, 0.167, 0.574, 0.20, 0.08),
)


# Eq. 9 of the paper, typed from the paper: name -> coefficients of 1, L, W, L^2, L W, W^2.
_EQ9 = {
    "A1": (-1.475, 2.963, 6.987, -2.869, -19.07, -8.39),
    "w1": (0.4736, 2.15, 6.109, -2.338, -14.8, -10.74),
    "phi1": (1.6, -3.08, -9.415, 1.539, 16.82, 6.086),
    "gamma1": (2.286, -3.97, -9.70, 4.052, 16.95, 11.19),
    "A2": (1.734, -2.731, -5.85, 5.735, 17.88, 16.36),
    "w2": (1.208, -0.9549, -0.04626, -0.1239, -1.739, -4.679),
    "phi2": (0.801, -2.273, -6.41, 1.942, 12.59, 9.89),
    "gamma2": (-0.2707, 3.232, 10.7, -6.575, -15.95, -24.3),
}


@pytest.fixture(scope="session")
def paper_eq9() -> MappingProxyType:
    """Eq. 9 of the paper as typed from it (independent of the shipped data file), read-only:
    name -> (b0..b5) on the basis 1, L, W, L^2, L W, W^2, in the paper's parameter order."""
    return MappingProxyType(_EQ9)


@pytest.fixture(scope="session")
def table2() -> np.ndarray:
    """Table 2 of the paper, shape (9, 10): the 8 parameters (PARAMETER_NAMES order), then L, W [m].

    Row i is Test i + 1. Read-only.
    """
    table = np.array(_TABLE2)
    table.setflags(write=False)
    return table


@pytest.fixture(scope="session")
def over_x():
    """The function lifting (L, W) coefficients to (L, W, x) (:func:`_coefficients_over_x`)."""
    return _coefficients_over_x


def _coefficients_over_x(
    coefficients, x_range_m: tuple[float, float] = (-0.03, 0.03), seed: int = 1, scale: float = 0.1
):
    """``coefficients`` (over (L, W)) lifted to (L, W, x): the same (L, W) terms (at positions 0,
    1, 2, 4, 5, 7 of the (L, W, x) basis) and random x terms of size ``scale`` (zero: the same
    trajectories for every x, moved obstacle aside)."""
    from dataclasses import replace

    from pipeline.offline.variables import Variables

    lwx = Variables(("L", "W", "x"))
    rng = np.random.default_rng(seed)
    parameters = {}
    for name, b in coefficients.parameters.items():
        lifted = np.zeros(lwx.basis_size)
        lifted[[0, 1, 2, 4, 5, 7]] = b
        lifted[[3, 6, 8, 9]] = rng.normal(0.0, scale, 4)
        parameters[name] = tuple(float(v) for v in lifted)
    return replace(
        coefficients,
        parameters=parameters,
        fitted_range_m={**coefficients.fitted_range_m, "x": tuple(x_range_m)},
        variables=lwx,
        source="",
        source_sha256="",
        region_map=None,
    )


@pytest.fixture(scope="session")
def over_xd():
    """The function lifting (L, W) coefficients to (L, W, x, d) (:func:`_coefficients_over_xd`)."""
    return _coefficients_over_xd


def _coefficients_over_xd(
    coefficients,
    x_range_m: tuple[float, float] = (-0.03, 0.03),
    d_range_m: tuple[float, float] = (0.55, 0.57),
    seed: int = 1,
    scale: float = 0.1,
    d_scale: float = 1.0,
):
    """``coefficients`` (over (L, W)) lifted to (L, W, x, d): at d = d0 (the scene's ``top_y_m``)
    the parameters are those of ``_coefficients_over_x(coefficients, x_range_m, seed, scale)``, and
    each parameter gains random terms u, L u, W u, x u, u^2 in u = d - d0 of size ``d_scale``,
    written out in the (L, W, x, d) basis (zero: the same trajectories for every d, moved obstacle
    and end points aside)."""
    from dataclasses import replace

    from pipeline.offline.variables import Variables

    lwx = _coefficients_over_x(coefficients, x_range_m, seed, scale)
    basis = Variables(("L", "W", "x", "d")).basis
    position = {term: i for i, term in enumerate(basis)}
    d0 = float(coefficients.scene.top_y_m)
    rng = np.random.default_rng(seed + 1000)
    parameters = {}
    for name, b in lwx.parameters.items():
        lifted = np.zeros(len(basis))
        for term, value in zip(lwx.variables.basis, b, strict=True):
            lifted[position[term]] = value
        c_u, c_lu, c_wu, c_xu, c_uu = rng.normal(0.0, d_scale, 5)
        # c_u u + c_Lu L u + c_Wu W u + c_xu x u + c_uu u^2 with u = d - d0, expanded.
        lifted[position["1"]] += -c_u * d0 + c_uu * d0 * d0
        lifted[position["d"]] += c_u - 2.0 * c_uu * d0
        lifted[position["d^2"]] += c_uu
        for variable, c in (("L", c_lu), ("W", c_wu), ("x", c_xu)):
            lifted[position[f"{variable}*d"]] += c
            lifted[position[variable]] += -c * d0
        parameters[name] = tuple(float(v) for v in lifted)
    return replace(
        lwx,
        parameters=parameters,
        fitted_range_m={**lwx.fitted_range_m, "d": tuple(d_range_m)},
        variables=Variables(("L", "W", "x", "d")),
    )


_UNIT_ROUNDOFF = 2.0**-53


def _gamma(n: int) -> float:
    """gamma_n = n u / (1 - n u): the relative error bound of an n-term sum of products."""
    return n * _UNIT_ROUNDOFF / (1.0 - n * _UNIT_ROUNDOFF)


class RoundingBounds:
    """How far the online generator's compiled core may differ from the NumPy route (the derivation
    is in ``pipeline.online.kernel``): the regression's columns and T, recomputed here from their
    inputs with NumPy."""

    @staticmethod
    def regression(coefficients, length_m: float, width_m: float, **values: float) -> np.ndarray:
        """(free parameters by the NumPy route, bound on |compiled - NumPy| of each) at one point."""
        from pipeline.offline.variables import quadratic_design

        extra = coefficients.variables.take(values)
        point = np.array([[length_m, width_m, *extra.values()]])
        basis = quadratic_design(point, None)[0]
        matrix = np.array([coefficients.parameters[name] for name in coefficients.family.free_parameter_names])
        reference = coefficients.predict_free(length_m, width_m, **values)
        return reference, 2.0 * _gamma(basis.size + 1) * (np.abs(matrix) @ np.abs(basis))

    @staticmethod
    def duration(scene, length_m: float, width_m: float, centre_x_m: float = 0.0) -> tuple[float, float]:
        """(T [s] by the NumPy route, bound on |compiled - NumPy| [s]) for the even quartic's closed form."""
        from pipeline.motion.path import (
            LENGTH_RULE_POWERS,
            LENGTH_RULE_WEIGHTS,
            symmetric_quartic,
            symmetric_quartic_length_m,
        )

        bottom = scene.top_y_m - width_m
        x1, x2 = length_m / 2.0 + scene.start_dx_m, length_m / 2.0 + scene.approach_dx_m
        c4, c2, _ = symmetric_quartic(x1, scene.y1_m, x2, bottom - scene.approach_dy_m, bottom - scene.apex_dy_m)
        duration = symmetric_quartic_length_m(x1, c4, c2) / scene.speed_m_s
        k1, k3 = 2.0 * c2 * x1, 4.0 * c4 * x1**3
        signed = np.array([1.0, k1 * k1, 2.0 * k1 * k3, k3 * k3]) @ LENGTH_RULE_POWERS
        absolute = np.array([1.0, k1 * k1, abs(2.0 * k1 * k3), k3 * k3]) @ LENGTH_RULE_POWERS
        ratio = float(np.max(absolute / signed))
        bound = 2.0 * (_gamma(5) * ratio + _gamma(LENGTH_RULE_WEIGHTS.size + 2)) * duration * (1.0 + _gamma(8))
        return duration, bound


@pytest.fixture(scope="session")
def rounding() -> type[RoundingBounds]:
    """The bounds within which the compiled online core equals the NumPy route (``pipeline.online.kernel``)."""
    return RoundingBounds


@pytest.fixture(scope="session")
def urdf_with_links():
    """The function writing the shipped URDF with other link lengths (:func:`_urdf_with_links`)."""
    return _urdf_with_links


def _urdf_with_links(folder: Path, l1: float, l2: float) -> Path:
    """The shipped URDF with link lengths l1, l2 [m]: joint origins, link geometry and inertial
    origins, and the rod inertias m l^2 / 12 (0.5 kg links)."""
    text = DEFAULT_URDF.read_text(encoding="utf-8")
    # Through placeholders, so that a new length equal to an old one is not replaced twice.
    fields = {
        '<origin xyz="0.15 0 0"': f'<origin xyz="{l1 / 2:g} 0 0"',
        '<origin xyz="0.175 0 0"': f'<origin xyz="{l2 / 2:g} 0 0"',
        'length="0.30"': f'length="{l1:g}"',
        'length="0.35"': f'length="{l2:g}"',
        '<origin xyz="0.30 0 0"': f'<origin xyz="{l1:g} 0 0"',
        '<origin xyz="0.35 0 0"': f'<origin xyz="{l2:g} 0 0"',
        'iyy="3.75e-3" iyz="0" izz="3.75e-3"': f'iyy="{0.5 * l1 * l1 / 12:.6g}" iyz="0" izz="{0.5 * l1 * l1 / 12:.6g}"',
        'iyy="5.1e-3" iyz="0" izz="5.1e-3"': f'iyy="{0.5 * l2 * l2 / 12:.6g}" iyz="0" izz="{0.5 * l2 * l2 / 12:.6g}"',
    }
    for index, old in enumerate(fields):
        assert text.count(old) >= 1, old
        text = text.replace(old, f"@{index}@")
    for index, new in enumerate(fields.values()):
        text = text.replace(f"@{index}@", new)
    path = folder / f"arm_{round(l1 * 100):03d}_{round(l2 * 100):03d}.urdf"
    path.write_text(text, encoding="utf-8")
    return path
