"""RULA, the Rapid Upper Limb Assessment, scored per frame from the manikin's pose.

McAtamney & Corlett 1993, "RULA: a survey method for the investigation of work-related upper
limb disorders", Applied Ergonomics 24(2):91-99. The posture bands and tables A, B and C are the
package's cited copy in ``mtlc/ergonomics/data`` (sources in each file's first line). Angles are
measured on the skeleton (``docs/body.md``): the upper arm and the trunk geometrically, the
rest from the anatomically named degrees of freedom. The thresholds the paper leaves open (when
a joint counts as "neutral", "abducted", "twisted") are the constants below, documented in
``docs/rula.md``.
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from importlib.resources import files
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mtlc.body.kinematics import Pose
from mtlc.body.skeleton import Skeleton
from mtlc.ir.model import MotionIR, runs_of
from mtlc.loads import AXIAL_KINDS  # tools turned by re-gripping
from mtlc.loads import held_load as held_load  # what each hand holds, per frame

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

NEUTRAL_DEG = 5.0  # a wrist or trunk within 5° of zero counts as neutral / erect
DEVIATED_DEG = 10.0  # wrist deviation, neck or trunk twist and side bend beyond this add 1
ABDUCTED_DEG = 20.0  # shoulder abduction beyond this: "upper arm abducted"
RAISED_DEG = 10.0  # clavicle elevation beyond this: "shoulder raised"
OUT_TO_SIDE_DEG = 45.0  # shoulder abduction beyond this: the forearm works out to the side
TWIST_END_FRACTION = 0.75  # forearm rotation past 3/4 of its range: "near the end of twisting"
SIDES = ("r", "l")
LIGHT_KG = 2.0  # force/load score: under 2 kg intermittent is 0
HEAVY_KG = 10.0  # over 10 kg is 3
STATIC_S = 60.0  # a load held longer than a minute is "static" (2 for 2-10 kg)
REPEATED_PER_MIN = 4.0  # "action repeated >=4 times/min": muscle use +1, 2-10 kg scores 2


@dataclass(frozen=True)
class RulaScores:
    """Per-frame scores (N,) of one side's arm and the shared neck, trunk and legs."""

    upper_arm: IntArray
    lower_arm: IntArray
    wrist: IntArray
    wrist_twist: IntArray
    neck: IntArray
    trunk: IntArray
    legs: IntArray
    score_a: IntArray
    score_b: IntArray
    grand: IntArray


# -- the tables ------------------------------------------------------------------------------


def _rows(name: str) -> list[list[int]]:
    text = (files("mtlc.ergonomics") / "data" / name).read_text(encoding="utf-8")
    lines = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    return [[int(v) for v in row] for row in csv.reader(lines[1:])]


@cache
def table_a() -> IntArray:
    """Posture score A indexed [upper_arm-1, lower_arm-1, wrist-1, wrist_twist-1]."""
    out = np.zeros((6, 3, 4, 2), dtype=np.int64)
    for ua, la, w, wt, score in _rows("rula_table_a.csv"):
        out[ua - 1, la - 1, w - 1, wt - 1] = score
    return out


@cache
def table_b() -> IntArray:
    """Posture score B indexed [neck-1, trunk-1, legs-1]."""
    out = np.zeros((6, 6, 2), dtype=np.int64)
    for neck, trunk, legs, score in _rows("rula_table_b.csv"):
        out[neck - 1, trunk - 1, legs - 1] = score
    return out


@cache
def table_c() -> IntArray:
    """Grand score indexed [min(C, 8)-1, min(D, 7)-1]."""
    out = np.zeros((8, 7), dtype=np.int64)
    for c, d, score in _rows("rula_table_c.csv"):
        out[c - 1, d - 1] = score
    return out


# -- bands (degrees in, scores out; lower bounds exclusive except the first band) -------------


