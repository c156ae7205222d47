"""The manikin's body volumes as capsules, and how deep a hand or forearm goes inside them.

A capsule is a segment between two points of the body (joint centres) and a radius: every point
within the radius of the segment is inside. The body's capsules (trunk, thighs) are the inscribed
ones (half the smaller breadth of the part), so a capsule stays inside the body it stands for;
the limbs tested against them (forearms, hands) are capsules too, with their own radius, so what
is tested is the limb's surface, not its axis. The definition, its sizes and why are in
docs/metrics.md ("hands inside the body"): one definition, which the verify pass reports
(MT0514), the approach and clearance passes avoid, and bench/motion.py measures on its own.

Sizes (GB 10000-88 measures, scaled by stature for a population whose table lacks them):

* trunk: from the pelvis joint (the hip centres' mid-point) to the mid-point of the two
  sternoclavicular joints, radius half the chest depth (men P50: 212 mm, so 106 mm);
* thigh: from the hip joint centre to the knee joint centre, radius half the sitting thigh
  clearance (the thigh's thickness; men P50: 130 mm, so 65 mm);
* forearm: elbow to wrist, radius ``LIMB_RADIUS["forearm"]`` (0.36) of the hand breadth (men
  P50: 30 mm); hand: wrist to fingertip, radius 0.25 of the hand breadth (20 mm), its axis
  ending one radius short of the fingertip so that its surface ends at the fingertip.

Pure geometry on ``Pose`` arrays: numpy only, vectorised over frames.

``self_intersection`` is the check: the depth of the limb's surface in each capsule (the sum of
the radii minus the distance between the two axes). Avoiding the capsules (``clearance``, used
by the clearance pass and ``mtlc.body.ik.clearance``) asks ``CLEARANCE_MARGIN`` more, at
``LIMB_SAMPLES`` points along each limb and at the point of its axis closest to each capsule's
(the deepest), so what the solver leaves is outside with room to spare, not on the edge of
the check.

``collision_capsules`` is the other model, the body's **outer** volume against the equipment
(docs/collision.md): 16 capsules, head, pelvis, abdomen, thorax, and each side's upper arm,
forearm, hand, thigh, shank and foot, each end a point fixed in a joint's frame, so
``capsule_segments`` places them all for every frame in one pass. The forearms, hands and thighs
are the self-contact model's (one definition of each); the rest are sized below.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .anthropometry import measure
from .kinematics import Pose, site_positions
from .skeleton import Skeleton

FloatArray = NDArray[np.float64]

# GB 10000-88 measures the capsules are sized from, and the stature they go with (mm)
TRUNK_MEASURE = "chest_depth"
THIGH_MEASURE = "thigh_clearance_sitting"
REFERENCE_POPULATION = "gb10000_1988"


@dataclass(frozen=True)
class Capsule:
    """A body part's volume: the segment between two joints (or joint mid-points), a radius."""

    name: str
    ends: tuple[tuple[str, ...], tuple[str, ...]]  # joints averaged for each end
    radius: float  # m


@dataclass(frozen=True)
class Limb:
    """A part that must stay outside the capsules: the segment between two body points."""

    name: str
    start: str  # a joint or a site
    end: str


def measure_m(skel: Skeleton, name: str) -> float:
    """A GB 10000-88 measure for the manikin (m): its own row when the manikin is built from
    GB 10000-88, else the same sex and percentile's value scaled by the stature ratio."""
    sex = skel.sex if skel.sex in ("male", "female") else "male"
    pct = skel.percentile if skel.percentile in (1, 5, 10, 50, 90, 95, 99) else 50
    value = measure(REFERENCE_POPULATION, sex, pct, name) / 1000.0
    if skel.population == REFERENCE_POPULATION or skel.dims is None:
        return value
    stature = measure(REFERENCE_POPULATION, sex, pct, "stature") / 1000.0
    return value * skel.dims.stature / stature


def body_capsules(skel: Skeleton) -> tuple[Capsule, ...]:
    """The trunk and the two thighs, sized from the manikin (see the module docstring)."""
    trunk = 0.5 * measure_m(skel, TRUNK_MEASURE)
    thigh = 0.5 * measure_m(skel, THIGH_MEASURE)
    return (
        Capsule("trunk", (("pelvis",), ("r_clavicle", "l_clavicle")), trunk),
        Capsule("right thigh", (("r_hip",), ("r_knee",)), thigh),
        Capsule("left thigh", (("l_hip",), ("l_knee",)), thigh),
    )


