"""The manikin's skeleton: one joint naming table, offsets, degrees of freedom, limits, masses.

Conventions (fixed for the whole project): SI units; world right-handed with **Y up**, the
ground at Y = 0; at the neutral pose (all angles 0) the manikin stands upright facing **+Z**,
its left is **+X**, arms hanging with the palms towards the thighs (forearm mid-position).

Forward kinematics follows ``shared/design/IR.md`` exactly: joints are listed parents first; a
joint's world transform is its parent's world transform, then a translation by ``offset`` (in
the parent's frame), then ``R(axis_1, q_1) · R(axis_2, q_2) · …``. The root (``pelvis``, at the
mid-point of the hip joint centres, offset zero, no degrees of freedom of its own) takes the
frame's root position and unit quaternion (w first) instead of a parent. At the neutral pose
every joint frame is parallel to the world, so offsets are simply differences of joint-centre
positions.

Every positive angle is the anatomically named motion (flexion, abduction, internal rotation,
pronation, radial deviation, dorsiflexion, inversion; for the spine and neck flexion, lateral
flexion to the right and rotation to the left). Left-side axes mirror the right ones through
the sagittal plane: ``(a_x, -a_y, -a_z)``.

Limits come from ``joint_limits.csv`` (AAOS via Norkin & White Table A.1, Merck Manual, US VA
38 CFR 4.71a; spine and neck low confidence), masses and centres of mass from de Leva (1996)
Table 4 in ``segment_mass.csv``. See ``docs/body.md`` for the table and the derivations.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .anthropometry import (
    HEAD_JOINT_BELOW_EYE,
    NECK_ABOVE_ACROMION,
    STERNOCLAVICULAR_BELOW_ACROMION,
    Dimensions,
    citation,
    dimensions,
    table_rows,
)

Vec3 = tuple[float, float, float]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Dof:
    """One rotational degree of freedom: an angle about a unit axis in the joint's frame."""

    name: str
    axis: Vec3
    min: float
    max: float


@dataclass(frozen=True)
class Joint:
    """A joint and the rigid segment it carries (its mass and centre of mass, joint frame)."""

    name: str
    parent: str | None
    offset: Vec3
    dofs: tuple[Dof, ...]
    mass: float
    com: Vec3
    description: str = ""


@dataclass(frozen=True)
class Site:
    """A point fixed in a joint's frame: an effector, a contact point or a landmark.

    ``direction`` (unit, joint frame) is set for sites that aim, such as the gaze.
    """

    name: str
    joint: str
    offset: Vec3
    kind: str
    direction: Vec3 | None = None


# ----------------------------------------------------------------------------------------
# The naming table. (name, parent, description). Side-specific joints exist as r_*/l_*.
# ----------------------------------------------------------------------------------------
JOINT_TABLE: tuple[tuple[str, str | None, str], ...] = (
    ("pelvis", None, "root; mid-point of the hip joint centres; carries the lower trunk"),
    ("lumbar", "pelvis", "lumbar spine (about L5/S1-L3); carries the middle trunk"),
    ("thorax", "lumbar", "thoracolumbar junction (T12/L1, xiphoid level); carries the upper trunk"),
    ("neck", "thorax", "lower cervical spine (C7/T1)"),
    ("head", "neck", "atlanto-occipital joint; carries the head and neck mass"),
    ("r_clavicle", "thorax", "right sternoclavicular joint (shoulder girdle)"),
    ("r_shoulder", "r_clavicle", "right glenohumeral joint centre; carries the upper arm"),
    ("r_elbow", "r_shoulder", "right elbow joint centre (+ forearm rotation); carries the forearm"),
    ("r_wrist", "r_elbow", "right wrist joint centre; carries the hand"),
    ("l_clavicle", "thorax", "left sternoclavicular joint (shoulder girdle)"),
    ("l_shoulder", "l_clavicle", "left glenohumeral joint centre; carries the upper arm"),
    ("l_elbow", "l_shoulder", "left elbow joint centre (+ forearm rotation); carries the forearm"),
    ("l_wrist", "l_elbow", "left wrist joint centre; carries the hand"),
    ("r_hip", "pelvis", "right hip joint centre; carries the thigh"),
    ("r_knee", "r_hip", "right knee joint centre; carries the shank"),
    ("r_ankle", "r_knee", "right ankle joint centre (talocrural + subtalar); carries the foot"),
    ("l_hip", "pelvis", "left hip joint centre; carries the thigh"),
    ("l_knee", "l_hip", "left knee joint centre; carries the shank"),
    ("l_ankle", "l_knee", "left ankle joint centre (talocrural + subtalar); carries the foot"),
    # last, so that the older joints keep their dof columns (the toes came with issue 18)
    (
        "r_toes",
        "r_ankle",
        "right metatarsophalangeal joints, mid-ball; the toes (no mass of their own)",
    ),
    (
        "l_toes",
        "l_ankle",
        "left metatarsophalangeal joints, mid-ball; the toes (no mass of their own)",
    ),
)

