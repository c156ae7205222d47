"""A supplied BVH walking clip: read it, find its steps, its key joints, and adapt its gait.

Seed 004's method on motion-capture data, as the locomotion pass uses it:

* claim 2, step segmentation: the feet's global positions by forward kinematics, their heights
  filtered and thresholded (:func:`mtlc.passes.locomotion.segment_steps`): the lift-off and
  touch-down of every step, its length and the footprints;
* claim 3, key joints: principal components of the joint-angle channels over the frames
  (the covariance matrix's eigenvectors, enough of them for 90 % of the variance), then k-means
  (``scipy.cluster.vq.kmeans2``, seeded) of each joint's loadings: the cluster that carries
  the motion holds the key joints;
* claim 4, adaptation: the ratio of the step the task wants to the clip's step, the feet's
  paths scaled by it relative to each step's start (and the step height by its own ratio),
  the key joints' angles solved by damped least squares to put the feet there, and the
  adapted clip segmented again: its step length, height and cadence drive the generated walk.

The reader is small and dependency-free: HIERARCHY (ROOT/JOINT/End Site, OFFSET, CHANNELS)
and MOTION (Frames, Frame Time, one line per frame). Rotations compose in the listed channel
order (``R = R(c1)·R(c2)·R(c3)``), as BVH writers mean them. The clip is assumed Y up, as
nearly all BVH files are; lengths are scaled to metres by the clip's own leg length.
"""

from __future__ import annotations

import hashlib
import math
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.ir.model import MotionIR, Segment
from mtlc.passes.context import PassContext
from mtlc.passes.locomotion import DetectedStep, Gait, gait_of, segment_steps
from mtlc.semantics.modules import InputRefused, read_input_bytes

MAX_CLIP_BYTES = 64 * 1024 * 1024  # a walking clip of minutes of motion capture is a few MB

FloatArray = NDArray[np.float64]

FOOT_NAMES = {  # lower-case name fragments, best first
    "l": ("leftfoot", "lfoot", "l_foot", "leftankle", "lankle", "l_ankle", "left_ankle"),
    "r": ("rightfoot", "rfoot", "r_foot", "rightankle", "rankle", "r_ankle", "right_ankle"),
}
TOE_NAMES = {
    "l": ("lefttoe", "ltoe", "l_toe", "lefttoebase", "left_toe"),
    "r": ("righttoe", "rtoe", "r_toe", "righttoebase", "right_toe"),
}
PCA_VARIANCE = 0.9  # components kept: this share of the angle channels' variance
CLUSTERS = 3
KEY_SHARE = 0.25  # a cluster is key if its joints move at least this share of the strongest's
ADAPT_ITERATIONS = 12


class ClipError(Exception):
    """A clip that cannot be read or used; ``line`` is where in the file, when known."""

    def __init__(self, message: str, line: int | None = None) -> None:
        super().__init__(message)
        self.line = line


@dataclass
class BvhJoint:
    name: str
    parent: int  # -1 for the root
    offset: FloatArray
    channels: tuple[str, ...]
    first: int  # index of its first channel in a frame
    end_site: FloatArray | None = None


@dataclass
class BvhClip:
    joints: list[BvhJoint]
    frame_time: float
    motion: FloatArray  # (F, channels)
    path: str = ""
    scale: float = 1.0  # clip units to metres
    notes: dict[str, Any] = field(default_factory=dict)

    @property
    def time(self) -> FloatArray:
        return np.arange(len(self.motion)) * self.frame_time

    def index(self, name: str) -> int:
        return next(i for i, j in enumerate(self.joints) if j.name == name)


# --------------------------------------------------------------------------- reading


def read_bvh(path: str | Path) -> BvhClip:
    """Parse a BVH file; raises :class:`ClipError` with the offending line."""
    return parse_bvh(_clip_bytes(path).decode("utf-8", errors="replace"), str(path))


def _clip_bytes(path: str | Path) -> bytes:
    """The clip file's bytes, or :class:`ClipError`."""
    try:
        return read_input_bytes(path, MAX_CLIP_BYTES)  # a regular file: not a pipe or a device
    except InputRefused as exc:
        raise ClipError(f"cannot read it: {exc}") from None
    except OSError as exc:
        raise ClipError(f"cannot read it: {exc.strerror or exc}") from None


