"""IK goals and the default chain for each effector.

A goal asks a site (an effector such as ``r_hand``) for a world position, optionally a world
orientation of its frame, or, for aiming sites such as ``gaze``, to look at a point.
Every array may carry a leading batch dimension (one target per row).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..kinematics import quat_to_matrix
from ..skeleton import Skeleton

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Goal:
    """What one effector should do.

    ``position``: (3,) or (B, 3) world target of the site, or None.
    ``orientation``: world rotation of the site's frame, (3, 3)/(B, 3, 3) or quaternion
    (4,)/(B, 4) w first, or None.
    ``aim``: (3,) or (B, 3) world point the site's ``direction`` should point at (gaze).
    ``orientation_weight``: metres per radian when position and orientation errors mix.
    """

    effector: str
    position: ArrayLike | None = None
    orientation: ArrayLike | None = None
    aim: ArrayLike | None = None
    orientation_weight: float = 0.1

    def __post_init__(self) -> None:
        if self.position is None and self.orientation is None and self.aim is None:
            raise ValueError(f"goal for {self.effector} asks for nothing")
        if self.aim is not None and (self.position is not None or self.orientation is not None):
            raise ValueError("an aim goal cannot also ask for a position or orientation")


@dataclass(frozen=True)
class GoalArrays:
    """Goals normalised to batch arrays (internal)."""

    sites: tuple[str, ...]
    position: tuple[FloatArray | None, ...]  # (B, 3)
    orientation: tuple[FloatArray | None, ...]  # (B, 3, 3)
    aim: tuple[FloatArray | None, ...]  # (B, 3)
    weight: tuple[float, ...]
    batch: int


def batch_size(goals: Sequence[Goal]) -> int:
    """The batch size implied by the goals' arrays (1 if none is batched)."""
    b = 1
    for g in goals:
        for a, nd in ((g.position, 1), (g.aim, 1)):
            if a is not None and np.ndim(a) == nd + 1:
                b = max(b, np.shape(a)[0])
        if g.orientation is not None:
            o = np.asarray(g.orientation)
            if (o.shape[-1] == 4 and o.ndim == 2) or (o.shape[-1] == 3 and o.ndim == 3):
                b = max(b, o.shape[0])
    return b


def normalise(skel: Skeleton, goals: Sequence[Goal], batch: int | None = None) -> GoalArrays:
    """Check the goals against the skeleton and broadcast them to (B, …) arrays."""
    if not goals:
        raise ValueError("no goals")
    B = batch_size(goals) if batch is None else batch
    pos, ori, aim, w = [], [], [], []
    for g in goals:
        st = skel.site(g.effector)
        if g.aim is not None and st.direction is None:
            raise ValueError(f"{g.effector} has no direction to aim with")
        pos.append(
            None if g.position is None else np.broadcast_to(np.asarray(g.position, float), (B, 3))
        )
        if g.orientation is None:
            ori.append(None)
        else:
            o = np.asarray(g.orientation, dtype=float)
            o = quat_to_matrix(o) if o.shape[-1] == 4 else o
            ori.append(np.broadcast_to(o, (B, 3, 3)))
        aim.append(None if g.aim is None else np.broadcast_to(np.asarray(g.aim, float), (B, 3)))
        w.append(float(g.orientation_weight))
    return GoalArrays(
        sites=tuple(g.effector for g in goals),
        position=tuple(pos),
        orientation=tuple(ori),
        aim=tuple(aim),
        weight=tuple(w),
        batch=B,
    )


# Joints each effector moves by default (the shortest useful chain), by reach.
_ARM = ("{s}_shoulder", "{s}_elbow", "{s}_wrist")
CHAINS: dict[str, dict[str, tuple[str, ...]]] = {
    "hand": {
        "arm": _ARM,
        "girdle": ("{s}_clavicle", *_ARM),
        "torso": ("lumbar", "thorax", "{s}_clavicle", *_ARM),
    },
    "foot": {"arm": ("{s}_hip", "{s}_knee", "{s}_ankle")},
    "gaze": {
        "arm": ("neck", "head"),
        "girdle": ("neck", "head"),
        "torso": ("thorax", "neck", "head"),
    },
}


def default_dofs(skel: Skeleton, effectors: Sequence[str], reach: str = "arm") -> list[int]:
    """Dofs a solver moves for these effectors: the union of each effector's chain.

    ``reach`` is ``"arm"`` (hand: shoulder, elbow, wrist: 7 dofs), ``"girdle"`` (+ clavicle)
    or ``"torso"`` (+ lumbar and thorax). Feet always use hip, knee, ankle; the gaze neck and
    head. Any other site uses every dof between the root and its joint.
    """
    out: set[int] = set()
    for e in effectors:
        st = skel.site(e)
        side = st.joint[0] if st.joint[:2] in ("r_", "l_") else ""
        kind = (
            "hand"
            if st.joint.endswith("wrist")
            else "foot"
            if st.joint.endswith("ankle")
            else "gaze"
            if st.joint == "head"
            else ""
        )
        if kind:
            table = CHAINS[kind]
            joints = table.get(reach, table["arm"])
            out.update(skel.dofs_of_joints([j.format(s=side) for j in joints]))
        else:
            out.update(skel.chain_dofs(e))
    return sorted(out)