def upper_arm_band(flexion_deg: FloatArray) -> IntArray:
    """1: 20° extension to 20° flexion; 2: more extension or 20–45°; 3: 45–90°; 4: over 90°."""
    a = np.asarray(flexion_deg, dtype=float)
    score = np.select([a < -20, a <= 20, a <= 45, a <= 90], [2, 1, 2, 3], 4)
    return score.astype(np.int64)


def lower_arm_band(elbow_flexion_deg: FloatArray) -> IntArray:
    """1: 60–100° of elbow flexion; 2: less or more."""
    a = np.asarray(elbow_flexion_deg, dtype=float)
    return np.where((a >= 60) & (a <= 100), 1, 2).astype(np.int64)


def wrist_band(flexion_deg: FloatArray) -> IntArray:
    """1: neutral (within NEUTRAL_DEG); 2: up to 15° of flexion or extension; 3: more."""
    a = np.abs(np.asarray(flexion_deg, dtype=float))
    return np.select([a <= NEUTRAL_DEG, a <= 15], [1, 2], 3).astype(np.int64)


def neck_band(flexion_deg: FloatArray) -> IntArray:
    """1: 0–10° of flexion; 2: 10–20°; 3: over 20°; 4: in extension."""
    a = np.asarray(flexion_deg, dtype=float)
    return np.select([a < 0, a <= 10, a <= 20], [4, 1, 2], 3).astype(np.int64)


def trunk_band(flexion_deg: FloatArray) -> IntArray:
    """1: erect (within NEUTRAL_DEG, or in extension); 2: up to 20°; 3: 20–60°; 4: over 60°."""
    a = np.asarray(flexion_deg, dtype=float)
    return np.select([a <= NEUTRAL_DEG, a <= 20, a <= 60], [1, 2, 3], 4).astype(np.int64)


def grand_score(
    score_a: IntArray, score_b: IntArray, muscle: int | IntArray = 0, force: int | IntArray = 0
) -> IntArray:
    """Table C from A and B, each raised by the muscle-use and force/load scores (each one
    number for the task or one per frame)."""
    c = np.clip(np.asarray(score_a) + muscle + force, 1, 8)
    d = np.clip(np.asarray(score_b) + muscle + force, 1, 7)
    return table_c()[c - 1, d - 1]


# -- repetition: a fastener's strokes or grips -------------------------------------------------


@dataclass(frozen=True)
class Repetition:
    """One hand's repeated actions on one fastener: ``count`` strokes or grips from ``start`` to
    ``end`` (s), the fastener's turning window."""

    side: str
    site: str
    count: int
    start: float
    end: float

    @property
    def per_minute(self) -> float:
        return repetition_rate(self.count, self.end - self.start)

    @property
    def repeated(self) -> bool:
        """RULA's "repeated": at least two actions, at ``REPEATED_PER_MIN`` a minute or more."""
        return self.count >= 2 and self.per_minute >= REPEATED_PER_MIN


def repetition_rate(count: int, seconds: float) -> float:
    """Actions a minute: ``count`` over a window of ``seconds``."""
    return 60.0 * count / seconds if seconds > 0 else float("inf")


