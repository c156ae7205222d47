"""MT0610: a hand, forearm or held tool does not fit through the opening it reaches through.

The goal's hand (its breadth by its thickness, the fingertips left out: they hold the part),
its forearm and its tool (circles) are each tested for a free prism along an axis through the
scene's geometry (mtlc.geometry.openings); a glove adds ``glove-mm`` on every side.

Where the site has a normal, the way in is the one the language states (a TO comes in along
the site's normal): tool, hand and forearm laid end to end out from the site along it, each as
long as it is on the manikin. That is a verdict on the design, whatever path the motion took:
if even the straight way in does not pass, no way does. Where the site has none, the axes are
the output frames' own, at the end of the reach and over the work after it (up to ``FRAMES``
frames). Reported once per task line, at the tightest part, with the size that would pass and
the part of the model that stops it. No geometry, no finding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mtlc.body.capsules import HAND_BREADTH, capsule_segments, collision_capsules, measure_m
from mtlc.geometry.clearance import goal_groups, held_capsules
from mtlc.geometry.openings import passage
from mtlc.ir.model import Segment, SourceRef
from mtlc.lint.findings import Finding
from mtlc.lint.rules.view import MotionView, segment_finding
from mtlc.lint.rules.visibility import goal_frames, pose_frames

FRAMES = 6  # frames of a goal tested: its arrival and up to five over the work
FINGERS = 0.25  # of the hand's axis, from the fingertip end, left out: the fingers hold the part
TOOL_TIP = 0.25  # of a tool's axis, at its working end, left out: it engages the part
EPS = 1e-9


@dataclass(frozen=True)
class Tight:
    """The tightest part of one goal: how much of its size passes, where, what stops it."""

    scale: float
    part: str
    size: tuple[float, float]  # m: breadth, thickness needed (with the glove)
    frame: int
    blocker: str
    goal: Segment


def access_openings(view: MotionView) -> list[Finding]:
    """MT0610, once per task line, at its tightest part."""
    worst: dict[SourceRef, Tight] = {}
    for tight in goal_openings(view):
        if tight.scale >= 1.0:
            continue
        key = tight.goal.provenance.origin
        if key not in worst or tight.scale < worst[key].scale:
            worst[key] = tight
    return [_finding(view, w) for w in sorted(worst.values(), key=lambda w: w.frame)]


def goal_openings(view: MotionView) -> list[Tight]:
    """Each goal's tightest part through the openings on its way (scale ``inf``: no opening
    around it); empty without geometry."""
    scene, skel = view.rays, view.ir.skeleton
    if scene is None or skel is None:
        return []
    glove = view.config.glove_mm / 1000.0
    caps = {c.name: c for c in collision_capsules(skel)}
    tools = held_capsules(view.ir)
    breadth = measure_m(skel, HAND_BREADTH) + 2 * glove
    out = []
    for reach, work in goal_groups(view.ir):
        frames = goal_frames(view.time, reach, work, FRAMES)
        if len(frames) == 0:
            continue
        word = "right" if reach.goal.effector.startswith("r") else "left"
        hand, forearm = caps[f"{word} hand"], caps[f"{word} forearm"]
        parts = [
            (hand, (breadth, 2 * hand.radius + 2 * glove), FINGERS),
            (forearm, (2 * forearm.radius + 2 * glove,) * 2, 0.0),
        ]
        t = view.time[frames]
        for cap, a, b in tools:
            if (
                cap.start[0].startswith(reach.goal.effector[:1])
                and ((t >= a - EPS) & (t <= b + EPS)).any()
            ):
                parts.insert(0, (cap, (2 * cap.radius,) * 2, TOOL_TIP))
        normal = reach.goal.params.get("normal")
        along = normal is not None and reach.goal.position is not None
        if along:
            frames = frames[:1]  # the way in along the normal: one question, asked at arrival
        pose = pose_frames(view.pose, frames)
        best: Tight | None = None
        starts, ends, _ = capsule_segments(skel, pose, tuple(p[0] for p in parts))
        for i, frame in enumerate(frames):
            if along:
                axes = _along_normal(reach, normal, starts[i], ends[i], parts)
            else:
                axes = [
                    (s, e + cut * (s - e))
                    for s, e, (_, _, cut) in zip(starts[i], ends[i], parts, strict=True)
                ]
            for (a, b), (cap, size, _) in zip(axes, parts, strict=True):
                got = passage(scene, a, b, *size)
                if best is None or got.scale < best.scale:
                    blocker = scene.name(got.face) if got.face >= 0 else "the model"
                    best = Tight(got.scale, cap.name, size, int(frame), blocker, reach)
        if best is not None:
            out.append(best)
    return out


def _along_normal(
    reach: Segment, normal: object, starts: np.ndarray, ends: np.ndarray, parts: list
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The parts laid end to end out from the site along its normal, the working end first
    (tool, hand, forearm), each as long as it is on the frame; the share each leaves out
    (the fingers, the tool's tip) at the site's end."""
    unit = np.asarray(normal, dtype=float)
    unit = unit / max(float(np.linalg.norm(unit)), 1e-12)
    site = np.asarray(reach.goal.position, dtype=float)
    out, depth = [], 0.0
    for s, e, (_, _, cut) in zip(starts, ends, parts, strict=True):
        length = float(np.linalg.norm(e - s))
        out.append((site + unit * (depth + cut * length), site + unit * (depth + length)))
        depth += length
    return out


def _finding(view: MotionView, w: Tight) -> Finding:
    need = f"{w.size[0] * 1000:.0f} x {w.size[1] * 1000:.0f} mm"
    if w.size[0] == w.size[1]:
        need = f"{w.size[0] * 1000:.0f} mm across"
    free = f"{w.scale * w.size[0] * 1000:.0f} x {w.scale * w.size[1] * 1000:.0f} mm"
    if w.size[0] == w.size[1]:
        free = f"{w.scale * w.size[0] * 1000:.0f} mm across"
    site = f" to site `{w.goal.goal.site}`" if w.goal.goal.site else ""
    glove = f", with {view.config.glove_mm:g} mm gloves" if view.config.glove_mm else ""
    msg = (
        f"the {w.part} does not fit through the opening in `{w.blocker}` on the way{site}: "
        f"it lets {free} through, the {w.part.split()[-1]} is {need}{glove} (at "
        f"{view.time[w.frame]:.2f} s in "
        f"`{' > '.join(w.goal.provenance.path)}`)"
    )
    help = "widen the opening, move the site nearer to it, or reach it with a smaller tool"
    return segment_finding(view, "MT0610", w.goal, msg, help)
