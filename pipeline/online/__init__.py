"""The online stage: the generator (coefficients + (L, W) -> trajectory), the arm check and certify-or-repair."""

from pipeline.online.arm_check import check_arm_matches
from pipeline.online.generator import GeneratedTrajectory, generate, generate_parameters
from pipeline.online.repair import CertifiedTrajectory, RepairConfig, generate_certified

__all__ = [
    "CertifiedTrajectory",
    "GeneratedTrajectory",
    "RepairConfig",
    "check_arm_matches",
    "generate",
    "generate_certified",
    "generate_parameters",
]