# Degrees of freedom per joint (right side and axial); each entry is
# (suffix, right-side axis, (csv joint, csv motion, fraction) for min, (...) for max).
# A limit spec of a float is a value in degrees that joint_limits.csv does not hold.
_LimitSpec = tuple[str, str, float] | float
_DOF_TABLE: dict[str, tuple[tuple[str, Vec3, _LimitSpec, _LimitSpec], ...]] = {
    # Spine: thoracolumbar ranges split between lumbar and thorax (assumed shares).
    "lumbar": (
        (
            "flex",
            (1.0, 0.0, 0.0),
            ("trunk (lumbar)", "extension", 1.0),
            ("trunk (lumbar)", "flexion", 1.0),
        ),
        (
            "lat",
            (0.0, 0.0, 1.0),
            ("trunk (lumbar)", "lateral flexion (each side)", 1.0),
            ("trunk (lumbar)", "lateral flexion (each side)", 1.0),
        ),
        (
            "rot",
            (0.0, 1.0, 0.0),
            ("trunk (thoracolumbar)", "rotation (each side)", 1 / 3),
            ("trunk (thoracolumbar)", "rotation (each side)", 1 / 3),
        ),
    ),
    "thorax": (
        (
            "flex",
            (1.0, 0.0, 0.0),
            ("trunk (lumbar)", "extension", 0.5),
            ("trunk (lumbar)", "flexion", 0.5),
        ),
        (
            "lat",
            (0.0, 0.0, 1.0),
            ("trunk (lumbar)", "lateral flexion (each side)", 0.5),
            ("trunk (lumbar)", "lateral flexion (each side)", 0.5),
        ),
        (
            "rot",
            (0.0, 1.0, 0.0),
            ("trunk (thoracolumbar)", "rotation (each side)", 2 / 3),
            ("trunk (thoracolumbar)", "rotation (each side)", 2 / 3),
        ),
    ),
    # Cervical ranges split 3/4 (C7..C1) and 1/4 (atlanto-occipital); rotation all in the neck.
    "neck": (
        (
            "flex",
            (1.0, 0.0, 0.0),
            ("neck (cervical)", "extension", 0.75),
            ("neck (cervical)", "flexion", 0.7),
        ),
        (
            "lat",
            (0.0, 0.0, 1.0),
            ("neck (cervical)", "lateral flexion (each side)", 0.75),
            ("neck (cervical)", "lateral flexion (each side)", 0.75),
        ),
        (
            "rot",
            (0.0, 1.0, 0.0),
            ("neck (cervical)", "rotation (each side)", 1.0),
            ("neck (cervical)", "rotation (each side)", 1.0),
        ),
    ),
    "head": (
        (
            "flex",
            (1.0, 0.0, 0.0),
            ("neck (cervical)", "extension", 0.25),
            ("neck (cervical)", "flexion", 0.3),
        ),
        (
            "lat",
            (0.0, 0.0, 1.0),
            ("neck (cervical)", "lateral flexion (each side)", 0.25),
            ("neck (cervical)", "lateral flexion (each side)", 0.25),
        ),
    ),
    # Shoulder girdle: not in joint_limits.csv; modest assumed ranges (degrees).
    "clavicle": (
        ("elev", (0.0, 0.0, -1.0), 10.0, 30.0),
        ("prot", (0.0, 1.0, 0.0), 15.0, 15.0),
    ),
    "shoulder": (
        ("flex", (-1.0, 0.0, 0.0), ("shoulder", "extension", 1.0), ("shoulder", "flexion", 1.0)),
        (
            "abd",
            (0.0, 0.0, -1.0),
            ("shoulder", "adduction (across midline from neutral)", 1.0),
            ("shoulder", "abduction", 1.0),
        ),
        (
            "rot",
            (0.0, 1.0, 0.0),
            ("shoulder", "external (lateral) rotation", 1.0),
            ("shoulder", "internal (medial) rotation", 1.0),
        ),
    ),
    "elbow": (
        ("flex", (-1.0, 0.0, 0.0), ("elbow", "extension", 1.0), ("elbow", "flexion", 1.0)),
        ("pro", (0.0, 1.0, 0.0), ("forearm", "supination", 1.0), ("forearm", "pronation", 1.0)),
    ),
    "wrist": (
        (
            "flex",
            (0.0, 0.0, 1.0),
            ("wrist", "extension (dorsiflexion)", 1.0),
            ("wrist", "flexion (palmar)", 1.0),
        ),
        (
            "dev",
            (-1.0, 0.0, 0.0),
            ("wrist", "ulnar deviation", 1.0),
            ("wrist", "radial deviation", 1.0),
        ),
    ),
    "hip": (
        (
            "flex",
            (-1.0, 0.0, 0.0),
            ("hip", "extension (hyperextension)", 1.0),
            ("hip", "flexion", 1.0),
        ),
        (
            "abd",
            (0.0, 0.0, -1.0),
            ("hip", "adduction (across midline)", 1.0),
            ("hip", "abduction", 1.0),
        ),
        (
            "rot",
            (0.0, 1.0, 0.0),
            ("hip", "external (lateral) rotation", 1.0),
            ("hip", "internal (medial) rotation", 1.0),
        ),
    ),
    "knee": (("flex", (1.0, 0.0, 0.0), ("knee", "extension", 1.0), ("knee", "flexion", 1.0)),),
    "ankle": (
        (
            "dorsi",
            (-1.0, 0.0, 0.0),
            ("ankle", "plantarflexion", 1.0),
            ("ankle", "dorsiflexion", 1.0),
        ),
        (
            "inv",
            (0.0, 0.0, 1.0),
            ("foot (subtalar)", "eversion", 1.0),
            ("foot (subtalar)", "inversion", 1.0),
        ),
    ),
    # the toes bend at the balls: a heel-up foot (kneeling on tucked toes, a lunge) rests on
    # its balls and toes, as a person's does, not on the tip of a rigid foot
    "toes": (
        (
            "dorsi",
            (-1.0, 0.0, 0.0),
            ("toes (MTP)", "flexion", 1.0),
            ("toes (MTP)", "extension", 1.0),
        ),
    ),
}

