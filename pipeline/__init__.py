"""Online trajectory generation for a planar 2-link arm around a rectangular obstacle.

The public API. Everything a user needs is imported from here; the subpackages follow the data
flow (each imports only those before it): ``model`` (URDF -> arm, kinematics, scene, obstacle)
-> ``motion`` (path, sinusoids, families) -> ``geometry`` (clearance routes, certificates) ->
``offline`` (fitness, PSO, DOE, regression, coefficients) -> ``certify`` (the range certificate
and its map) -> ``build`` (the whole offline build as one call) -> ``online`` (loading,
generator, certify-or-repair).

The online names (:func:`load_coefficients`, :func:`generate`, :func:`generate_batch`, the
errors) need NumPy and Numba only; the others (the build, the arm, certify-or-repair) load
Pinocchio and Coal. Every name but the errors and :func:`load_coefficients` is imported on
first use.
"""

from __future__ import annotations

import importlib
from types import MappingProxyType

from pipeline.exceptions import (
    ArmMismatchError,
    BuildNotConvergedError,
    DataFileError,
    ExecutionRefusedError,
    InvalidParameterError,
    MissingDependencyError,
    NoCertifiedTrajectoryError,
    NoSceneWindowError,
    ObstacleSizeError,
    OutOfFittedRangeError,
    OutOfFittedRangeWarning,
    OutputLockedError,
    PipelineError,
    RegionMapLimitsError,
    RegionMapMismatchError,
    RegionMapMismatchWarning,
    SchedulerUnreachableError,
    TimingRefusedError,
    UnreachableObstacleError,
    WorkerPoolError,
)
from pipeline.online.loading import load_coefficients

#: Public names imported on first access: those whose modules need Pinocchio or Coal, and the
#: online object's and the generator's.
_LAZY = MappingProxyType(
    {
        "GeneratedTrajectory": "pipeline.online.generator",
        "generate": "pipeline.online.generator",
        "OnlineGenerator": "pipeline.online.online_generator",
        "load": "pipeline.online.online_generator",
        "GeneratedBatch": "pipeline.online.batch",
        "generate_batch": "pipeline.online.batch",
        "BuildConfig": "pipeline.build",
        "BuildResult": "pipeline.build",
        "run_build": "pipeline.build",
        "scene_from_options": "pipeline.build",
        "load_planar_arm": "pipeline.model.arm",
        "PlanarArm": "pipeline.model.arm",
        "CertifiedBatch": "pipeline.online.batch_certify",
        "certify_batch": "pipeline.online.batch_certify",
        "CertifiedTrajectory": "pipeline.online.repair",
        "RepairConfig": "pipeline.online.repair",
        "generate_certified": "pipeline.online.repair",
        "ArmLimits": "pipeline.model.limits",
        "PAPER_TIMING": "pipeline.motion.timing",
        "RestToRestTiming": "pipeline.motion.timing",
        "REST_TO_REST": "pipeline.motion.rest_to_rest",
        "NEAR_OPTIMAL": "pipeline.motion.near_optimal",
        "NearOptimal": "pipeline.motion.near_optimal",
        "NearOptimalSettings": "pipeline.motion.near_optimal",
        "ExecutionBatch": "pipeline.online.batch_execution",
        "execution_batch": "pipeline.online.batch_execution",
    }
)

__all__ = [
    "NEAR_OPTIMAL",
    "PAPER_TIMING",
    "REST_TO_REST",
    "ArmLimits",
    "ArmMismatchError",
    "BuildConfig",
    "BuildNotConvergedError",
    "BuildResult",
    "CertifiedBatch",
    "CertifiedTrajectory",
    "DataFileError",
    "ExecutionBatch",
    "ExecutionRefusedError",
    "GeneratedBatch",
    "GeneratedTrajectory",
    "InvalidParameterError",
    "MissingDependencyError",
    "NearOptimal",
    "NearOptimalSettings",
    "NoCertifiedTrajectoryError",
    "NoSceneWindowError",
    "ObstacleSizeError",
    "OnlineGenerator",
    "OutOfFittedRangeError",
    "OutOfFittedRangeWarning",
    "OutputLockedError",
    "PipelineError",
    "PlanarArm",
    "RegionMapLimitsError",
    "RegionMapMismatchError",
    "RegionMapMismatchWarning",
    "RepairConfig",
    "RestToRestTiming",
    "SchedulerUnreachableError",
    "TimingRefusedError",
    "UnreachableObstacleError",
    "WorkerPoolError",
    "certify_batch",
    "execution_batch",
    "generate",
    "generate_batch",
    "generate_certified",
    "load",
    "load_coefficients",
    "load_planar_arm",
    "run_build",
    "scene_from_options",
]


def __getattr__(name: str):
    """The public names of :data:`_LAZY`, imported on first access (PEP 562)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'pipeline' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
