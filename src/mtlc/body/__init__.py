"""The human body model: percentile manikins, batched kinematics and IK solvers.

A library of its own: it knows numpy, scipy and its packaged data, never the language.

>>> from mtlc.body import build_manikin, forward, site_positions
>>> sk = build_manikin("gb10000_1988", "male", 50)
>>> pose = forward(sk, sk.q_comfort[None])          # batch of one configuration
>>> site_positions(sk, pose, "r_hand").shape
(1, 3)
"""

from .anthropometry import PERCENTILES, POPULATIONS, SEXES, Dimensions, citation, dimensions
from .kinematics import (
    Pose,
    center_of_mass,
    com_jacobian,
    forward,
    forward_part,
    jacobian,
    matrix_to_quat,
    part_site_positions,
    quat_to_matrix,
    rotation_error,
    site_direction,
    site_positions,
    site_rotation,
)
from .skeleton import (
    JOINT_TABLE,
    Dof,
    Joint,
    Site,
    Skeleton,
    build_manikin,
    skeleton_from_dimensions,
)

__all__ = [
    "JOINT_TABLE",
    "PERCENTILES",
    "POPULATIONS",
    "SEXES",
    "Dimensions",
    "Dof",
    "Joint",
    "Pose",
    "Site",
    "Skeleton",
    "build_manikin",
    "center_of_mass",
    "citation",
    "com_jacobian",
    "dimensions",
    "forward",
    "forward_part",
    "jacobian",
    "matrix_to_quat",
    "part_site_positions",
    "quat_to_matrix",
    "rotation_error",
    "site_direction",
    "site_positions",
    "site_rotation",
    "skeleton_from_dimensions",
]
