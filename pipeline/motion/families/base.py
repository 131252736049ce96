"""The interface every trajectory family implements.

A family says which of the eight sinusoid parameters (A1, w1, phi1, gamma1, A2, w2, phi2,
gamma2) are searched by the PSO and fitted by the regression (its *free* parameters), and how
the eight follow from the free ones for one obstacle. Everything that depends on the family
asks the family object; nothing else compares family names.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from types import MappingProxyType
from typing import ClassVar

import numpy as np

from pipeline.model.kinematics import inverse_kinematics

# Search box per parameter kind: A [rad], w [rad/s], phi [rad], gamma [rad].
_BOUNDS = MappingProxyType(
    {"A": (-3.0, 3.0), "w": (0.2, 2.5), "phi": (-np.pi / 2, np.pi / 2), "gamma": (-np.pi, np.pi)}
)

#: Names of the entries of :meth:`EndpointContext.as_array`, in order.
CONTEXT_NAMES: tuple[str, ...] = ("theta1_start", "theta2_start", "theta1_end", "theta2_end", "duration")


@dataclass(frozen=True)
class EndpointContext:
    """What a family may need to know about one obstacle besides its free parameters.

    Attributes:
        theta_start_rad: Joint angles at P1 [rad] (analytic IK on the family's elbow branch).
        theta_end_rad: Joint angles at P5 [rad].
        duration_s: T [s].
    """

    theta_start_rad: tuple[float, float]
    theta_end_rad: tuple[float, float]
    duration_s: float

    def as_array(self) -> np.ndarray:
        """(theta1_start, theta2_start, theta1_end, theta2_end, T) as a (5,) array, see :data:`CONTEXT_NAMES`."""
        return np.array([*self.theta_start_rad, *self.theta_end_rad, self.duration_s])


def endpoint_context(path, link_lengths_m: tuple[float, float], elbow: int = 1) -> EndpointContext:
    """Joint angles of P1 and P5 (analytic IK on the given elbow branch) and T, for a
    :class:`pipeline.motion.path.QuarticPath` ``path``.

    Raises:
        UnreachableObstacleError: P1 or P5 is outside the arm's reach.
    """
    start = inverse_kinematics(path.points_m[0], link_lengths_m, elbow)
    end = inverse_kinematics(path.points_m[-1], link_lengths_m, elbow)
    return EndpointContext((float(start[0]), float(start[1])), (float(end[0]), float(end[1])), path.duration_s)


@dataclass(frozen=True)
class TrajectoryFamily(ABC):
    """A way of spanning the eight sinusoid parameters by a few free ones.

    Class attributes:
        name: The family's name in files and on the command line.
        free_parameter_names: The free parameters, in the order the PSO searches and the
            regression fits them.
        pins_endpoints: True if the tip is at P1 at t = 0 and at P5 at t = T by construction
            (wherever :meth:`endpoints_exact` says so), so the end poses are fixed by the obstacle.
        uses_endpoint_context: True if :meth:`expand` needs the obstacle's
            :class:`EndpointContext` (else it accepts None).
        expands_to_itself: True if :meth:`expand` returns the free parameters unchanged (all
            eight free, no context): the online generator then skips it.
    """

    name: ClassVar[str]
    free_parameter_names: ClassVar[tuple[str, ...]]
    pins_endpoints: ClassVar[bool]
    uses_endpoint_context: ClassVar[bool]
    expands_to_itself: ClassVar[bool] = False

    @property
    def free_count(self) -> int:
        """Number of free parameters k."""
        return len(self.free_parameter_names)

    def search_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) of the PSO search box over the free parameters."""
        lower = np.array([_BOUNDS[n.rstrip("12")][0] for n in self.free_parameter_names])
        upper = np.array([_BOUNDS[n.rstrip("12")][1] for n in self.free_parameter_names])
        return lower, upper

    def polish_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the local polish: the search box, except that phases are unbounded.

        A phase is 2 pi periodic (and pi periodic with A's sign flip, Eq. 8): a bound on it
        would stop a local solver at +-pi/2 when the optimum lies just across, in the same
        motion family.
        """
        lower, upper = self.search_bounds()
        phases = np.array([name.startswith("phi") for name in self.free_parameter_names])
        return np.where(phases, -np.inf, lower), np.where(phases, np.inf, upper)

    def endpoint_context(self, path, link_lengths_m: tuple[float, float], elbow: int = 1) -> EndpointContext:
        """The obstacle's :class:`EndpointContext` (IK of P1 and P5 on ``elbow``'s branch, and T)."""
        return endpoint_context(path, link_lengths_m, elbow)

    @abstractmethod
    def expand(self, free: np.ndarray, context: EndpointContext | None) -> np.ndarray:
        """The 8 parameters (..., 8) from free parameters (..., k) for one obstacle's context."""

    @abstractmethod
    def canonical_free(self, free: np.ndarray) -> np.ndarray:
        """Free parameters (..., k) mapped to one canonical form (Eq. 8) of the same motion."""

    @abstractmethod
    def expand_jacobians(self, free: np.ndarray, context: EndpointContext | None) -> tuple[np.ndarray, np.ndarray]:
        """Derivatives of :meth:`expand`: d(8 parameters)/d(free) (..., 8, k) and
        d(8 parameters)/d(context) (..., 8, 5), the context as :meth:`EndpointContext.as_array`.

        With the derivatives of the free parameters (the regression's polynomials) and of the
        context (the IK of P1, P5 and T) with respect to (L, W), the chain rule gives
        d(8 parameters)/d(L, W), which a range certificate needs.
        """

    @abstractmethod
    def endpoints_exact(self, free: np.ndarray, context: EndpointContext | None) -> np.ndarray:
        """Boolean (...,): True where the family puts the tip exactly on P1 and P5 (up to rounding)."""