# A comfortable, relaxed standing posture used as the null-space target of the TA solver
# (radians; anything not listed is 0). Slightly flexed elbows and knees, relaxed forearms.
COMFORT_POSTURE: dict[str, float] = {
    "shoulder_flex": 0.15,
    "shoulder_abd": 0.1,
    "shoulder_rot": 0.2,
    "elbow_flex": 0.6,
    "elbow_pro": 0.3,
    "wrist_flex": 0.0,
    "hip_flex": 0.05,
    "knee_flex": 0.08,
    # knee − hip: the soles level under an upright pelvis (0 raised the heels 7 mm, and a heel
    # off the floor bears no weight: docs/metrics.md, "Support")
    "ankle_dorsi": 0.03,
}


@functools.cache
def _limits_deg() -> dict[tuple[str, str], float]:
    return {(r["joint"], r["motion"]): float(r["limit_deg"]) for r in table_rows("joint_limits")}


def _limit(spec: _LimitSpec) -> float:
    if isinstance(spec, float):
        return math.radians(spec)
    joint, motion, frac = spec
    return math.radians(_limits_deg()[(joint, motion)] * frac)


@functools.cache
def _de_leva(sex: str) -> dict[str, tuple[float, float, float]]:
    """segment -> (mass fraction, CoM fraction from proximal end, reference length / stature)."""
    ref_h = {"male": 1.741, "female": 1.735}[sex]
    out: dict[str, tuple[float, float, float]] = {}
    for r in table_rows("segment_mass"):
        if r["model"] == "deLeva1996" and r["sex"] == sex:
            out[r["segment"]] = (
                float(r["mass_fraction"]),
                float(r["com_from_proximal_fraction"]),
                float(r["ref_length_m"]) / ref_h,
            )
    return out