def repetitions(ir: MotionIR) -> list[Repetition]:
    """Each fastener's turning, per hand: a wrench's strokes (segments with ``stroke`` in their
    params; a series starts again at stroke 1) and a screwdriver's or pliers' grips (the twists
    after a reach made with the tool, each counting ``result["grips"]``, 1 before the tool pass
    has re-gripped it). Ordered by start."""
    series: dict[tuple[str, int], list[Any]] = {}  # (side, series id) -> [site, count, t0, t1]
    current: dict[str, tuple[int, str]] = {}  # side -> (series id, fastener) under way
    for seg in sorted(ir.segments, key=lambda s: (s.start, s.end)):
        side, params = seg.goal.effector[:1], seg.goal.params
        tool = params.get("tool")
        if side not in SIDES or not isinstance(tool, dict):
            continue
        axial = tool.get("kind") in AXIAL_KINDS
        if "stroke" in params:
            site = str(seg.goal.site)
            if int(params["stroke"]) == 1 or current.get(side, (0, ""))[1] != site:
                current[side] = (id(seg), site)
            _count(series, (side, current[side][0]), site, 1, seg.start, seg.end)
        elif seg.kind == "TO" and axial:
            current[side] = (id(seg), str(seg.goal.site))  # the reach onto the next screw
        elif params.get("posture") == "twist" and axial and side in current:
            grips = int((seg.result or {}).get("grips", 1))
            ident, site = current[side]
            _count(series, (side, ident), site, grips, seg.start, seg.end)
    out = [Repetition(side, *vals) for (side, _), vals in series.items()]
    return sorted(out, key=lambda r: (r.start, r.side, r.site))


def _count(
    series: dict[tuple[str, int], list[Any]],
    key: tuple[str, int],
    site: str,
    count: int,
    start: float,
    end: float,
) -> None:
    """Add ``count`` actions from ``start`` to ``end`` to a series, widening its window."""
    entry = series.setdefault(key, [site, 0, start, end])
    entry[1] += count
    entry[2], entry[3] = min(entry[2], start), max(entry[3], end)


def repeated_frames(ir: MotionIR, time: FloatArray) -> dict[str, BoolArray]:
    """Per hand, the frames inside the turning window of a repeated series (``repetitions``)."""
    t = np.asarray(time, dtype=float)
    out = {side: np.zeros(len(t), dtype=bool) for side in SIDES}
    for rep in repetitions(ir):
        if rep.repeated:
            out[rep.side] |= (t >= rep.start - 1e-9) & (t <= rep.end + 1e-9)
    return out


def muscle_scores(ir: MotionIR, time: FloatArray) -> dict[str, IntArray]:
    """Each hand's muscle-use score per frame: +1 while it repeats an action 4 times a minute
    or more (a fastener's strokes or grips); 0 elsewhere (a static posture is not scored)."""
    return {side: rep.astype(np.int64) for side, rep in repeated_frames(ir, time).items()}


def _held_longer_than(mask: BoolArray, time: FloatArray, seconds: float) -> BoolArray:
    """Frames in a run of ``mask`` that lasts ``seconds`` or longer."""
    m = np.asarray(mask, dtype=bool)
    out = np.zeros(len(m), dtype=bool)
    for a, b in runs_of(m):
        out[a:b] = time[b - 1] - time[a] >= seconds
    return out


def force_score(
    load_kg: FloatArray, time: FloatArray, repeated: BoolArray | None = None
) -> IntArray:
    """RULA's force/load score per frame (McAtamney & Corlett 1993): under 2 kg 0; 2-10 kg
    intermittent 1, held a minute or longer (static) or on a ``repeated`` frame 2; over 10 kg
    3."""
    kg = np.asarray(load_kg, dtype=float)
    static = _held_longer_than(kg >= LIGHT_KG, np.asarray(time, dtype=float), STATIC_S)
    if repeated is not None:
        static = static | np.asarray(repeated, dtype=bool)
    return np.select([kg < LIGHT_KG, kg > HEAVY_KG, static], [0, 3, 2], default=1).astype(np.int64)


def force_scores(
    ir: MotionIR, time: FloatArray, repeated: Mapping[str, BoolArray] | None = None
) -> dict[str, IntArray]:
    """Each hand's force/load score per frame, from what it holds (:func:`held_load`) and
    whether it repeats its action (``repeated``, default :func:`repeated_frames`)."""
    rep = repeated_frames(ir, time) if repeated is None else repeated
    return {side: force_score(kg, time, rep[side]) for side, kg in held_load(ir, time).items()}


# -- angles from the pose --------------------------------------------------------------------