# the hands' and forearms' axes: elbow to wrist, wrist to fingertip
ARM_LIMBS = (
    Limb("right forearm", "r_elbow", "r_wrist"),
    Limb("right hand", "r_wrist", "r_fingertip"),
    Limb("left forearm", "l_elbow", "l_wrist"),
    Limb("left hand", "l_wrist", "l_fingertip"),
)
LIMB_SAMPLES = 6  # points along a limb's axis, ends included (a forearm: every 5 cm or so)
SAMPLE_FRACTIONS = np.linspace(0.0, 1.0, LIMB_SAMPLES)  # where along the axis
SAMPLE_FRACTIONS.setflags(write=False)
# a limb's samples against each capsule: the even ones, then the point of its axis closest to
# the capsule's axis (the deepest point: a forearm crossing a thigh between two even samples,
# 5 cm apart, went 2-5 mm into it while every sample was clear, the fuel filter's male P99)
COLUMN_SAMPLES = LIMB_SAMPLES + 1
HAND_BREADTH = "hand_breadth"
# a limb's radius as a fraction of the hand's breadth (men P50: forearm 30 mm, hand 20 mm)
LIMB_RADIUS = {"forearm": 0.36, "hand": 0.25}
CLEARANCE_MARGIN = 0.005  # m the limb's surface keeps outside a capsule when avoiding it


def _point(skel: Skeleton, pose: Pose, name: str) -> FloatArray:
    if name in skel.joint_names:
        return pose.p[..., skel.joint_index(name), :]
    return site_positions(skel, pose, name)


def _capsule_axis(skel: Skeleton, pose: Pose, cap: Capsule) -> tuple[FloatArray, FloatArray]:
    a, b = (_mean_point([pose.p[..., skel.joint_index(j), :] for j in end]) for end in cap.ends)
    return a, b


def _mean_point(points: list[FloatArray]) -> FloatArray:
    """``np.mean(points, axis=0)``; of one or two points without stacking them (a solver's
    one-row residual asked for six means an iteration): the same numbers, x / 1 and
    (x + y) / 2."""
    if len(points) == 1:
        return points[0] / 1.0
    if len(points) == 2:
        return (points[0] + points[1]) / 2.0
    return np.mean(points, axis=0)


def limb_axis(skel: Skeleton, pose: Pose, limb: Limb) -> tuple[FloatArray, FloatArray]:
    """The limb's axis (N, 3) ends: a hand's ends one radius short of its fingertip, where the
    hand's surface ends (the fingertip landmark is on the surface: GB 10000-88's hand length)."""
    p0, p1 = _point(skel, pose, limb.start), _point(skel, pose, limb.end)
    if limb.end.endswith("fingertip"):
        d = p1 - p0
        length = np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)
        p1 = p1 - d / length * np.minimum(limb_radius(skel, limb), 0.5 * length)
    return p0, p1


# -- the collision model: the body's outer volume against the equipment -------------------------

# a capsule's radius as a fraction of the GB 10000-88 measure it is sized from (docs/collision.md)
UPPER_ARM_RADIUS_OF_HAND_BREADTH = 0.5  # men P50: 41 mm (an arm about 8 cm across, as assumed)
CALF_RADIUS_OF_FOOT_BREADTH = 0.5  # the calf about as broad as the foot (men P50: 48 mm)
FOOT_RADIUS_OF_FOOT_BREADTH = 0.3  # the foot's height at the instep (men P50: 29 mm)
# GB 10000-88 gives head breadth 154 mm for men P50 (stature 1678 mm); the table shipped here
# has no head measures, so the head scales with stature
HEAD_BREADTH_OF_STATURE = 154.0 / 1678.0
HEAD_FRONT_OF_EYE = 0.01  # m: the brow's front ahead of the eyes
TOOL_RADIUS = 0.01  # m: a tool with no `radius` (a wrench's handle, a screwdriver's shaft)


