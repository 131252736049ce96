"""A general-purpose planner to compare with: OMPL's RRT-Connect in the arm's joint space.

:func:`plan_rrt_connect` runs RRT-Connect (``ompl`` from PyPI, the optional ``bench`` extra)
in the arm's joint space (bounds: the URDF's position limits), from the analytic IK of P1 to
that of P5, with a Coal validity checker on the same geometry as ours: a state is valid iff the
Pinocchio + Coal clearance of both links is **>= margin** (the scene's safety margin, 0.01 m by
default, the margin our generator is held to). ``ompl`` is imported lazily inside the
functions, so this module imports without it. The piecewise-linear path it returns is certified
by :mod:`pipeline.geometry.polyline_certificate`.
"""

from __future__ import annotations

import importlib.util
import time
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import CoalClearance
from pipeline.geometry.polyline_certificate import JointPath, timed_path
from pipeline.model.arm import PlanarArm
from pipeline.model.kinematics import inverse_kinematics, reach_annulus_m
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import desired_path
from pipeline.validation import check_non_negative, check_positive, check_positive_int

#: OMPL's own default state validity checking resolution (fraction of the space's extent).
OMPL_DEFAULT_RESOLUTION = 0.01
#: OMPL console log levels by name (OMPL's default prints every Info line on stdout).
OMPL_LOG_LEVELS = ("none", "error", "warn", "info")


def ompl_available() -> bool:
    """True if the ``ompl`` Python bindings can be imported."""
    return importlib.util.find_spec("ompl") is not None


def ompl_version() -> str | None:
    """Installed version of the ``ompl`` distribution, or None."""
    from importlib import metadata

    try:
        return metadata.version("ompl")
    except metadata.PackageNotFoundError:
        return None


_SEEDED: list[int] = []


def seed_ompl(seed: int) -> bool:
    """Seed OMPL's global random generator, once per process (OMPL only honours the first seed,
    before any sampler exists). Returns True if this call set the seed."""
    check_positive_int("seed", seed, minimum=0)
    if _SEEDED:
        return False
    from ompl import util as ou

    ou.RNG.setSeed(seed + 1)  # OMPL treats seed 0 as "pick one at random"
    _SEEDED.append(seed)
    return True


@dataclass(frozen=True)
class PlannerConfig:
    """How RRT-Connect is run.

    Attributes:
        time_limit_s: Planning time budget per query [s] (OMPL stops at the first solution).
        margin_m: A state is valid iff both links' Coal clearance is >= this [m].
        simplify: Shortcut the solution with OMPL's path simplifier (as a user would), within
            another ``time_limit_s``.
        resolution: OMPL's state validity checking resolution along motions, as a fraction of
            the joint space's extent (OMPL's default 0.01).
        range_rad: RRT-Connect's maximum step [rad]; None lets OMPL choose (20% of the extent).
        log_level: OMPL's console output: "none", "error", "warn" or "info" (set process-wide).
    """

    time_limit_s: float = 1.0
    margin_m: float = 0.01
    simplify: bool = True
    resolution: float = OMPL_DEFAULT_RESOLUTION
    range_rad: float | None = None
    log_level: str = "warn"

    def __post_init__(self) -> None:
        if self.log_level not in OMPL_LOG_LEVELS:
            raise InvalidParameterError("log_level", self.log_level, f"one of {OMPL_LOG_LEVELS}")
        check_positive("time_limit_s", self.time_limit_s)
        check_non_negative("margin_m", self.margin_m)
        check_positive("resolution", self.resolution)
        if self.range_rad is not None:
            check_positive("range_rad", self.range_rad)


