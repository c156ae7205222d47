"""The human body model: percentile manikins, batched kinematics and IK solvers.

A library of its own: it knows numpy, scipy and its packaged data, never the language.

>>> from mtlc.body import build_manikin, forward, site_positions
>>> sk = build_manikin("gb10000_1988", "male", 50)
>>> pose = forward(sk, sk.q_comfort[None])          # batch of one configuration
>>> site_positions(sk, pose, "r_hand").shape
(1, 3)
"""

import importlib
from typing import TYPE_CHECKING, Any

from .anthropometry import PERCENTILES, POPULATIONS, SEXES, Dimensions, citation, dimensions

if TYPE_CHECKING:
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

# the kinematics and the skeleton load numpy: imported on first use, so that the front end
# (which needs only the anthropometry: a stature for the walks' time) starts without it
_LAZY = {
    **dict.fromkeys(
        ("Pose", "center_of_mass", "com_jacobian", "forward", "forward_part", "jacobian",
         "matrix_to_quat", "part_site_positions", "quat_to_matrix", "rotation_error",
         "site_direction", "site_positions", "site_rotation"),
        ".kinematics",
    ),
    **dict.fromkeys(
        ("JOINT_TABLE", "Dof", "Joint", "Site", "Skeleton", "build_manikin",
         "skeleton_from_dimensions"),
        ".skeleton",
    ),
}  # fmt: skip


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


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