@dataclass(frozen=True)
class PartCapsule:
    """A body part (or a held tool) as a capsule: two points, each fixed in a joint's frame
    (joint name, offset in that frame, m), and a radius (m)."""

    name: str
    start: tuple[str, tuple[float, float, float]]
    end: tuple[str, tuple[float, float, float]]
    radius: float


def _vec(*v: float) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _joints(name: str, start: str, end: str, radius: float) -> PartCapsule:
    """A capsule between two joint centres."""
    zero = _vec(0, 0, 0)
    return PartCapsule(name, (start, zero), (end, zero), radius)


def collision_capsules(skel: Skeleton) -> tuple[PartCapsule, ...]:
    """The body's 16 capsules against the equipment, sized from the manikin's anthropometry
    (see the module docstring and docs/collision.md for each size's reason)."""
    stature = measure_m(skel, "stature")
    hand_breadth = measure_m(skel, HAND_BREADTH)
    foot_breadth = measure_m(skel, "foot_breadth")
    chest = 0.5 * measure_m(skel, TRUNK_MEASURE)  # the trunk's half depth
    thigh = next(c.radius for c in body_capsules(skel) if c.name == "right thigh")
    # head: a vertical capsule from the head joint to the vertex, its front at the brow
    head_r = 0.5 * HEAD_BREADTH_OF_STATURE * stature
    eye = skel.site("gaze").offset
    vertex = skel.site("vertex").offset
    z_head = eye[2] + HEAD_FRONT_OF_EYE - head_r
    caps = [
        PartCapsule(
            "head",
            ("head", _vec(0, 0, z_head)),
            ("head", _vec(0, vertex[1] - head_r, z_head)),
            head_r,
        )
    ]
    # trunk: pelvis across the hip joints as broad as the hips, abdomen up the spine, thorax
    # across the chest as broad as the chest, all as deep as the chest
    pelvis_half = max(0.5 * measure_m(skel, "hip_breadth") - chest, 0.0)
    thorax_half = max(0.5 * measure_m(skel, "chest_breadth") - chest, 0.0)
    sc_y = skel.joints[skel.joint_index("r_clavicle")].offset[1]
    zero = _vec(0, 0, 0)
    caps += [
        PartCapsule(
            "pelvis",
            ("pelvis", _vec(-pelvis_half, 0, 0)),
            ("pelvis", _vec(pelvis_half, 0, 0)),
            chest,
        ),
        PartCapsule("abdomen", ("lumbar", zero), ("thorax", zero), chest),
        PartCapsule(
            "thorax",
            ("thorax", _vec(-thorax_half, 0.5 * sc_y, 0)),
            ("thorax", _vec(thorax_half, 0.5 * sc_y, 0)),
            chest,
        ),
    ]
    foot_r = FOOT_RADIUS_OF_FOOT_BREADTH * foot_breadth
    for side, word in (("r", "right"), ("l", "left")):
        forearm, hand = side_limbs(side)
        hand_r = limb_radius(skel, hand)
        tip = np.asarray(skel.site(f"{side}_fingertip").offset, float)
        tip_length = float(np.linalg.norm(tip))
        tip_axis = tip * (1.0 - min(hand_r, 0.5 * tip_length) / tip_length)  # as ``limb_axis``
        heel = skel.site(f"{side}_heel").offset
        toe = skel.site(f"{side}_toe").offset
        heel_axis = _vec(heel[0], heel[1] + foot_r, heel[2] + foot_r)
        toe_axis = _vec(toe[0], toe[1] + foot_r, toe[2] - foot_r)
        caps += [
            _joints(
                f"{word} upper arm",
                f"{side}_shoulder",
                f"{side}_elbow",
                UPPER_ARM_RADIUS_OF_HAND_BREADTH * hand_breadth,
            ),
            _joints(
                f"{word} forearm", f"{side}_elbow", f"{side}_wrist", limb_radius(skel, forearm)
            ),
            PartCapsule(
                f"{word} hand", (f"{side}_wrist", zero), (f"{side}_wrist", _vec(*tip_axis)), hand_r
            ),
            _joints(f"{word} thigh", f"{side}_hip", f"{side}_knee", thigh),
            _joints(
                f"{word} shank",
                f"{side}_knee",
                f"{side}_ankle",
                CALF_RADIUS_OF_FOOT_BREADTH * foot_breadth,
            ),
            PartCapsule(
                f"{word} foot", (f"{side}_ankle", heel_axis), (f"{side}_toes", toe_axis), foot_r
            ),
        ]
    return tuple(caps)


