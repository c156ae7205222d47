"""BVH (Biovision Hierarchy) generator: the solved frames as a standard motion-capture file.

The hierarchy is the manikin itself: one BVH joint per skeleton joint, named alike, with the
skeleton's offsets, so the BVH rest pose is our neutral pose. Lengths are **centimetres** (most
BVH tools assume them), angles degrees; axes are ours (Y up, the manikin faces +Z).

Every joint has three rotation channels in an order of its own, the order of its degrees of
freedom (then the axes it lacks): our joint rotation ``R(a_1, q_1)·R(a_2, q_2)·…`` about
coordinate axes already *is* an intrinsic Euler sequence, so the channel values are our angles
(negated for an axis pointing down its coordinate axis) and the file reproduces our forward
kinematics exactly, gimbal configurations included. Only the root's quaternion (and a joint
about a non-coordinate axis, which the manikin has none of) goes through a matrix-to-Euler
decomposition. See ``docs/bvh.md``.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mtlc.body.kinematics import axis_angle, quat_to_matrix
from mtlc.body.skeleton import Skeleton
from mtlc.ir.model import MotionIR

FloatArray = NDArray[np.float64]

CENTIMETRES_PER_METRE = 100.0
# Lengths to 0.01 mm (3 decimals of a cm), angles to 0.001°: far coarser than what another BLAS
# build changes (about 1e-6°), far inside the 1 mm read-back tolerance. docs/bvh.md.
DECIMALS = 3
AXIS_LETTERS = "XYZ"
# The root turns mostly about the vertical: yaw first, so the decomposition's singular
# configuration is a pelvis pitched by 90 degrees.
ROOT_ORDER = (1, 0, 2)
# Which site ends each leaf joint's bone (the hand's grip point, the toe, the top of the head).
END_SITE_BY_JOINT = {"wrist": "hand", "toes": "toe", "head": "vertex"}
GIMBAL_COS = 1e-9


@dataclass(frozen=True)
class JointChannels:
    """How one joint's rotation is written: the axis order and how angles map onto it.

    ``direct`` holds, per channel, the dof index and sign feeding it (``None`` for a channel
    with no dof, always 0); it is ``None`` when the joint needs a decomposition.
    """

    order: tuple[int, int, int]
    direct: tuple[tuple[int, float] | None, ...] | None


def emit_bvh(ir: MotionIR) -> str:
    """The IR's frames as BVH text: hierarchy, then one line per frame at the IR's rate."""
    if ir.frames is None or ir.skeleton is None:
        raise ValueError("emit_bvh needs a finished IR: run every motion pass first")
    skel: Skeleton = ir.skeleton
    order = depth_first(skel)
    channels = [joint_channels(skel, j) for j in range(skel.n_joints)]
    lines = ["HIERARCHY", *hierarchy_lines(skel, channels)]
    motion = motion_values(skel, ir, order, channels)
    lines += [
        "MOTION",
        f"Frames: {motion.shape[0]}",
        f"Frame Time: {1.0 / ir.frames.fps:.8f}",
    ]
    lines += format_rows(motion)
    return "\n".join(lines) + "\n"


# -- hierarchy -----------------------------------------------------------------------------
def depth_first(skel: Skeleton) -> list[int]:
    """Joint indices in the order BVH nests them (children in skeleton order)."""
    children = children_of(skel)
    out: list[int] = []
    stack = [0]
    while stack:
        j = stack.pop()
        out.append(j)
        stack.extend(reversed(children[j]))
    return out


def children_of(skel: Skeleton) -> list[list[int]]:
    kids: list[list[int]] = [[] for _ in range(skel.n_joints)]
    for j in range(1, skel.n_joints):
        kids[int(skel.parent[j])].append(j)
    return kids


def hierarchy_lines(skel: Skeleton, channels: Sequence[JointChannels]) -> Iterator[str]:
    """The HIERARCHY block, recursively from the root."""
    children = children_of(skel)

    def block(j: int, depth: int) -> Iterator[str]:
        pad = "  " * depth
        keyword = "ROOT" if j == 0 else "JOINT"
        yield f"{pad}{keyword} {skel.joint_names[j]}"
        yield f"{pad}{{"
        yield f"{pad}  OFFSET {format_vector(skel.offsets[j] * CENTIMETRES_PER_METRE)}"
        rotations = " ".join(f"{AXIS_LETTERS[a]}rotation" for a in channels[j].order)
        if j == 0:
            yield f"{pad}  CHANNELS 6 Xposition Yposition Zposition {rotations}"
        else:
            yield f"{pad}  CHANNELS 3 {rotations}"
        for c in children[j]:
            yield from block(c, depth + 1)
        if not children[j]:
            yield f"{pad}  End Site"
            yield f"{pad}  {{"
            end = end_site_offset(skel, j) * CENTIMETRES_PER_METRE
            yield f"{pad}    OFFSET {format_vector(end)}"
            yield f"{pad}  }}"
        yield f"{pad}}}"

    yield from block(0, 0)


def end_site_offset(skel: Skeleton, joint: int) -> FloatArray:
    """Where a leaf's bone ends (joint frame, m): its named site, else its farthest site."""
    name = skel.joint_names[joint]
    side, _, kind = name.rpartition("_")
    wanted = END_SITE_BY_JOINT.get(kind)
    site_names = {s.name for s in skel.sites}
    if wanted is not None:
        full = f"{side}_{wanted}" if side else wanted
        if full in site_names:
            return np.asarray(skel.site(full).offset, dtype=float)
    own = [np.asarray(s.offset, dtype=float) for s in skel.sites if s.joint == name]
    if own:
        return max(own, key=lambda v: (float(np.linalg.norm(v)), tuple(v)))
    return np.array([0.0, 0.1, 0.0])  # a bone needs a length; 10 cm along +Y


