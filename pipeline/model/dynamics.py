"""The arm's inverse dynamics in closed form, identified from Pinocchio, and its limits.

**Why a closed form.** Certifying torque limits over continuous time needs the torque as a
function that interval arithmetic can bound over a box of states; Pinocchio's RNEA evaluates it
at points. For a planar chain of two revolute joints about parallel axes the structure is
known, and its constants are read off Pinocchio once:

* The mass matrix depends on q2 alone (the kinetic energy is invariant under a rotation of the
  whole arm about joint 1), and in the plane the cross term of link 2 with link 1 is
  ``m2 l1 (x2 cos q2 - y2 sin q2)`` for link 2's centre of mass (x2, y2) in its own frame, so
  ``M(q2) = M0 + Mc cos q2 + Ms sin q2`` with ``Mc = [[2b, b], [b, 0]]``, ``Ms = [[2c, c], [c, 0]]``.
  Pinocchio's CRBA at q2 = 0, pi/2 and pi gives M0 = (M(0) + M(pi)) / 2, Mc = (M(0) - M(pi)) / 2
  and Ms = M(pi/2) - M0; :func:`identify_dynamics` checks the structure (and tests compare the
  closed form with CRBA and RNEA at random states).
* The Christoffel symbols of that M: with ``h(q2) = dM11/dq2 / 2 = (-Mc11 sin q2 + Ms11 cos q2) / 2``
  (dM12/dq2 = h, dM22/dq2 = 0),
  ``tau1 = M11 ddq1 + M12 ddq2 + h (2 dq1 dq2 + dq2^2)`` and ``tau2 = M12 ddq1 + M22 ddq2 - h dq1^2``.
* Gravity: the arm moves in a horizontal plane when its joint axes are parallel to gravity; then
  gravity does no work on any motion of the arm and contributes nothing to the joint torques. This
  is derived from the model, not assumed: :func:`identify_dynamics` refuses an arm whose axes are
  not parallel to Pinocchio's gravity vector, and checks that RNEA at rest gives zero torque.

Joint friction, damping and rotor inertia are not modelled (the URDF's ``<dynamics>`` are not
used by RNEA either).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pipeline.exceptions import RobotModelError

if TYPE_CHECKING:  # the closed form itself needs neither Pinocchio nor Coal
    from pipeline.model.arm import PlanarArm

__all__ = ["PlanarDynamics", "identify_dynamics", "rnea_torques"]

#: Largest relative mismatch accepted between the closed form's structure and Pinocchio's CRBA.
_STRUCTURE_TOLERANCE = 1e-9


@dataclass(frozen=True)
class PlanarDynamics:
    """``tau = M(q2) ddq + c(q2, dq)`` of a planar 2R arm about vertical axes (module docstring).

    Attributes:
        m0, mc, ms: The constant matrices of ``M(q2) = m0 + mc cos q2 + ms sin q2`` [kg m^2],
            each a 2 x 2 tuple of tuples.
    """

    m0: tuple[tuple[float, float], tuple[float, float]]
    mc: tuple[tuple[float, float], tuple[float, float]]
    ms: tuple[tuple[float, float], tuple[float, float]]

    def mass_matrix(self, q2: np.ndarray) -> np.ndarray:
        """M(q2) [kg m^2], shape (..., 2, 2)."""
        q2 = np.asarray(q2, dtype=float)[..., None, None]
        return np.asarray(self.m0) + np.asarray(self.mc) * np.cos(q2) + np.asarray(self.ms) * np.sin(q2)

    def coriolis_coefficient(self, q2: np.ndarray) -> np.ndarray:
        """h(q2) = dM11/dq2 / 2 [kg m^2], shape of ``q2``."""
        q2 = np.asarray(q2, dtype=float)
        return 0.5 * (-self.mc[0][0] * np.sin(q2) + self.ms[0][0] * np.cos(q2))

    def torque(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
        """Joint torques [N m] for joint angles [rad], speeds [rad/s], accelerations [rad/s^2], each (..., 2)."""
        q, dq, ddq = (np.asarray(v, dtype=float) for v in (q, dq, ddq))
        mass = self.mass_matrix(q[..., 1])
        h = self.coriolis_coefficient(q[..., 1])
        inertial = np.einsum("...ij,...j->...i", mass, ddq)
        centrifugal = np.stack([h * (2.0 * dq[..., 0] * dq[..., 1] + dq[..., 1] ** 2), -h * dq[..., 0] ** 2], -1)
        return inertial + centrifugal

    def mass_matrix_sup(self) -> np.ndarray:
        """sup over q2 of |M_ij(q2)| [kg m^2], (2, 2): |m0| + sqrt(mc^2 + ms^2) entrywise (exact)."""
        return np.abs(np.asarray(self.m0)) + np.hypot(np.asarray(self.mc), np.asarray(self.ms))

    def coriolis_sup(self) -> float:
        """sup over q2 of |h(q2)| [kg m^2] (exact)."""
        return 0.5 * math.hypot(self.mc[0][0], self.ms[0][0])

    @functools.cached_property
    def suprema(self) -> tuple[tuple[tuple[float, float], tuple[float, float]], float]:
        """(:meth:`mass_matrix_sup` as rows of plain floats, :meth:`coriolis_sup`), computed once
        per dynamics (the instance is frozen): what the closed-form bounds read per query."""
        mass = self.mass_matrix_sup()
        rows = ((float(mass[0, 0]), float(mass[0, 1])), (float(mass[1, 0]), float(mass[1, 1])))
        return rows, float(self.coriolis_sup())


def _crba(arm: PlanarArm, q2: float) -> np.ndarray:
    import pinocchio as pin

    data = arm.model.createData()
    mass = pin.crba(arm.model, data, np.array([0.0, q2]))
    return np.triu(mass) + np.triu(mass, 1).T


def identify_dynamics(arm: PlanarArm) -> PlanarDynamics:
    """The closed-form dynamics of ``arm`` (module docstring), identified from Pinocchio.

    Raises:
        RobotModelError: the joint axes are not parallel to gravity (gravity would load the
            joints: not handled), or the model's mass matrix does not have the planar structure.
    """
    import pinocchio as pin

    gravity = np.asarray(arm.model.gravity.linear, dtype=float)
    if np.linalg.norm(gravity) > 0.0:
        sine = np.linalg.norm(np.cross(arm.axis, gravity)) / np.linalg.norm(gravity)
        if sine > 1e-9:
            raise RobotModelError(
                f"{arm.urdf_path}: the joint axis {np.round(arm.axis, 6).tolist()} is not parallel to gravity "
                f"{np.round(gravity, 6).tolist()} (angle {math.degrees(math.asin(min(1.0, sine))):.3g} deg): "
                "gravity would load the joints, which the torque certificate does not model; the arm must move "
                "in a horizontal plane"
            )
    data = arm.model.createData()
    for q in (np.zeros(2), np.array([0.7, -1.9]), np.array([-2.5, 2.2])):
        resting = pin.rnea(arm.model, data, q, np.zeros(2), np.zeros(2))
        if np.max(np.abs(resting)) > 1e-9:
            raise RobotModelError(f"{arm.urdf_path}: RNEA at rest gives torques {resting.tolist()} N m, expected 0")
    at_0, at_half, at_pi = _crba(arm, 0.0), _crba(arm, math.pi / 2), _crba(arm, math.pi)
    m0, mc = 0.5 * (at_0 + at_pi), 0.5 * (at_0 - at_pi)
    ms = at_half - m0
    scale = max(1e-12, float(np.max(np.abs(at_0))))
    for name, part in (("cos", mc), ("sin", ms)):
        expected = np.array([[2.0 * part[0, 1], part[0, 1]], [part[0, 1], 0.0]])
        if np.max(np.abs(part - expected)) > _STRUCTURE_TOLERANCE * scale:
            raise RobotModelError(
                f"{arm.urdf_path}: the mass matrix's {name} q2 part {part.tolist()} is not that of a planar 2R arm"
            )

    def tuple2(matrix: np.ndarray) -> tuple[tuple[float, float], tuple[float, float]]:
        return ((float(matrix[0, 0]), float(matrix[0, 1])), (float(matrix[1, 0]), float(matrix[1, 1])))

    return PlanarDynamics(tuple2(m0), tuple2(mc), tuple2(ms))


def rnea_torques(arm: PlanarArm, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
    """Joint torques [N m] by Pinocchio's RNEA, one state at a time (rows of q [rad], dq [rad/s],
    ddq [rad/s^2]): the reference the closed form is tested against, and what exports carry."""
    import pinocchio as pin

    data = arm.model.createData()
    return np.array([pin.rnea(arm.model, data, *state).copy() for state in zip(q, dq, ddq, strict=True)])