def tool_capsule(skel: Skeleton, tool_site: str, tool: dict[str, object]) -> PartCapsule:
    """A held tool as a capsule from the hand's grip point to the tool's working point (the
    site the tool pass adds for it, ``r_tool_wrench_10mm``), its radius the tool's ``radius``
    or ``TOOL_RADIUS``."""
    hand = skel.site(f"{tool_site[0]}_hand")
    tip = skel.site(tool_site)
    radius = tool.get("radius", TOOL_RADIUS)
    return PartCapsule(
        f"tool {tool.get('name', tool_site)}",
        (hand.joint, _vec(*hand.offset)),
        (tip.joint, _vec(*tip.offset)),
        float(radius) if isinstance(radius, int | float) else TOOL_RADIUS,
    )


def capsule_segments(
    skel: Skeleton, pose: Pose, caps: tuple[PartCapsule, ...]
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The capsules' axes in the world for every frame of ``pose``: start and end points
    (..., C, 3), and the radii (C,). One gather and one batched rotation per end."""
    if not caps:
        shape = (*pose.batch_shape, 0, 3)
        return np.zeros(shape), np.zeros(shape), np.zeros(0)
    ends = []
    for which in ("start", "end"):
        js = [skel.joint_index(getattr(c, which)[0]) for c in caps]
        offs = np.array([getattr(c, which)[1] for c in caps], dtype=float)
        ends.append(pose.p[..., js, :] + np.einsum("...cij,cj->...ci", pose.R[..., js, :, :], offs))
    return ends[0], ends[1], np.array([c.radius for c in caps])


def segment_distance(p1: FloatArray, q1: FloatArray, p2: FloatArray, q2: FloatArray) -> FloatArray:
    """(N,) the closest distance between segments ``p1``-``q1`` and ``p2``-``q2`` (each (N, 3))."""
    s, t = closest_parameters(p1, q1, p2, q2)
    return np.linalg.norm(p1 + s[..., None] * (q1 - p1) - p2 - t[..., None] * (q2 - p2), axis=-1)


def closest_parameters(
    p1: FloatArray, q1: FloatArray, p2: FloatArray, q2: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """(s, t) (...,) where along segments ``p1``-``q1`` and ``p2``-``q2`` (each (..., 3)) their
    closest points are, as fractions of each: the parameters clamped to the segments (Ericson,
    Real-Time Collision Detection, 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.maximum(np.einsum("...c,...c->...", d1, d1), 1e-18)
    e = np.maximum(np.einsum("...c,...c->...", d2, d2), 1e-18)
    b, c, f = (np.einsum("...c,...c->...", x, y) for x, y in ((d1, d2), (d1, r), (d2, r)))
    denom = a * e - b * b
    s = np.where(denom > 1e-18, np.clip((b * f - c * e) / np.maximum(denom, 1e-18), 0.0, 1.0), 0.0)
    t = (b * s + f) / e
    s = np.where(
        t < 0.0, np.clip(-c / a, 0.0, 1.0), np.where(t > 1.0, np.clip((b - c) / a, 0.0, 1.0), s)
    )
    return s, np.clip(t, 0.0, 1.0)


def depth_inside(points: FloatArray, a: FloatArray, b: FloatArray, radius: float) -> FloatArray:
    """How deep (m, positive inside, negative outside) each point (N, K, 3) is inside the
    capsule of axis ``a``-``b`` (N, 3) and ``radius``."""
    d = (b - a)[:, None, :]
    rel = points - a[:, None, :]
    length2 = np.maximum(np.einsum("nkc,nkc->nk", d, d), 1e-18)
    t = np.clip(np.einsum("nkc,nkc->nk", rel, d) / length2, 0.0, 1.0)
    dist = np.linalg.norm(rel - t[..., None] * d, axis=-1)
    return radius - dist


def self_intersection(
    skel: Skeleton, pose: Pose, limbs: tuple[Limb, ...] = ARM_LIMBS
) -> tuple[FloatArray, list[tuple[str, str]]]:
    """(N, L·C) depth of each limb's surface inside each capsule per frame (m: the limb's radius
    plus the capsule's minus the distance between their axes; negative when it stays outside),
    and the (limb, capsule) pairs in column order. A limb is never tested against the capsule
    it is attached to (none of the arms' are)."""
    caps = body_capsules(skel)
    cols: list[FloatArray] = []
    pairs: list[tuple[str, str]] = []
    axes = [(cap, *_capsule_axis(skel, pose, cap)) for cap in caps]
    for limb in limbs:
        p0, p1 = limb_axis(skel, pose, limb)
        p0, p1 = np.reshape(p0, (-1, 3)), np.reshape(p1, (-1, 3))
        r = limb_radius(skel, limb)
        for cap, a, b in axes:
            a, b = (
                np.broadcast_to(np.reshape(a, (-1, 3)), p0.shape),
                np.broadcast_to(np.reshape(b, (-1, 3)), p0.shape),
            )
            cols.append(r + cap.radius - segment_distance(p0, p1, a, b))
            pairs.append((limb.name, cap.name))
    return np.stack(cols, axis=1), pairs


def measured_points(skel: Skeleton, limbs: tuple[Limb, ...]) -> tuple[str, ...]:
    """The joints and sites whose positions ``self_intersection`` and ``clearance`` of
    ``limbs`` read (the capsules' ends and the limbs'): what a ``forward_part`` poses for them
    (the other arm, the head and the feet left out, the same numbers)."""
    names = [j for cap in body_capsules(skel) for end in cap.ends for j in end]
    return tuple(dict.fromkeys([*names, *(n for limb in limbs for n in (limb.start, limb.end))]))


def limb_radius(skel: Skeleton, limb: Limb) -> float:
    """The limb's own radius (m): ``LIMB_RADIUS`` of the manikin's hand breadth."""
    kind = "hand" if limb.name.endswith("hand") else "forearm"
    return LIMB_RADIUS[kind] * measure_m(skel, HAND_BREADTH)


def side_limbs(side: str) -> tuple[Limb, ...]:
    """The forearm and hand of one side ("r" or "l")."""
    prefix = "right " if side == "r" else "left "
    return tuple(limb for limb in ARM_LIMBS if limb.name.startswith(prefix))


def limbs_of_sides(sides: Collection[str]) -> tuple[Limb, ...]:
    """The forearms and hands of ``sides`` ("r", "l"), in ``ARM_LIMBS``' order: what a check
    of one arm's reach passes to ``self_intersection`` (the other arm's columns, half the
    work, were computed and dropped)."""
    return tuple(limb for limb in ARM_LIMBS if limb.name.split()[0][0] in sides)


def clearance(
    skel: Skeleton, pose: Pose, limbs: tuple[Limb, ...], margin: float = CLEARANCE_MARGIN
) -> FloatArray:
    """(N, L·C·S') how far (m) each sample point of each limb's surface is inside each capsule
    grown by ``margin`` (``COLUMN_SAMPLES`` a limb and capsule, the last the point closest to
    the capsule's axis, so the deepest sample is ``self_intersection``'s depth plus the
    margin): positive where the limb must move out, negative where it is clear. The
    avoidance's residual; ``self_intersection`` is the check."""
    return _clearance(skel, pose, limbs, margin, directions=False)[0]


def segment_clearance(
    skel: Skeleton,
    pose: Pose,
    start: FloatArray,
    end: FloatArray,
    radius: float,
    margin: float = CLEARANCE_MARGIN,
) -> FloatArray:
    """(N, ...) how far (m) the surface of a limb of ``radius`` whose axis runs from ``start``
    to ``end`` (N, ..., 3: several candidate axes per pose) goes into the trunk or a thigh of
    ``pose`` (N rows) grown by ``margin``: ``clearance``'s measure (its capsules, its deepest
    sample: the point of the axis closest to each capsule's) of an axis that is not the pose's
    own, deepest capsule. Positive: inside."""
    lead = start.shape[:-1]
    extra = (1,) * (len(lead) - 1)
    out = np.full(lead, -np.inf)
    for cap in body_capsules(skel):
        a, b = (x.reshape(len(x), *extra, 3) for x in _capsule_axis(skel, pose, cap))
        depth = cap.radius + radius + margin - segment_distance(start, end, a, b)
        np.maximum(out, depth, out=out)
    return out


def clearance_directions(
    skel: Skeleton, pose: Pose, limbs: tuple[Limb, ...], margin: float = CLEARANCE_MARGIN
) -> tuple[FloatArray, FloatArray]:
    """``clearance`` (N, L·C·S') and each column's derivative by its sample point
    (N, L·C·S', 3) (``sample_fractions``: where the samples are): minus the unit direction
    from the capsule axis's closest point to the sample (the closest point slides along the
    axis, at right angles to that direction, so it adds nothing; zero on the axis). The
    avoidance's residual and what its analytic Jacobian needs, from one pass over the
    samples."""
    depth, direction = _clearance(skel, pose, limbs, margin, directions=True)
    assert direction is not None
    return depth, direction


def sample_fractions(skel: Skeleton, pose: Pose, limbs: tuple[Limb, ...]) -> FloatArray:
    """(N, L, C, S') where along each limb's axis (0 at its start, 1 at its end) its samples
    against each capsule are: ``SAMPLE_FRACTIONS``, then the point closest to the capsule's
    axis (``COLUMN_SAMPLES``): ``clearance``'s columns in order."""
    caps = body_capsules(skel)
    ends = [_capsule_axis(skel, pose, cap) for cap in caps]
    a, b = np.stack([e[0] for e in ends], axis=1), np.stack([e[1] for e in ends], axis=1)
    return np.stack([_fractions(*limb_axis(skel, pose, limb), a, b) for limb in limbs], axis=1)


def _fractions(p0: FloatArray, p1: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """(N, C, S') a limb's sample fractions against capsules of axes ``a``-``b`` (N, C, 3)."""
    n, c = a.shape[:2]
    s, _ = closest_parameters(p0[:, None], p1[:, None], a, b)
    return np.concatenate([np.broadcast_to(SAMPLE_FRACTIONS, (n, c, LIMB_SAMPLES)),
                           s[..., None]], axis=-1)  # fmt: skip


def _clearance(
    skel: Skeleton, pose: Pose, limbs: tuple[Limb, ...], margin: float, directions: bool
) -> tuple[FloatArray, FloatArray | None]:
    """``clearance`` (and its directions), every capsule of a limb at once: the same
    arithmetic, number for number, as ``depth_inside`` capsule by capsule at the points
    ``sample_fractions`` places."""
    caps = body_capsules(skel)
    ends = [_capsule_axis(skel, pose, cap) for cap in caps]
    a = np.stack([e[0] for e in ends], axis=1)[:, :, None, :]  # (N, C, 1, 3)
    d = np.stack([e[1] - e[0] for e in ends], axis=1)[:, :, None, :]
    length2 = np.maximum(np.einsum("ncsx,ncsx->ncs", d, d), 1e-18)
    radii = np.array([cap.radius for cap in caps])[None, :, None]
    depths: list[FloatArray] = []
    dirs: list[FloatArray] = []
    for limb in limbs:
        p0, p1 = limb_axis(skel, pose, limb)
        frac = _fractions(p0, p1, a[:, :, 0], a[:, :, 0] + d[:, :, 0])  # (N, C, S')
        pts = p0[:, None, None, :] + frac[..., None] * (p1 - p0)[:, None, None, :]
        rel = pts - a  # (N, C, S', 3)
        t = np.clip(np.einsum("ncsx,ncsx->ncs", rel, d) / length2, 0.0, 1.0)
        away = rel - t[..., None] * d
        dist = np.linalg.norm(away, axis=-1)
        depths.append((radii + (limb_radius(skel, limb) + margin)) - dist)
        if directions:
            dirs.append(-away / np.where(dist > 0.0, dist, np.inf)[..., None])
    n = len(depths[0])
    depth = np.concatenate(depths, axis=1).reshape(n, -1)
    return depth, np.concatenate(dirs, axis=1).reshape(n, -1, 3) if directions else None
