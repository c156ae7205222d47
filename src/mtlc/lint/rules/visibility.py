"""MT0607: a site being reached or worked on (a TA or TO segment) lies outside the view cone;
MT0611: the equipment hides it from the eyes.

MT0607: per frame of each reach, the angle between the head's forward axis and the line from
the eye to the reached site (mtlc.ergonomics.view); reported once per task line, at its worst
frame. MT0611: lines from the eye to a small disc at the site, through the scene's triangles
(mtlc.geometry.rays), at the reach's end and over the work there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from mtlc.body.kinematics import Pose, site_positions
from mtlc.ergonomics.view import EYE_SITE, outside_cone, site_view_angles
from mtlc.geometry.clearance import goal_groups
from mtlc.ir.model import Segment, SourceRef
from mtlc.lint.findings import Finding
from mtlc.lint.rules.view import MotionView, segment_finding

REACH_KINDS = ("TA", "TO")


def frame_window(time: np.ndarray, start: float, end: float) -> slice:
    """The frames from ``start`` to ``end`` inclusive."""
    lo = int(np.searchsorted(time, start - 1e-9, side="left"))
    hi = int(np.searchsorted(time, end + 1e-9, side="right"))
    return slice(lo, hi)


def pose_frames(pose: Pose, frames: slice | np.ndarray) -> Pose:
    """The poses of some frames only (a slice or an index array)."""
    return replace(pose, R=pose.R[frames], p=pose.p[frames], axes=pose.axes[frames],
                   root=pose.root[frames])  # fmt: skip


def site_out_of_view(view: MotionView) -> list[Finding]:
    half = view.config.view_cone_half_angle
    worst: dict[SourceRef, tuple[float, int, Segment]] = {}  # task line -> angle, frame, reach
    for seg in view.ir.segments:
        if seg.kind not in REACH_KINDS or seg.goal.position is None:
            continue
        frames = frame_window(view.time, seg.start, seg.end)
        if frames.stop <= frames.start:
            continue
        target = np.asarray(seg.goal.position, dtype=float)
        angle = site_view_angles(view.ir.skeleton, pose_frames(view.pose, frames), target)
        bad = outside_cone(angle, half)
        if not bad.any():
            continue
        k = int(np.argmax(np.where(bad, angle, -np.inf)))
        key = seg.provenance.origin
        if key not in worst or angle[k] > worst[key][0]:
            worst[key] = (float(angle[k]), frames.start + k, seg)
    ordered = sorted(worst.values(), key=lambda w: w[1])
    return [_finding(view, half, angle, frame, seg) for angle, frame, seg in ordered]


def _finding(view: MotionView, half: float, angle: float, frame: int, seg: Segment) -> Finding:
    msg = (
        f"site `{seg.goal.site}` is outside the {half:g}° view cone while it is reached or worked "
        f"on: {math.degrees(angle):.1f}° off the line of sight at {view.time[frame]:.2f} s in "
        f"`{' > '.join(seg.provenance.path)}`"
    )
    help = "look at the site first (`look`), turn the body toward it, or move the site into view"
    return segment_finding(view, "MT0607", seg, msg, help)


# MT0611: the equipment between the eyes and a site (docs/visibility.md, "Occlusion")
SITE_RADIUS = 0.01  # m: the site is seen as a disc this wide across the line of sight...
RING = 8  # ...sampled at its centre and this many points around its rim
SPARE = 0.01  # m before a sampled point a surface does not hide it (the one the site is on)
HIDDEN_SHARE = 0.5  # a site is hidden at a frame when less than this share of it is visible
OCCLUSION_FRAMES = 6  # frames of a goal tested: its arrival and up to five over the work


@dataclass(frozen=True)
class Sight:
    """How much of one goal's site the eyes see through the geometry: the least share at a
    frame (and that frame), the share over the goal's frames, and what hides the most."""

    goal: Segment
    share: float
    frame: int
    mean: float
    by: str | None


