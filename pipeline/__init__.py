"""Online trajectory generation for a planar 2-link arm around a rectangular obstacle.

The public API; the subpackages follow the data flow (each imports only those before it):

``model`` (URDF -> arm, kinematics, scene, obstacle) -> ``motion`` (path, sinusoids, families)
-> ``geometry`` (clearance routes, certificates) -> ``offline`` (fitness, PSO, DOE,
regression, coefficients) -> ``online`` (generator, certify-or-repair).
"""

from pipeline.exceptions import PipelineError
from pipeline.model.arm import load_planar_arm
from pipeline.offline.coefficients import load_coefficients
from pipeline.online.generator import generate
from pipeline.online.repair import generate_certified

__all__ = ["PipelineError", "generate", "generate_certified", "load_coefficients", "load_planar_arm"]