def _deg(skel: Skeleton, q: FloatArray, name: str) -> FloatArray:
    return np.degrees(q[..., skel.dof_names.index(name)])


def _local(pose: Pose, skel: Skeleton, frame_joint: str, vec: FloatArray) -> FloatArray:
    """World vectors (N, 3) expressed in a joint's frame (Y up, Z forward, X the body's left)."""
    R = pose.R[..., skel.joint_index(frame_joint), :, :]
    return np.einsum("nji,nj->ni", R, vec)


def upper_arm_flexion(skel: Skeleton, pose: Pose, side: str) -> FloatArray:
    """Signed elevation (deg) of the upper arm from the trunk's downward axis.

    Positive (flexion) unless the arm points mostly backwards; so a sideways-raised arm scores
    by its elevation, as RULA's assessors read it, and the abduction adds its own +1.
    """
    shoulder = pose.p[..., skel.joint_index(f"{side}_shoulder"), :]
    elbow = pose.p[..., skel.joint_index(f"{side}_elbow"), :]
    u = _local(pose, skel, "thorax", elbow - shoulder)
    u = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-12)
    elevation = np.degrees(np.arccos(np.clip(-u[..., 1], -1.0, 1.0)))
    backwards = (u[..., 2] < 0) & (np.abs(u[..., 2]) > np.abs(u[..., 0]))
    return np.where(backwards, -elevation, elevation)


def trunk_flexion(skel: Skeleton, pose: Pose) -> FloatArray:
    """Forward lean (deg) of the thorax from the world vertical, negative leaning back."""
    R = pose.R[..., skel.joint_index("thorax"), :, :]
    pelvis = pose.R[..., skel.joint_index("pelvis"), :, :]
    up = R[..., :, 1]  # the thorax's Y axis in the world
    forward = pelvis[..., :, 2]
    forward = forward - forward[..., 1:2] * np.array([0.0, 1.0, 0.0])
    forward = forward / np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)
    lean = np.degrees(np.arccos(np.clip(up[..., 1], -1.0, 1.0)))
    return np.where(np.einsum("ni,ni->n", up, forward) < 0, -lean, lean)


def arm_scores(skel: Skeleton, pose: Pose, q: FloatArray, side: str) -> tuple[IntArray, ...]:
    """(upper arm, lower arm, wrist, wrist twist) scores of one side, per frame."""
    abd = _deg(skel, q, f"{side}_shoulder_abd")
    upper = upper_arm_band(upper_arm_flexion(skel, pose, side))
    upper = upper + (_deg(skel, q, f"{side}_clavicle_elev") > RAISED_DEG) + (abd > ABDUCTED_DEG)
    wrist_pos = pose.p[..., skel.joint_index(f"{side}_wrist"), :]
    thorax_pos = pose.p[..., skel.joint_index("thorax"), :]
    lateral = _local(pose, skel, "thorax", wrist_pos - thorax_pos)[..., 0]
    across = lateral > 0 if side == "r" else lateral < 0  # past the body's midline
    lower = lower_arm_band(_deg(skel, q, f"{side}_elbow_flex")) + (across | (abd > OUT_TO_SIDE_DEG))
    wrist = wrist_band(_deg(skel, q, f"{side}_wrist_flex"))
    wrist = wrist + (np.abs(_deg(skel, q, f"{side}_wrist_dev")) > DEVIATED_DEG)
    k = skel.dof_names.index(f"{side}_elbow_pro")
    pro, lo, hi = q[..., k], skel.lower[k], skel.upper[k]
    near_end = (pro > hi * TWIST_END_FRACTION) | (pro < lo * TWIST_END_FRACTION)
    twist = np.where(near_end, 2, 1)
    return (
        np.clip(upper, 1, 6).astype(np.int64),
        np.clip(lower, 1, 3).astype(np.int64),
        np.clip(wrist, 1, 4).astype(np.int64),
        twist.astype(np.int64),
    )