def _mirror(axis: Vec3) -> Vec3:
    """Axis of the left-side twin of a right-side rotation (reflection x -> -x)."""
    return (axis[0], -axis[1] if axis[1] else 0.0, -axis[2] if axis[2] else 0.0)


def _side_x(x: float, side: str) -> float:
    return -x if side == "r" else x


# Ratios that are modelling assumptions (documented in docs/body.md).
HIP_CENTRE_SEPARATION_OF_HIP_BREADTH = 0.56
STERNOCLAVICULAR_HALF_WIDTH = 0.012  # fraction of stature
GRIP_FRACTION_OF_HAND = 0.4
HEEL_BEHIND_ANKLE_OF_FOOT = 0.22
BALL_FROM_HEEL_OF_FOOT = 0.72
EYE_IN_FRONT_OF_HEAD_JOINT = 0.05  # fraction of stature


@dataclass(eq=False)
class Skeleton:
    """A manikin: joints (parents first), sites, and the numpy arrays kinematics runs on.

    Build one with :func:`build_manikin`. The dataclass fields are the serialisable facts;
    the arrays (``parent``, ``offsets``, ``dof_axis`` …) are derived in ``__post_init__``.
    """

    joints: tuple[Joint, ...]
    sites: tuple[Site, ...]
    population: str = "custom"
    sex: str = ""
    percentile: int = 0
    dims: Dimensions | None = None
    comfort: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        names = [j.name for j in self.joints]
        if len(set(names)) != len(names):
            raise ValueError("duplicate joint names")
        self.joint_names: tuple[str, ...] = tuple(names)
        self._jidx = {n: i for i, n in enumerate(names)}
        par = []
        for i, j in enumerate(self.joints):
            if j.parent is None:
                if i != 0:
                    raise ValueError("only the first joint may be the root")
                par.append(-1)
            else:
                pi = self._jidx.get(j.parent, -1)
                if pi < 0 or pi >= i:
                    raise ValueError(f"joint {j.name}: parent {j.parent} must be listed before it")
                par.append(pi)
        self.parent: NDArray[np.intp] = np.asarray(par, dtype=np.intp)
        self.offsets: FloatArray = np.array([j.offset for j in self.joints], dtype=float)
        self.masses: FloatArray = np.array([j.mass for j in self.joints], dtype=float)
        self.coms: FloatArray = np.array([j.com for j in self.joints], dtype=float)
        dofs = [d for j in self.joints for d in j.dofs]
        self.dofs: tuple[Dof, ...] = tuple(dofs)
        self.dof_names: tuple[str, ...] = tuple(d.name for d in dofs)
        self._didx = {n: i for i, n in enumerate(self.dof_names)}
        self.dof_joint: NDArray[np.intp] = np.array(
            [i for i, j in enumerate(self.joints) for _ in j.dofs], dtype=np.intp
        )
        ax = np.array([d.axis for d in dofs], dtype=float).reshape(-1, 3)
        self.dof_axis: FloatArray = ax / np.linalg.norm(ax, axis=1, keepdims=True)
        self.lower: FloatArray = np.array([d.min for d in dofs], dtype=float)
        self.upper: FloatArray = np.array([d.max for d in dofs], dtype=float)
        starts, s = [], 0
        for j in self.joints:
            starts.append(s)
            s += len(j.dofs)
        self.joint_dof_start: NDArray[np.intp] = np.asarray(starts, dtype=np.intp)
        self.joint_dof_count: NDArray[np.intp] = np.array(
            [len(j.dofs) for j in self.joints], dtype=np.intp
        )
        # ancestor[j, k]: joint k is j or an ancestor of j.
        nj = len(self.joints)
        anc = np.zeros((nj, nj), dtype=bool)
        for i in range(nj):
            k = i
            while k >= 0:
                anc[i, k] = True
                k = int(self.parent[k])
        self.ancestor: NDArray[np.bool_] = anc
        self._sidx = {s.name: i for i, s in enumerate(self.sites)}
        if len(self._sidx) != len(self.sites):
            raise ValueError("duplicate site names")
        for st in self.sites:
            if st.joint not in self._jidx:
                raise ValueError(f"site {st.name}: unknown joint {st.joint}")
        q = np.zeros(len(dofs))
        for i, n in enumerate(self.dof_names):
            key = n[2:] if n[:2] in ("r_", "l_") else n
            q[i] = self.comfort.get(key, 0.0)
        self.q_comfort: FloatArray = np.clip(q, self.lower, self.upper)

    # -- look-ups --------------------------------------------------------------------------
    @property
    def n_dofs(self) -> int:
        """Number of joint angles (the root's 6 not included)."""
        return len(self.dofs)

    @property
    def n_joints(self) -> int:
        """Number of joints, the root included."""
        return len(self.joints)

    @property
    def total_mass(self) -> float:
        """Sum of the segment masses (kg)."""
        return float(self.masses.sum())

    def joint_index(self, name: str) -> int:
        """Index of a joint by name (KeyError with the known names otherwise)."""
        try:
            return self._jidx[name]
        except KeyError:
            raise KeyError(
                f"unknown joint {name!r}; known: {', '.join(self.joint_names)}"
            ) from None

    def dof_index(self, name: str) -> int:
        """Index of a degree of freedom by name."""
        try:
            return self._didx[name]
        except KeyError:
            raise KeyError(f"unknown dof {name!r}; known: {', '.join(self.dof_names)}") from None

    def site(self, name: str) -> Site:
        """A site (effector, contact point or landmark) by name."""
        try:
            return self.sites[self._sidx[name]]
        except KeyError:
            known = ", ".join(s.name for s in self.sites)
            raise KeyError(f"unknown site {name!r}; known: {known}") from None

    def sites_of_kind(self, kind: str) -> tuple[Site, ...]:
        """All sites of one kind: 'effector', 'contact' or 'landmark'."""
        return tuple(s for s in self.sites if s.kind == kind)

    def dofs_of_joints(self, joints: Sequence[str]) -> list[int]:
        """Indices of every dof of the named joints, in skeleton order."""
        out: list[int] = []
        for n in joints:
            j = self.joint_index(n)
            s = int(self.joint_dof_start[j])
            out.extend(range(s, s + int(self.joint_dof_count[j])))
        return sorted(out)

    def chain_dofs(self, site: str, start: str | None = None) -> list[int]:
        """Dofs between joint ``start`` (inclusive; default the root) and a site's joint."""
        j = self.joint_index(self.site(site).joint)
        chain = [k for k in range(self.n_joints) if self.ancestor[j, k]]
        if start is not None:
            s = self.joint_index(start)
            if not self.ancestor[j, s]:
                raise ValueError(f"{start} is not an ancestor of site {site}")
            chain = [k for k in chain if self.ancestor[k, s]]
        return self.dofs_of_joints([self.joint_names[k] for k in chain])

    def clip(self, q: FloatArray) -> FloatArray:
        """Angles clipped into the joint limits."""
        return np.clip(q, self.lower, self.upper)

    def within_limits(self, q: FloatArray, tol: float = 1e-9) -> NDArray[np.bool_]:
        """Per configuration: is every angle within its limits (to ``tol``)?"""
        q = np.asarray(q, dtype=float)
        return np.all((q >= self.lower - tol) & (q <= self.upper + tol), axis=-1)

    def random_q(self, rng: np.random.Generator, n: int, margin: float = 0.0) -> FloatArray:
        """``n`` uniformly random in-limit configurations (``margin`` rad inside each limit)."""
        lo, hi = self.lower + margin, self.upper - margin
        return lo + (hi - lo) * rng.random((n, self.n_dofs))

    @property
    def root_position(self) -> FloatArray:
        """Root (mid-hip) position that stands the neutral manikin on the ground Y = 0."""
        y = self.dims.hip_height if self.dims is not None else 0.0
        return np.array([0.0, y, 0.0])

    @property
    def q_middle(self) -> FloatArray:
        """The middle of every joint range (the benchmark's 'middle seed')."""
        return 0.5 * (self.lower + self.upper)

    # -- serialisation -----------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The IR's ``manikin`` object (plain JSON types, SI units), see IR.md."""

        def r(v: Sequence[float]) -> list[float]:
            return [round(float(x), 6) for x in v]

        return {
            "population": self.population,
            "sex": self.sex,
            "percentile": self.percentile,
            "mass": round(self.total_mass, 4),
            "joints": [
                {
                    "name": j.name,
                    "parent": j.parent,
                    "offset": r(j.offset),
                    "dofs": [
                        {
                            "name": d.name,
                            "axis": r(d.axis),
                            "min": round(d.min, 6),
                            "max": round(d.max, 6),
                        }
                        for d in j.dofs
                    ],
                    "mass": round(j.mass, 4),
                    "com": r(j.com),
                }
                for j in self.joints
            ],
            "effectors": [
                {"name": s.name, "joint": s.joint, "offset": r(s.offset)}
                | ({"direction": r(s.direction)} if s.direction else {})
                for s in self.sites_of_kind("effector")
            ],
            "contact_points": [
                {"name": s.name, "joint": s.joint, "offset": r(s.offset)}
                for s in self.sites_of_kind("contact")
            ],
            "landmarks": [
                {"name": s.name, "joint": s.joint, "offset": r(s.offset)}
                for s in self.sites_of_kind("landmark")
            ],
        }