def parse_bvh(text: str, path: str = "<clip>") -> BvhClip:
    lines = text.splitlines()
    tokens: list[tuple[str, int]] = []
    motion_at = None
    for n, line in enumerate(lines, 1):
        if line.strip().upper() == "MOTION":
            motion_at = n
            break
        tokens.extend((tok, n) for tok in line.replace("{", " { ").replace("}", " } ").split())
    if not tokens or tokens[0][0].upper() != "HIERARCHY":
        raise ClipError("not a BVH file: it does not start with HIERARCHY", 1)
    if motion_at is None:
        raise ClipError("the BVH file has no MOTION section", len(lines) or 1)
    joints: list[BvhJoint] = []
    stack: list[int] = []
    pos = 1
    n_channels = 0

    def need(i: int) -> tuple[str, int]:
        if i >= len(tokens):
            raise ClipError("the hierarchy ends early", tokens[-1][1])
        return tokens[i]

    def number(i: int) -> float:
        tok, ln = need(i)
        try:
            return float(tok)
        except ValueError:
            raise ClipError(f"expected a number, found `{tok}`", ln) from None

    while pos < len(tokens):
        tok, ln = tokens[pos]
        key = tok.upper()
        if key in ("ROOT", "JOINT"):
            name = need(pos + 1)[0]
            if need(pos + 2)[0] != "{":
                raise ClipError(f"expected `{{` after {key} {name}", ln)
            if need(pos + 3)[0].upper() != "OFFSET":
                raise ClipError(f"expected OFFSET in joint {name}", need(pos + 3)[1])
            offset = np.array([number(pos + 4), number(pos + 5), number(pos + 6)])
            if need(pos + 7)[0].upper() != "CHANNELS":
                raise ClipError(f"expected CHANNELS in joint {name}", need(pos + 7)[1])
            try:
                count = int(need(pos + 8)[0])
            except ValueError:
                raise ClipError("expected a channel count", need(pos + 8)[1]) from None
            chans = tuple(need(pos + 9 + k)[0] for k in range(count))
            for ch in chans:
                if ch.lower() not in _CHANNEL_AXES:
                    raise ClipError(f"unknown channel `{ch}`", ln)
            joints.append(BvhJoint(name, stack[-1] if stack else -1, offset, chans, n_channels))
            n_channels += count
            stack.append(len(joints) - 1)
            pos += 9 + count
        elif key == "END":
            if need(pos + 2)[0] != "{" or need(pos + 3)[0].upper() != "OFFSET":
                raise ClipError("expected `{ OFFSET` after End Site", ln)
            if stack:
                joints[stack[-1]].end_site = np.array(
                    [number(pos + 4), number(pos + 5), number(pos + 6)]
                )
            if need(pos + 7)[0] != "}":
                raise ClipError("expected `}` closing End Site", need(pos + 7)[1])
            pos += 8
        elif key == "}":
            if not stack:
                raise ClipError("unbalanced `}`", ln)
            stack.pop()
            pos += 1
        else:
            raise ClipError(f"unexpected `{tok}` in the hierarchy", ln)
    if stack:
        raise ClipError("the hierarchy is not closed", tokens[-1][1])
    if not joints:
        raise ClipError("the hierarchy has no joints", 1)
    rest = [(ln.strip(), n) for n, ln in enumerate(lines[motion_at:], motion_at + 1) if ln.strip()]
    if len(rest) < 2:
        raise ClipError("MOTION needs `Frames:` and `Frame Time:` lines", motion_at)
    try:
        frames = int(rest[0][0].split(":", 1)[1])
        frame_time = float(rest[1][0].split(":", 1)[1])
    except (IndexError, ValueError):
        raise ClipError("cannot read `Frames:` / `Frame Time:`", rest[0][1]) from None
    if frame_time <= 0 or not math.isfinite(frame_time):
        raise ClipError("the frame time must be positive", rest[1][1])
    data = rest[2:]
    if len(data) < frames:
        raise ClipError(f"the file says {frames} frames but has {len(data)}", len(lines))
    motion = np.empty((frames, n_channels))
    for k, (line, ln) in enumerate(data[:frames]):
        vals = line.split()
        if len(vals) != n_channels:
            raise ClipError(f"frame {k + 1} has {len(vals)} values, not {n_channels}", ln)
        try:
            motion[k] = [float(v) for v in vals]
        except ValueError:
            raise ClipError(f"frame {k + 1} has a value that is not a number", ln) from None
    if not np.all(np.isfinite(motion)):
        raise ClipError("the motion has values that are not finite", motion_at)
    return BvhClip(joints, frame_time, motion, path)