def neck_trunk_scores(skel: Skeleton, pose: Pose, q: FloatArray) -> tuple[IntArray, IntArray]:
    """(neck, trunk) scores per frame, with their twist and side-bend additions."""
    neck_flex = _deg(skel, q, "neck_flex") + _deg(skel, q, "head_flex")
    neck_lat = _deg(skel, q, "neck_lat") + _deg(skel, q, "head_lat")
    neck = neck_band(neck_flex) + (np.abs(_deg(skel, q, "neck_rot")) > DEVIATED_DEG)
    neck = neck + (np.abs(neck_lat) > DEVIATED_DEG)
    trunk_rot = _deg(skel, q, "lumbar_rot") + _deg(skel, q, "thorax_rot")
    trunk_lat = _deg(skel, q, "lumbar_lat") + _deg(skel, q, "thorax_lat")
    trunk = trunk_band(trunk_flexion(skel, pose)) + (np.abs(trunk_rot) > DEVIATED_DEG)
    trunk = trunk + (np.abs(trunk_lat) > DEVIATED_DEG)
    return np.clip(neck, 1, 6).astype(np.int64), np.clip(trunk, 1, 6).astype(np.int64)


def score_frames(
    skel: Skeleton,
    pose: Pose,
    q: FloatArray,
    both_feet: BoolArray,
    *,
    muscle: int | Mapping[str, IntArray] = 0,
    force: int | Mapping[str, IntArray] = 0,
) -> dict[str, RulaScores]:
    """RULA scores per frame for the right and the left side.

    ``both_feet`` (N,): legs and feet supported with the weight even (legs score 1, else 2).
    ``muscle`` (0 or 1) and ``force`` (0–3) are each one number for the task or each side's
    score per frame (:func:`muscle_scores`, :func:`force_scores`).
    """
    qa = np.asarray(q, dtype=float)
    legs = np.where(np.asarray(both_feet, dtype=bool), 1, 2).astype(np.int64)
    neck, trunk = neck_trunk_scores(skel, pose, qa)
    score_b = table_b()[neck - 1, trunk - 1, legs - 1]
    out: dict[str, RulaScores] = {}
    for side in SIDES:
        upper, lower, wrist, twist = arm_scores(skel, pose, qa, side)
        score_a = table_a()[upper - 1, lower - 1, wrist - 1, twist - 1]
        grand = grand_score(score_a, score_b, _of_side(muscle, side), _of_side(force, side))
        out[side] = RulaScores(
            upper, lower, wrist, twist, neck, trunk, legs, score_a, score_b, grand
        )
    return out


def task_scores(
    ir: MotionIR, pose: Pose, q: FloatArray, time: FloatArray, both_feet: BoolArray
) -> dict[str, RulaScores]:
    """:func:`score_frames` with each hand's muscle-use and force/load scores from the task
    (what it holds, what it repeats): the one call lint, report and preview make."""
    repeated = repeated_frames(ir, time)
    muscle = {side: rep.astype(np.int64) for side, rep in repeated.items()}
    force = force_scores(ir, time, repeated)
    assert ir.skeleton is not None
    return score_frames(ir.skeleton, pose, q, both_feet, muscle=muscle, force=force)


def _of_side(score: int | Mapping[str, IntArray], side: str) -> int | IntArray:
    """A task-level score as it is, or one side's per-frame scores."""
    return score if isinstance(score, int) else np.asarray(score[side], np.int64)


def worst_grand(scores: dict[str, RulaScores]) -> IntArray:
    """The worse side's grand score per frame."""
    return np.maximum.reduce([s.grand for s in scores.values()])


def action_level(grand: IntArray) -> IntArray:
    """RULA action level 1–4 from the grand score (1–2, 3–4, 5–6, 7)."""
    g = np.asarray(grand)
    return np.select([g <= 2, g <= 4, g <= 6], [1, 2, 3], 4).astype(np.int64)
