"""Visibility: is the site being worked on inside the worker's view cone?

Seed 000 asks the motion to be analysed for visibility (可视性). The view direction is the head's
forward axis, the direction of the skeleton's ``gaze`` site (the eye point, ``docs/body.md``);
the manikin has no eyes that turn on their own, so the cone is carried by the head. A site is
visible when the angle between that axis and the line from the eye to the site is at most the
cone's half-angle (30° by default: ``docs/visibility.md`` gives the source and the reasoning).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mtlc.body.kinematics import Pose, site_direction, site_positions
from mtlc.body.skeleton import Skeleton

FloatArray = NDArray[np.float64]

DEFAULT_HALF_ANGLE_DEG = 30.0
EYE_SITE = "gaze"


def view_angle(eye: ArrayLike, forward: ArrayLike, target: ArrayLike) -> FloatArray:
    """Angle (rad, (...)) between the view axis ``forward`` and the line from ``eye`` to
    ``target``; all (..., 3) in the same frame. A target at the eye counts as straight ahead."""
    to_target = np.asarray(target, dtype=float) - np.asarray(eye, dtype=float)
    axis = np.asarray(forward, dtype=float)
    axis = axis / np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), 1e-12)
    dist = np.linalg.norm(to_target, axis=-1)
    cosine = np.einsum("...i,...i->...", to_target, axis) / np.maximum(dist, 1e-12)
    angle = np.arccos(np.clip(cosine, -1.0, 1.0))
    return np.where(dist < 1e-9, 0.0, angle)


def eye_and_axis(skel: Skeleton, pose: Pose) -> tuple[FloatArray, FloatArray]:
    """The eye point and the head's forward axis (each (..., 3), world) of every posed frame."""
    return site_positions(skel, pose, EYE_SITE), site_direction(skel, pose, EYE_SITE)


def site_view_angles(skel: Skeleton, pose: Pose, target: ArrayLike) -> FloatArray:
    """Per frame, the angle (rad) at which ``target`` (3,) or (N, 3) is seen off the view axis."""
    eye, axis = eye_and_axis(skel, pose)
    return view_angle(eye, axis, target)


def outside_cone(angle: ArrayLike, half_angle_deg: float = DEFAULT_HALF_ANGLE_DEG) -> NDArray:
    """Which angles (rad) fall outside a cone of ``half_angle_deg``; the boundary is inside."""
    return np.asarray(angle, dtype=float) > math.radians(half_angle_deg) + 1e-12