_CHANNEL_AXES = {
    "xposition": 0, "yposition": 1, "zposition": 2,
    "xrotation": 0, "yrotation": 1, "zrotation": 2,
}  # fmt: skip


def _axis_rot(axis: int, deg: FloatArray) -> FloatArray:
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    if axis == 0:
        rows = [[o, z, z], [z, c, -s], [z, s, c]]
    elif axis == 1:
        rows = [[c, z, s], [z, o, z], [-s, z, c]]
    else:
        rows = [[c, -s, z], [s, c, z], [z, z, o]]
    return np.stack([np.stack(r, -1) for r in rows], -2)


def joint_rotation(joint: BvhJoint, motion: FloatArray) -> FloatArray:
    """A joint's local rotation for every frame: its rotation channels in listed order."""
    R = np.broadcast_to(np.eye(3), (len(motion), 3, 3)).copy()
    for k, ch in enumerate(joint.channels):
        if ch.lower().endswith("rotation"):
            R = R @ _axis_rot(_CHANNEL_AXES[ch.lower()], motion[:, joint.first + k])
    return R


def forward_clip(clip: BvhClip, motion: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
    """World positions (F, J, 3) in metres and rotations (F, J, 3, 3) of every joint."""
    m = clip.motion if motion is None else motion
    F, J = len(m), len(clip.joints)
    pos = np.empty((F, J, 3))
    rot = np.empty((F, J, 3, 3))
    for j, jt in enumerate(clip.joints):
        local = jt.offset * clip.scale
        trans = np.zeros((F, 3))
        for k, ch in enumerate(jt.channels):
            if ch.lower().endswith("position"):
                trans[:, _CHANNEL_AXES[ch.lower()]] = m[:, jt.first + k] * clip.scale
        R = joint_rotation(jt, m)
        if jt.parent < 0:
            pos[:, j] = local + trans
            rot[:, j] = R
        else:
            pr = rot[:, jt.parent]
            pos[:, j] = pos[:, jt.parent] + np.einsum("fij,fj->fi", pr, local + trans)
            rot[:, j] = pr @ R
    return pos, rot


# --------------------------------------------------------------------------- feet and steps


def _find(clip: BvhClip, names: tuple[str, ...]) -> int | None:
    low = [j.name.lower().replace(" ", "") for j in clip.joints]
    for frag in names:
        for i, n in enumerate(low):
            if n == frag or n.endswith(frag) or n.startswith(frag):
                return i
    return None


def feet_of(clip: BvhClip) -> dict[str, tuple[int, int | None]]:
    """The foot (ankle) and toe joints of each side, by the common names."""
    out = {}
    for side in ("r", "l"):
        foot = _find(clip, FOOT_NAMES[side])
        if foot is None:
            raise ClipError(
                f"no {'right' if side == 'r' else 'left'} foot joint found "
                "(looked for names like RightFoot/LeftFoot, RightAnkle/LeftAnkle)"
            )
        out[side] = (foot, _find(clip, TOE_NAMES[side]))
    return out


def leg_chain(clip: BvhClip, foot: int, levels: int = 3) -> list[int]:
    """The joints above a foot that move it: ankle's parent (knee), hip, (up to ``levels``)."""
    chain, j = [], clip.joints[foot].parent
    while j >= 0 and len(chain) < levels:
        chain.append(j)
        j = clip.joints[j].parent
    return chain[::-1]


def auto_scale(clip: BvhClip) -> float:
    """Metres per clip unit, from the clip's leg (hip to foot at the first frame).

    Metres if the leg is 0.3–3 long, centimetres if 30–150 (most mocap files); anything else
    is normalised to a 0.9 m leg (only the gait's proportions to the leg are used).
    """
    feet = feet_of(clip)
    clip.scale = 1.0
    pos, _ = forward_clip(clip, clip.motion[:1])
    foot = feet["r"][0]
    chain = leg_chain(clip, foot)
    if not chain:
        raise ClipError("the right foot has no leg joints above it")
    leg = float(np.linalg.norm(pos[0, chain[0]] - pos[0, foot]))
    if leg <= 0:
        raise ClipError("the clip's leg has no length")
    if 0.3 <= leg <= 3.0:
        return 1.0
    if 30.0 <= leg <= 150.0:
        return 0.01
    return 0.9 / leg


def foot_tracks(clip: BvhClip, motion: FloatArray | None = None) -> dict[str, FloatArray]:
    """The lowest of foot and toe joint of each side (F, 3), what touches the ground."""
    pos, _ = forward_clip(clip, motion)
    out = {}
    for side, (foot, toe) in feet_of(clip).items():
        pts = pos[:, [foot] if toe is None else [foot, toe]]
        low = pts[..., 1].argmin(axis=1)
        out[side] = pts[np.arange(len(pts)), low]
    return out


def clip_steps(clip: BvhClip, motion: FloatArray | None = None) -> list[DetectedStep]:
    """Claim 2 on the clip: steps from the feet's heights (and speeds)."""
    tracks = foot_tracks(clip, motion)
    return segment_steps(
        clip.time,
        {s: p[:, 1] for s, p in tracks.items()},
        tracks,
        speed_threshold=0.3,
    )


# --------------------------------------------------------------------------- key joints


def key_joints(clip: BvhClip, *, seed: int = 0) -> list[str]:
    """Claim 3: PCA over the frames of the angle channels, then k-means of joints by loadings."""
    rot_cols = [
        (j, jt.first + k)
        for j, jt in enumerate(clip.joints)
        for k, ch in enumerate(jt.channels)
        if ch.lower().endswith("rotation") and jt.parent >= 0
    ]
    if len(rot_cols) < 2 or len(clip.motion) < 3:
        return []
    X = np.unwrap(np.radians(clip.motion[:, [c for _, c in rot_cols]]), axis=0)
    X = X - X.mean(axis=0)
    cov = X.T @ X / (len(X) - 1)
    vals, vecs = np.linalg.eigh(cov)
    vals, vecs = vals[::-1].clip(min=0.0), vecs[:, ::-1]
    if vals.sum() <= 0:
        return []
    k = int(np.searchsorted(np.cumsum(vals) / vals.sum(), PCA_VARIANCE) + 1)
    loadings = vecs[:, :k] * np.sqrt(vals[:k])  # channel rows, reduced to k components
    joints = sorted({j for j, _ in rot_cols})
    rows = np.array(
        [np.sqrt((loadings[[i for i, (jj, _) in enumerate(rot_cols) if jj == j]] ** 2)
                 .sum(axis=0)) for j in joints]
    )  # fmt: skip
    n_clusters = min(CLUSTERS, len(joints))
    rng = np.random.default_rng(seed)
    init = rows[rng.choice(len(rows), n_clusters, replace=False)]
    from scipy.cluster.vq import kmeans2  # only with --walk-clip: scipy loads when needed

    _, labels = kmeans2(rows, init, minit="matrix", seed=seed)
    strength = np.linalg.norm(rows, axis=1)
    means = [
        strength[labels == c].mean() if np.any(labels == c) else 0.0 for c in range(n_clusters)
    ]
    keep = {c for c in range(n_clusters) if means[c] >= KEY_SHARE * max(means)}
    return [clip.joints[j].name for j, lab in zip(joints, labels, strict=True) if lab in keep]


# --------------------------------------------------------------------------- adaptation


@dataclass
class ClipAnalysis:
    clip: BvhClip
    steps: list[DetectedStep]
    gait: dict[str, float]
    key_joints: list[str]
    leg_length: float  # m, hip to foot at the first frame
    # the gait adapted to a length ratio (``gait_for_walk``), kept for the process's other tasks
    adapted: dict[float, tuple[dict[str, float], float, float, int]] = field(default_factory=dict)


ANALYSES_KEPT = 4  # clips whose analysis a process keeps (``analyse``)
_ANALYSES: dict[tuple[str, str], ClipAnalysis] = {}
_ANALYSES_LOCK = threading.Lock()  # `serve` compiles from its clients' threads


def analyse(path: str | Path) -> ClipAnalysis:
    """The clip's analysis, once per process for the same path and bytes: ``compile`` checks
    the clip before any motion and each walk's pass asks again (0.7 s each for a 6-second
    clip), and a lint sweep asks once per task and manikin. Nothing downstream changes an
    analysis (``adapt`` works on a copy of the motion)."""
    data = _clip_bytes(path)
    key = (str(path), hashlib.sha256(data).hexdigest())
    with _ANALYSES_LOCK:
        found = _ANALYSES.get(key)
        if found is None:
            found = _analysed(parse_bvh(data.decode("utf-8", errors="replace"), str(path)))
            while len(_ANALYSES) >= ANALYSES_KEPT:
                del _ANALYSES[next(iter(_ANALYSES))]
            _ANALYSES[key] = found
    return found


def _analysed(clip: BvhClip) -> ClipAnalysis:
    clip.scale = auto_scale(clip)
    steps = clip_steps(clip)
    if len(steps) < 2:
        raise ClipError(f"the clip has {len(steps)} step(s): a walking clip needs two or more")
    gait = gait_of(steps)
    if not math.isfinite(gait.get("step_length", math.nan)) or gait["step_length"] <= 0:
        raise ClipError("the clip's feet do not move forward: no step length")
    gait["foot_rise"] = _foot_rise(clip, clip.motion)
    pos, _ = forward_clip(clip, clip.motion[:1])
    foot = feet_of(clip)["r"][0]
    leg = float(np.linalg.norm(pos[0, leg_chain(clip, foot)[0]] - pos[0, foot]))
    return ClipAnalysis(clip, steps, gait, key_joints(clip), leg)


def _foot_rise(clip: BvhClip, motion: FloatArray) -> float:
    """Median peak rise of the foot joints above their stance height (the step height)."""
    pos, _ = forward_clip(clip, motion)
    rises = []
    for foot, _ in feet_of(clip).values():
        y = pos[:, foot, 1]
        rises.append(float(y.max() - np.percentile(y, 5)))
    return float(np.median(rises))


def adapt(
    analysis: ClipAnalysis, length_ratio: float, height_ratio: float
) -> tuple[FloatArray, float]:
    """Claim 4: scale the feet's steps and solve the key joints by IK to follow them.

    Each foot's path is scaled about the footprint it left from (horizontal by
    ``length_ratio``, vertical rise by ``height_ratio``) and the root's horizontal travel by
    ``length_ratio``; the legs' key-joint rotation channels (all leg joints if PCA found
    none of them) are solved per frame by damped least squares with a numerical Jacobian.
    Returns the adapted motion and the feet's remaining error (m, 95th percentile over the
    frames: a few frames near a straight knee may converge slowly).
    """
    clip = analysis.clip
    m = clip.motion.copy()
    pos, _ = forward_clip(clip, m)
    root = clip.joints[0]
    travel = pos[-1, 0] - pos[0, 0]
    travel[1] = 0.0
    if np.linalg.norm(travel) < 1e-6:
        raise ClipError("the clip does not travel: not a walking clip")
    d = travel / np.linalg.norm(travel)  # the walking direction
    for k, ch in enumerate(root.channels):  # the body travels further or less
        name = ch.lower()
        if name.endswith("position") and _CHANNEL_AXES[name] != 1:
            col = m[:, root.first + k]
            along = ((pos[:, 0] - pos[0, 0]) @ d) * (length_ratio - 1.0) / clip.scale
            m[:, root.first + k] = col + along * d[_CHANNEL_AXES[name]]
    feet = feet_of(clip)
    key = set(analysis.key_joints)
    points, goals, cols_set = [], [], set()
    for foot, toe in feet.values():
        # scaled along the walking direction about the root's first position (one origin for
        # both feet keeps their stagger): footprints stay planted;
        # the toe follows too, so the foot keeps its pitch
        low = np.percentile(pos[:, foot, 1], 5)
        p = pos[:, foot]
        out = p + np.outer((p - pos[0, 0]) @ d, d) * (length_ratio - 1.0)
        out[:, 1] = low + (p[:, 1] - low) * height_ratio
        points.append(foot)
        goals.append(out)
        if toe is not None:  # the toe keeps its place on the foot, so the foot its pitch
            points.append(toe)
            goals.append(out + pos[:, toe] - p)
        chain = leg_chain(clip, foot) + ([foot] if toe is not None else [])
        chosen = [j for j in chain if clip.joints[j].name in key] or chain
        cols_set.update(
            clip.joints[j].first + k
            for j in chosen
            for k, ch in enumerate(clip.joints[j].channels)
            if ch.lower().endswith("rotation")
        )
    cols = sorted(cols_set)
    foot_idx = points
    goal = np.stack(goals, axis=1)  # (F, P, 3)
    n_err = 3 * len(points)
    eps, lam2 = 0.05, 1e-7  # degrees for the finite differences; damping (m² per degree²)
    for _ in range(ADAPT_ITERATIONS):
        cur = forward_clip(clip, m)[0][:, foot_idx]
        err = (goal - cur).reshape(len(m), n_err)
        if np.abs(err).max() < 1e-4:
            break
        J = np.empty((len(m), n_err, len(cols)))
        for c, col in enumerate(cols):
            mp = m.copy()
            mp[:, col] += eps
            J[:, :, c] = (forward_clip(clip, mp)[0][:, foot_idx] - cur).reshape(len(m), n_err) / eps
        JJt = J @ np.swapaxes(J, 1, 2) + lam2 * np.eye(n_err)
        step = np.einsum("fji,fj->fi", J, np.linalg.solve(JJt, err[..., None])[..., 0])
        m[:, cols] += np.clip(step, -10.0, 10.0)
    final = forward_clip(clip, m)[0][:, foot_idx]
    return m, float(np.percentile(np.linalg.norm(goal - final, axis=-1), 95))


def checked_clip(path: Path, sink: DiagnosticSink) -> ClipAnalysis | None:
    """The clip's analysis, or None with MT0503 reported: ``compile`` asks before any motion
    (a clip it cannot use fails the compile, which then need not solve the motion first)."""
    try:
        return analyse(path)
    except ClipError as exc:
        span = Span(str(path), exc.line, 1, exc.line, 1) if exc.line else Span.whole_file(str(path))
        sink.report(
            "MT0503",
            f"walking clip `{path}`: {exc}",
            span,
            help="give a BVH walking clip (HIERARCHY and MOTION, feet named like "
            "LeftFoot/RightFoot) with at least two steps, or leave out --walk-clip",
        )
        return None


def gait_for_walk(ir: MotionIR, ctx: PassContext, seg: Segment, base: Gait) -> Gait:
    """The walk's gait from the supplied clip, adapted to the task's step (claims 2–4).

    The task's step: the clip's step scaled to the manikin's leg, shortened so that a whole
    number of steps covers this walk's distance; the step height keeps the clip's proportion
    to the leg. A clip that cannot be read or used is reported once (MT0503) and the walk
    falls back to the stature gait.
    """
    path = ctx.options.walk_clip
    assert path is not None
    cached = ctx.cache.get("walk_clip")
    if cached is None:
        cached = checked_clip(path, ctx.sink) or False
        ctx.cache["walk_clip"] = cached
    if cached is False:
        return base
    an: ClipAnalysis = cached
    legs = ctx.cache["legs"]
    to_manikin = (legs.length + legs.ankle_height) / an.leg_length
    clip_step = an.gait["step_length"] * to_manikin
    distance = float(seg.goal.params.get("distance") or 0.0)
    n = max(1, math.ceil(distance / clip_step - 1e-9)) if distance > 0 else 1
    task_step = distance / n if distance > 0 else clip_step
    ratio = task_step / clip_step
    key = round(ratio, 3)
    adapted = ctx.cache.setdefault("walk_clip_adapted", {})
    if key not in adapted:
        if ratio not in an.adapted:
            motion, err = adapt(an, ratio, 1.0)
            steps = clip_steps(an.clip, motion)
            an.adapted[ratio] = (gait_of(steps), _foot_rise(an.clip, motion), err, len(steps))
        adapted[key] = an.adapted[ratio]
    g, rise, err, n_found = adapted[key]
    seg.result["clip"] = {
        "file": str(path),
        "steps": len(an.steps),
        "key_joints": an.key_joints,
        "step_length": round(an.gait["step_length"], 6),
        "cadence": round(an.gait["cadence"], 6),
        "length_ratio": round(ratio, 6),
        "adapted_step_length": round(g.get("step_length", math.nan), 6),
        "adapted_steps": n_found,
        "ik_error": round(err, 6),
    }
    length = g.get("step_length", math.nan) * to_manikin
    return Gait(
        step_length=length if math.isfinite(length) and length > 0 else task_step,
        step_height=rise * to_manikin,
        cadence=float(g.get("cadence", an.gait["cadence"])),
        source="clip",
    )
