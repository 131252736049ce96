"""The arm and its world: URDF -> Pinocchio arm, closed-form kinematics, scene, rounded-box obstacle."""