# -- channels ------------------------------------------------------------------------------
def joint_channels(skel: Skeleton, joint: int) -> JointChannels:
    """The channel order of a joint and whether its angles map straight onto it."""
    if joint == 0:  # the quaternion (times any dofs of the root's own): always decomposed
        return JointChannels(ROOT_ORDER, None)
    start = int(skel.joint_dof_start[joint])
    dofs = range(start, start + int(skel.joint_dof_count[joint]))
    axes: list[int] = []
    signs: list[float] = []
    for k in dofs:
        hit = coordinate_axis(skel.dof_axis[k])
        if hit is None or hit[0] in axes:
            return JointChannels(ROOT_ORDER, None)
        axes.append(hit[0])
        signs.append(hit[1])
    order = (*axes, *(a for a in range(3) if a not in axes))
    direct = tuple((dofs[i], signs[i]) if i < len(axes) else None for i in range(3))
    return JointChannels((order[0], order[1], order[2]), direct)


def coordinate_axis(axis: FloatArray) -> tuple[int, float] | None:
    """(index, sign) when ``axis`` is ±X, ±Y or ±Z (to rounding), else None."""
    i = int(np.argmax(np.abs(axis)))
    if abs(abs(float(axis[i])) - 1.0) > 1e-12:
        return None
    return i, float(np.sign(axis[i]))


# -- motion --------------------------------------------------------------------------------
def motion_values(
    skel: Skeleton, ir: MotionIR, order: Sequence[int], channels: Sequence[JointChannels]
) -> FloatArray:
    """(N, 6 + 3·(J − 1)) channel values, cm and degrees, in the file's column order."""
    frames = ir.frames
    assert frames is not None
    q = np.asarray(frames.q, dtype=float)
    root_rotation = quat_to_matrix(frames.root_rotation)
    columns = [np.asarray(frames.root_position, dtype=float) * CENTIMETRES_PER_METRE]
    for j in order:
        columns.append(np.degrees(joint_angles(skel, j, channels[j], q, root_rotation)))
    return np.concatenate(columns, axis=1)


def joint_angles(
    skel: Skeleton, joint: int, ch: JointChannels, q: FloatArray, root_rotation: FloatArray
) -> FloatArray:
    """(N, 3) channel angles in radians for one joint."""
    if ch.direct is not None:
        out = np.zeros((q.shape[0], 3))
        for i, src in enumerate(ch.direct):
            if src is not None:
                out[:, i] = src[1] * q[:, src[0]]
        return out
    local = local_rotation(skel, joint, q)
    if joint == 0:
        local = root_rotation @ local
    return euler_from_matrix(local, ch.order)


def local_rotation(skel: Skeleton, joint: int, q: FloatArray) -> FloatArray:
    """(N, 3, 3) product of a joint's dof rotations, exactly as forward kinematics forms it."""
    out = np.broadcast_to(np.eye(3), (q.shape[0], 3, 3)).copy()
    start = int(skel.joint_dof_start[joint])
    for k in range(start, start + int(skel.joint_dof_count[joint])):
        out = out @ axis_angle(skel.dof_axis[k], q[:, k])
    return out


def euler_from_matrix(R: FloatArray, order: tuple[int, int, int]) -> FloatArray:
    """Intrinsic angles (..., 3) with ``R = R_i(a)·R_j(b)·R_k(c)`` for ``order = (i, j, k)``.

    Middle angle in [−90°, 90°]. At the singular middle angle (cos b = 0) only a ± c is
    determined: c is set to 0 and a takes the whole rotation, so the matrix is still exact.
    """
    i, j, k = order
    parity = 1.0 if (j - i) % 3 == 1 else -1.0  # XYZ, YZX, ZXY are even
    sin_b = np.clip(parity * R[..., i, k], -1.0, 1.0)
    b = np.arcsin(sin_b)
    cos_b = np.hypot(R[..., j, k], R[..., k, k])
    regular = cos_b > GIMBAL_COS
    a = np.where(
        regular,
        np.arctan2(-parity * R[..., j, k], R[..., k, k]),
        np.arctan2(parity * R[..., k, j], R[..., j, j]),
    )
    c = np.where(regular, np.arctan2(-parity * R[..., i, j], R[..., i, i]), 0.0)
    return np.stack([a, b, c], axis=-1)


def euler_to_matrix(angles: FloatArray, order: tuple[int, int, int]) -> FloatArray:
    """Inverse of :func:`euler_from_matrix`: ``R_i(a)·R_j(b)·R_k(c)``."""
    eye = np.eye(3)
    out = axis_angle(eye[order[0]], angles[..., 0])
    out = out @ axis_angle(eye[order[1]], angles[..., 1])
    return out @ axis_angle(eye[order[2]], angles[..., 2])


# -- formatting ----------------------------------------------------------------------------
def format_rows(values: FloatArray) -> list[str]:
    """One text line per frame, fixed decimals, never ``-0.000000``."""
    clean = np.round(values, DECIMALS) + 0.0  # adding 0.0 turns -0.0 into 0.0
    if clean.ndim < 2 or clean.shape[1] == 0:
        return ["" for _ in clean]
    # one %-format per row (the same text as a format per number, a third of the time)
    fmt = " ".join([f"%.{DECIMALS}f"] * clean.shape[1])
    return [fmt % tuple(row) for row in clean.tolist()]


def format_vector(v: FloatArray) -> str:
    return format_rows(np.asarray(v, dtype=float)[None, :])[0]