def _dofs_for(joint: str, kind: str, side: str | None) -> tuple[Dof, ...]:
    out = []
    for suffix, axis, lo, hi in _DOF_TABLE[kind]:
        name = f"{joint}_{suffix}" if side is None else f"{side}_{kind}_{suffix}"
        ax = _mirror(axis) if side == "l" else axis
        out.append(Dof(name, ax, -_limit(lo), _limit(hi)))
    return tuple(out)


def skeleton_from_dimensions(d: Dimensions) -> Skeleton:
    """Build the skeleton for one set of dimensions (see module docstring for conventions).

    Joint-centre heights at the neutral pose, from the floor (H = stature):
    hip = ``d.hip_height``; lumbar and thorax at de Leva's omphalion and xiphoid levels
    (de Leva segment lengths scaled by stature); C7/T1 at acromion + 0.03 H; head joint at
    eye - 0.04 H; sternoclavicular at acromion - 0.02 H; glenohumeral, elbow, wrist, knee and
    ankle from :class:`Dimensions`.
    """
    h = d.stature
    dl = _de_leva(d.sex)
    m = d.mass
    y_hip = d.hip_height
    l_lt, l_mt, l_ut = dl["lower_trunk"][2] * h, dl["middle_trunk"][2] * h, dl["upper_trunk"][2] * h
    y_omph = y_hip + l_lt
    y_xyph = y_omph + l_mt
    y_lumbar = y_hip + 0.5 * l_lt
    y_thorax = y_xyph
    y_neck = d.acromion_height + NECK_ABOVE_ACROMION * h
    y_head = d.eye_height - HEAD_JOINT_BELOW_EYE * h
    y_sc = d.acromion_height - STERNOCLAVICULAR_BELOW_ACROMION * h
    y_sh, y_el, y_wr = d.shoulder_height, d.elbow_height, d.wrist_height
    y_kn, y_an = d.knee_height, d.ankle_height
    x_sh = 0.5 * d.biacromial_breadth
    x_sc = STERNOCLAVICULAR_HALF_WIDTH * h
    x_hip = 0.5 * HIP_CENTRE_SEPARATION_OF_HIP_BREADTH * d.hip_breadth

    def seg(name: str) -> tuple[float, float]:
        return dl[name][0] * m, dl[name][1]

    # Centres of mass along de Leva's own landmarks (trunk pieces: proximal = upper end).
    mf, cf = seg("lower_trunk")
    pelvis_com = (0.0, (1 - cf) * l_lt, 0.0)
    pelvis_mass = mf
    mf, cf = seg("middle_trunk")
    lumbar_mass, lumbar_com = mf, (0.0, y_omph + (1 - cf) * l_mt - y_lumbar, 0.0)
    mf, cf = seg("upper_trunk")
    thorax_mass, thorax_com = mf, (0.0, y_xyph + (1 - cf) * l_ut - y_thorax, 0.0)
    mf, cf = seg("head")
    l_head = dl["head"][2] * h
    head_mass, head_com = mf, (0.0, h - cf * l_head - y_head, 0.0)

    joints: list[Joint] = [
        Joint("pelvis", None, (0.0, 0.0, 0.0), (), pelvis_mass, pelvis_com, JOINT_TABLE[0][2]),
        Joint(
            "lumbar",
            "pelvis",
            (0.0, y_lumbar - y_hip, 0.0),
            _dofs_for("lumbar", "lumbar", None),
            lumbar_mass,
            lumbar_com,
            JOINT_TABLE[1][2],
        ),
        Joint(
            "thorax",
            "lumbar",
            (0.0, y_thorax - y_lumbar, 0.0),
            _dofs_for("thorax", "thorax", None),
            thorax_mass,
            thorax_com,
            JOINT_TABLE[2][2],
        ),
        Joint(
            "neck",
            "thorax",
            (0.0, y_neck - y_thorax, 0.0),
            _dofs_for("neck", "neck", None),
            0.0,
            (0.0, 0.0, 0.0),
            JOINT_TABLE[3][2],
        ),
        Joint(
            "head",
            "neck",
            (0.0, y_head - y_neck, 0.0),
            _dofs_for("head", "head", None),
            head_mass,
            head_com,
            JOINT_TABLE[4][2],
        ),
    ]
    desc = {n: t for n, _, t in JOINT_TABLE}
    for side in ("r", "l"):
        ua_m, ua_c = seg("upper_arm")
        fa_m, fa_c = seg("forearm")
        ha_m, ha_c = seg("hand")
        l_met3 = dl["hand"][2] * h
        joints += [
            Joint(
                f"{side}_clavicle",
                "thorax",
                (_side_x(x_sc, side), y_sc - y_thorax, 0.0),
                _dofs_for("", "clavicle", side),
                0.0,
                (0.0, 0.0, 0.0),
                desc[f"{side}_clavicle"],
            ),
            Joint(
                f"{side}_shoulder",
                f"{side}_clavicle",
                (_side_x(x_sh - x_sc, side), y_sh - y_sc, 0.0),
                _dofs_for("", "shoulder", side),
                ua_m,
                (0.0, -ua_c * (y_sh - y_el), 0.0),
                desc[f"{side}_shoulder"],
            ),
            Joint(
                f"{side}_elbow",
                f"{side}_shoulder",
                (0.0, y_el - y_sh, 0.0),
                _dofs_for("", "elbow", side),
                fa_m,
                (0.0, -fa_c * (y_el - y_wr), 0.0),
                desc[f"{side}_elbow"],
            ),
            Joint(
                f"{side}_wrist",
                f"{side}_elbow",
                (0.0, y_wr - y_el, 0.0),
                _dofs_for("", "wrist", side),
                ha_m,
                (0.0, -ha_c * l_met3, 0.0),
                desc[f"{side}_wrist"],
            ),
        ]
    for side in ("r", "l"):
        th_m, th_c = seg("thigh")
        sh_m, sh_c = seg("shank")
        ft_m, ft_c = seg("foot")
        lf = d.foot_length
        joints += [
            Joint(
                f"{side}_hip",
                "pelvis",
                (_side_x(x_hip, side), 0.0, 0.0),
                _dofs_for("", "hip", side),
                th_m,
                (0.0, -th_c * (y_hip - y_kn), 0.0),
                desc[f"{side}_hip"],
            ),
            Joint(
                f"{side}_knee",
                f"{side}_hip",
                (0.0, y_kn - y_hip, 0.0),
                _dofs_for("", "knee", side),
                sh_m,
                (0.0, -sh_c * (y_kn - y_an), 0.0),
                desc[f"{side}_knee"],
            ),
            Joint(
                f"{side}_ankle",
                f"{side}_knee",
                (0.0, y_an - y_kn, 0.0),
                _dofs_for("", "ankle", side),
                ft_m,
                (0.0, -0.5 * y_an, (ft_c - HEEL_BEHIND_ANKLE_OF_FOOT) * lf),
                desc[f"{side}_ankle"],
            ),
            Joint(
                f"{side}_toes",
                f"{side}_ankle",
                (0.0, -y_an, (BALL_FROM_HEEL_OF_FOOT - HEEL_BEHIND_ANKLE_OF_FOOT) * lf),
                _dofs_for("", "toes", side),
                0.0,
                (0.0, 0.0, 0.0),
                desc[f"{side}_toes"],
            ),
        ]
    # de Leva's rounded fractions sum to 0.9999 for women: rescale to the table's body mass.
    scale = m / sum(j.mass for j in joints)
    joints = [replace(j, mass=j.mass * scale) for j in joints]
    # Keep the naming table's order (parents first).
    order = {n: i for i, (n, _, _) in enumerate(JOINT_TABLE)}
    joints.sort(key=lambda j: order[j.name])

    sites: list[Site] = [
        Site(
            "gaze",
            "head",
            (0.0, d.eye_height - y_head, EYE_IN_FRONT_OF_HEAD_JOINT * h),
            "effector",
            (0.0, 0.0, 1.0),
        ),
    ]
    for side in ("r", "l"):
        sites += [
            Site(
                f"{side}_hand",
                f"{side}_wrist",
                (0.0, -GRIP_FRACTION_OF_HAND * d.hand_length, 0.0),
                "effector",
            ),
            Site(f"{side}_foot", f"{side}_ankle", (0.0, 0.0, 0.0), "effector"),
        ]
    for side in ("r", "l"):
        lf, fb = d.foot_length, d.foot_breadth
        heel_z = -HEEL_BEHIND_ANKLE_OF_FOOT * lf
        ball_z = heel_z + BALL_FROM_HEEL_OF_FOOT * lf
        sites += [
            Site(f"{side}_heel", f"{side}_ankle", (0.0, -y_an, heel_z), "contact"),
            Site(
                f"{side}_toe",
                f"{side}_toes",
                (0.0, 0.0, (1.0 - BALL_FROM_HEEL_OF_FOOT) * lf),
                "contact",
            ),
            Site(
                f"{side}_ball_med",
                f"{side}_ankle",
                (_side_x(-0.5 * fb, side), -y_an, ball_z),
                "contact",
            ),
            Site(
                f"{side}_ball_lat",
                f"{side}_ankle",
                (_side_x(0.5 * fb, side), -y_an, ball_z),
                "contact",
            ),
        ]
    sites += [Site("vertex", "head", (0.0, h - y_head, 0.0), "landmark")]
    for side in ("r", "l"):
        acr = (_side_x(x_sh - x_sc, side), d.acromion_height - y_sc, 0.0)
        sites += [
            Site(f"{side}_acromion", f"{side}_clavicle", acr, "landmark"),
            Site(f"{side}_fingertip", f"{side}_wrist", (0.0, -d.hand_length, 0.0), "landmark"),
        ]
    return Skeleton(
        joints=tuple(joints),
        sites=tuple(sites),
        population=d.population,
        sex=d.sex,
        percentile=d.percentile,
        dims=d,
        comfort=dict(COMFORT_POSTURE),
    )


@functools.cache
def build_manikin(
    population: str = "gb10000_1988", sex: str = "male", percentile: int = 50
) -> Skeleton:
    """The manikin for one population, sex and percentile (cached: treat it as read-only).

    >>> sk = build_manikin("gb10000_1988", "female", 5)
    >>> sk.n_dofs
    41
    """
    return skeleton_from_dimensions(dimensions(population, sex, percentile))


def data_citations() -> dict[str, str]:
    """Citation headers of every table the body model uses."""
    names = ("gb10000_1988", "ansur2", "drillis_contini", "joint_limits", "segment_mass")
    return {n: citation(n) for n in names}