def goal_sights(view: MotionView) -> list[Sight]:
    """Each goal's site seen from the eyes through the scene's geometry, at the reach's end and
    over the work there (empty without geometry)."""
    scene = view.rays
    if scene is None or view.ir.skeleton is None:
        return []
    out = []
    for reach, work in goal_groups(view.ir):
        if reach.goal.position is None:
            continue
        frames = goal_frames(view.time, reach, work, OCCLUSION_FRAMES)
        if len(frames) == 0:
            continue
        eye = site_positions(view.ir.skeleton, pose_frames(view.pose, frames), EYE_SITE)
        points = site_disc(eye, np.asarray(reach.goal.position, dtype=float))  # (F, P, 3)
        n, p = points.shape[:2]
        hits = scene.blocked(np.repeat(eye, p, axis=0), points.reshape(-1, 3), SPARE)
        blocked = np.isfinite(hits.distance).reshape(n, p)
        share = 1.0 - blocked.mean(axis=1)
        k = int(np.argmin(share))
        names = [scene.name(int(f)) for f in hits.face.reshape(n, p)[k][blocked[k]]]
        by = max(sorted(set(names)), key=names.count) if names else None
        out.append(Sight(reach, float(share[k]), int(frames[k]), float(share.mean()), by))
    return out


def site_hidden(view: MotionView) -> list[Finding]:
    """MT0611, once per task line, at its least visible frame."""
    worst: dict[SourceRef, Sight] = {}
    for sight in goal_sights(view):
        if sight.share >= HIDDEN_SHARE:
            continue
        key = sight.goal.provenance.origin
        if key not in worst or sight.share < worst[key].share:
            worst[key] = sight
    return [_hidden(view, s) for s in sorted(worst.values(), key=lambda s: s.frame)]


def goal_frames(time: np.ndarray, reach: Segment, work: list[Segment], most: int) -> np.ndarray:
    """A reach's last frame and up to ``most - 1`` frames spread over the work after it."""
    eps = 1e-9
    last = int(np.searchsorted(time, reach.end + eps, side="right")) - 1
    out = [last] if last >= 0 else []
    if work:
        lo = int(np.searchsorted(time, min(w.start for w in work) - eps, side="left"))
        hi = int(np.searchsorted(time, max(w.end for w in work) + eps, side="right"))
        if hi > lo:
            out += np.linspace(lo, hi - 1, min(most - 1, hi - lo)).round().astype(int).tolist()
    return np.array(sorted(set(out)), dtype=np.intp)


def site_disc(eye: np.ndarray, site: np.ndarray) -> np.ndarray:
    """(F, 1 + RING, 3): the site and RING points SITE_RADIUS around it, across the line of
    sight from each eye point (F, 3)."""
    sight = site - eye
    sight /= np.maximum(np.linalg.norm(sight, axis=1, keepdims=True), 1e-12)
    ref = np.where(np.abs(sight[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(sight, ref)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(sight, u)
    angle = np.linspace(0, 2 * math.pi, RING, endpoint=False)
    ring = SITE_RADIUS * (
        np.cos(angle)[None, :, None] * u[:, None, :] + np.sin(angle)[None, :, None] * v[:, None, :]
    )
    centre = np.broadcast_to(site, (len(eye), 1, 3))
    return np.concatenate([centre, site + ring], axis=1)


def _hidden(view: MotionView, sight: Sight) -> Finding:
    seg = sight.goal
    msg = (
        f"site `{seg.goal.site}` is hidden from the eyes by `{sight.by}`: {sight.share:.0%} of it "
        f"visible at {view.time[sight.frame]:.2f} s in `{' > '.join(seg.provenance.path)}` "
        f"({sight.mean:.0%} over the reach's end and the work)"
    )
    help = "move what is in the way, add a viewing opening, or turn the body to see past it"
    return segment_finding(view, "MT0611", seg, msg, help)