@dataclass(frozen=True, eq=False)
class PlanResult:
    """One RRT-Connect query.

    Attributes:
        solved: True if OMPL found an exact solution (an approximate one counts as failure).
        status: OMPL's planner status, as text.
        waypoints_rad: The solution's states, shape (k, 2) [rad] (empty if none).
        path: The timed path (URDF velocity limits), or None if not solved.
        plan_seconds: Wall time of setup + solve [s].
        simplify_seconds: Wall time of the simplification [s].
        validity_checks: Calls of the validity checker.
        coal_queries: Coal distance queries made by the validity checker.
        start_valid, goal_valid: Whether the start and goal states are valid.
    """

    solved: bool
    status: str
    waypoints_rad: np.ndarray
    path: JointPath | None
    plan_seconds: float
    simplify_seconds: float
    validity_checks: int
    coal_queries: int
    start_valid: bool
    goal_valid: bool

    @property
    def seconds(self) -> float:
        """Wall time of the whole query (setup, solve, simplification) [s]."""
        return self.plan_seconds + self.simplify_seconds


def start_goal_configurations(
    obstacle: Obstacle, scene: Scene, link_lengths_m: tuple[float, float], elbow: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles [rad] at P1 and P5 of the obstacle's desired path (analytic IK, one elbow branch)."""
    path = desired_path(obstacle, scene, reach_annulus_m(link_lengths_m))
    start = inverse_kinematics(path.points_m[0], link_lengths_m, elbow)
    goal = inverse_kinematics(path.points_m[-1], link_lengths_m, elbow)
    return start, goal


def plan_rrt_connect(
    arm: PlanarArm,
    obstacle: Obstacle,
    start_rad: np.ndarray,
    goal_rad: np.ndarray,
    config: PlannerConfig | None = None,
) -> PlanResult:
    """Plan from ``start_rad`` to ``goal_rad`` with OMPL's RRT-Connect and a Coal validity checker.

    Everything a user would do per obstacle is inside the timing: building the Coal checker,
    the state space and the SimpleSetup, solving, and (if configured) simplifying.

    Raises:
        ModuleNotFoundError: ``ompl`` is not installed.
    """
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    config = config or PlannerConfig()
    ou.setLogLevel(getattr(ou, f"LOG_{config.log_level.upper()}"))
    started = time.perf_counter()
    checker = CoalClearance(arm, obstacle)
    margin = config.margin_m
    checks = [0]

    def is_valid(state) -> bool:
        checks[0] += 1
        values = checker.link_clearance(np.array([state[0], state[1]]))
        return bool(values[0] >= margin and values[1] >= margin)

    space = ob.RealVectorStateSpace(2)
    bounds = ob.RealVectorBounds(2)
    for joint, (low, high) in enumerate(arm.position_limits_rad):
        bounds.setLow(joint, float(low))
        bounds.setHigh(joint, float(high))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    setup.setStateValidityChecker(is_valid)
    information = setup.getSpaceInformation()
    information.setStateValidityCheckingResolution(config.resolution)
    start, goal = space.allocState(), space.allocState()
    for j in (0, 1):
        start[j] = float(start_rad[j])
        goal[j] = float(goal_rad[j])
    setup.setStartAndGoalStates(start, goal)
    planner = og.RRTConnect(information)
    if config.range_rad is not None:
        planner.setRange(config.range_rad)
    setup.setPlanner(planner)
    start_valid = is_valid(start)
    goal_valid = is_valid(goal)
    status = setup.solve(config.time_limit_s)
    solved = bool(setup.haveExactSolutionPath())
    plan_seconds = time.perf_counter() - started
    simplify_seconds = 0.0
    waypoints = np.zeros((0, 2))
    path = None
    if solved:
        if config.simplify:
            begun = time.perf_counter()
            setup.simplifySolution(config.time_limit_s)
            simplify_seconds = time.perf_counter() - begun
        solution = setup.getSolutionPath()
        waypoints = np.array(
            [[solution.getState(i)[0], solution.getState(i)[1]] for i in range(solution.getStateCount())]
        )
        path = timed_path(waypoints, arm.velocity_limits_rad_s)
    return PlanResult(
        solved=solved,
        status=str(status),
        waypoints_rad=waypoints,
        path=path,
        plan_seconds=plan_seconds,
        simplify_seconds=simplify_seconds,
        validity_checks=checks[0],
        coal_queries=int(checker.queries),
        start_valid=start_valid,
        goal_valid=goal_valid,
    )
