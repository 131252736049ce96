"""The online stage: the generator (coefficients + (L, W) -> trajectory), the arm check and certify-or-repair."""

from pipeline.online.arm_check import check_arm_matches
from pipeline.online.batch import CertifiedBatch, GeneratedBatch, certify_batch, generate_batch
from pipeline.online.generator import GeneratedTrajectory, generate, generate_parameters
from pipeline.online.repair import CertifiedTrajectory, RepairConfig, generate_certified

__all__ = [
    "CertifiedBatch",
    "CertifiedTrajectory",
    "GeneratedBatch",
    "GeneratedTrajectory",
    "RepairConfig",
    "certify_batch",
    "check_arm_matches",
    "generate",
    "generate_batch",
    "generate_certified",
    "generate_parameters",
]
